//! The linear power amplifier in front of the motor: voltage gain 10 V/V,
//! 8 A current limit, trip on sustained overload, reset by re-enabling.
//!
//! Between events it is one of three linear regimes of the slide model:
//! * **voltage**: `e_m = clamp(10 · v_in, ±rail)`;
//! * **current limit**: the coil current is held at ±8 A (the limiter
//!   takes over from the voltage loop), the mechanical part sees a constant
//!   force;
//! * **off** (disabled by its enable line, or tripped): the output opens,
//!   the coil current is zero and the slide coasts on its air film.
//!
//! Entry into current limit is located inside a step to the nanosecond
//! (greedy power-of-two steps on the exact solution, all cached), so the
//! current never overshoots the limit; leaving it
//! and the trip are decided at event boundaries and at the trip instant.
//! The trip latches: only a low-then-high on the enable line (or
//! [`Amplifier::reset`]) clears it, like the 1983 amplifier that "turned
//! itself off" and needed a complete re-initialisation.

use crate::slide::{st, ZSlide};
// The f64 functions of `libm` where std's are missing (no_std builds);
// with std the inherent methods are used and the import is idle.
#[allow(unused_imports)]
use num_traits::Float;

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct AmplifierParams {
    /// Voltage gain, V/V (chapter 4: K_A = 10).
    pub gain: f64,
    /// Current limit, A (amplifier and motor fused for 8 A, chapter 5).
    pub current_limit_a: f64,
    /// Output voltage rail, V. Not published; 8 A × 1.4 Ω plus back EMF
    /// needs < 12 V, so any realistic rail only matters for gross commands.
    pub rail_v: f64,
    /// Time in current limit after which the amplifier trips, s. Not
    /// published ("even small loads suddenly placed on the system could
    /// sometimes cause the power amplifier to overload and turn itself off").
    pub trip_after_s: f64,
}

impl Default for AmplifierParams {
    fn default() -> Self {
        Self {
            gain: 10.0,
            current_limit_a: 8.0,
            rail_v: 48.0,
            trip_after_s: 2.0e-3,
        }
    }
}

/// Regime of the amplifier output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AmpRegime {
    Voltage,
    /// Holding the current at `+limit` (`true`) or `−limit` (`false`).
    CurrentLimit {
        positive: bool,
    },
    Off,
}

#[derive(Clone, Debug)]
pub struct Amplifier {
    pub params: AmplifierParams,
    enabled: bool,
    tripped: bool,
    limiting: Option<bool>,
    limit_time_ns: u64,
    /// Number of trips so far.
    pub trips: u32,
    /// Number of entries into current limit.
    pub limit_entries: u32,
    /// Where in its step the last limit entry fell, ns from the step start.
    pub last_entry_offset_ns: u64,
}

impl Amplifier {
    pub fn new(params: AmplifierParams) -> Self {
        Self {
            params,
            enabled: false,
            tripped: false,
            limiting: None,
            limit_time_ns: 0,
            trips: 0,
            limit_entries: 0,
            last_entry_offset_ns: 0,
        }
    }

    /// Enable line. A rising edge also clears a trip (the reset).
    pub fn set_enabled(&mut self, on: bool) {
        if on && !self.enabled {
            self.reset();
        }
        self.enabled = on;
    }
    pub fn enabled(&self) -> bool {
        self.enabled
    }
    pub fn tripped(&self) -> bool {
        self.tripped
    }
    /// Trips now for a cause of its own (over-temperature, supply): the
    /// output stage turns off and the fault line goes high until the next
    /// enable edge, as an overload trip does.
    pub fn trip_now(&mut self) {
        if !self.tripped {
            self.tripped = true;
            self.trips += 1;
        }
    }
    /// Clears a trip and the overload timer.
    pub fn reset(&mut self) {
        self.tripped = false;
        self.limiting = None;
        self.limit_time_ns = 0;
    }
    pub fn regime(&self) -> AmpRegime {
        if !self.enabled || self.tripped {
            AmpRegime::Off
        } else if let Some(p) = self.limiting {
            AmpRegime::CurrentLimit { positive: p }
        } else {
            AmpRegime::Voltage
        }
    }

    /// Output voltage demanded by the input (before the current limiter).
    pub fn demand_v(&self, v_in: f64) -> f64 {
        crate::fastmath::clamp_symmetric(self.params.gain * v_in, self.params.rail_v)
    }

    /// Advances slide and amplifier together by `dt_ns` with the amplifier
    /// input `v_in` (V) and external force `f_ext` (lbf) held.
    pub fn advance(&mut self, slide: &mut ZSlide, dt_ns: u64, v_in: f64, f_ext: f64) {
        if dt_ns == 0 {
            return;
        }
        if !self.enabled || self.tripped {
            slide.x[st::I] = 0.0;
            slide.step(dt_ns, 0.0, f_ext, true);
            return;
        }
        let e = self.demand_v(v_in);
        let p = &slide.params;
        if let Some(pos) = self.limiting {
            // Back to voltage control once the demanded voltage would lower
            // the current magnitude.
            let di_sign = e - p.r_ohm * slide.x[st::I] - p.kb_v_s_per_in * slide.x[st::V];
            if (pos && di_sign < 0.0) || (!pos && di_sign > 0.0) {
                self.limiting = None;
                self.limit_time_ns = 0;
            }
        }
        if self.limiting.is_some() {
            self.hold_for(slide, dt_ns, f_ext);
            return;
        }
        let saved = slide.x;
        slide.step(dt_ns, e, f_ext, false);
        let lim = self.params.current_limit_a;
        if slide.x[st::I].abs() <= lim {
            return;
        }
        // The current crossed the limit inside the step: find the last
        // nanosecond below it by greedy power-of-two steps (each a cached
        // discretisation, so a limit entry costs ~17 small steps, not 17
        // matrix exponentials).
        let positive = slide.x[st::I] > 0.0;
        let mut x_lo = saved;
        let mut t_lo = 0u64;
        for k in (0..64 - dt_ns.leading_zeros()).rev() {
            let h = 1u64 << k;
            if t_lo + h > dt_ns {
                continue;
            }
            slide.x = x_lo;
            slide.step(h, e, f_ext, false);
            if slide.x[st::I].abs() <= lim {
                x_lo = slide.x;
                t_lo += h;
            }
        }
        slide.x = x_lo;
        slide.x[st::I] = if positive { lim } else { -lim };
        self.limiting = Some(positive);
        self.limit_time_ns = 0;
        self.limit_entries += 1;
        self.last_entry_offset_ns = t_lo;
        self.hold_for(slide, dt_ns - t_lo, f_ext);
    }

    /// Holds the current at the limit for `dt_ns`, tripping inside the
    /// interval when the overload lasts `trip_after_s`.
    fn hold_for(&mut self, slide: &mut ZSlide, dt_ns: u64, f_ext: f64) {
        let trip_ns = (self.params.trip_after_s * 1e9).round().max(0.0) as u64;
        let left = trip_ns.saturating_sub(self.limit_time_ns);
        if dt_ns < left {
            slide.step_binary(dt_ns, 0.0, f_ext, true);
            self.limit_time_ns += dt_ns;
            return;
        }
        slide.step_binary(left, 0.0, f_ext, true);
        self.tripped = true;
        self.trips += 1;
        self.limiting = None;
        self.limit_time_ns = 0;
        slide.x[st::I] = 0.0;
        slide.step_binary(dt_ns - left, 0.0, f_ext, true);
    }
}
