//! Spindle-synchronous repetitive (learning) control, indexed by spindle
//! angle.
//!
//! The error that repeats every revolution (what the feedforward's rigid
//! model misses, the per-revolution part of the cutting force, the bolt
//! holes, the tachometer's once-per-rev ripple) is learned into a table of
//! 256 bins per revolution and added to the reference the loop follows:
//!
//! ```text
//! r'(φ) = r(φ) + c(φ)          c: the table, linearly interpolated in φ
//! c(θ) ← Q[ c(θ) + κ · e(θ + lead) ]    once per revolution per bin
//! ```
//!
//! Because the correction enters as *reference*, it passes through the
//! same plant-inverse feedforward as the command (its angular derivatives,
//! from the table's slopes, times the measured angle step), so the learned
//! reference is followed at every harmonic the model is good for, not only
//! inside the feedback bandwidth. The table is indexed by angle, not time:
//! when the spindle sags a few percent under cutting torque, a bin still
//! holds the same place on the part (a time-indexed buffer of one nominal
//! period would slide along the part and learn the error into the wrong
//! place). The learning is spread over the ticks inside a bin in proportion
//! to the angle each covers (Σ Δφ over a bin = one bin), so κ is per
//! revolution whatever the speed.
//!
//! Robustness: the lead (in bins) compensates the loop's residual lag; the
//! Q-filter `t[k] += (t[k−1] − 2t[k] + t[k+1]) / 2^shift`, applied twice
//! to each bin per revolution when it is complete (for shift 2 the kernel
//! [1 4 6 4 1]/16: gain cos⁴(πh/256) at harmonic h, 0.9976 at h = 2,
//! 0.87 at h = 21, 0.25 at h = 64), limits the learning to low
//! harmonics (zero phase in angle) and makes it forget slowly, which is
//! also how the table follows X as the feed moves the radius. Entries are
//! clamped to ± a quarter of the gauge range (memory bounded in size and
//! value). Learning freezes, with a reason, whenever the angle cannot be
//! trusted or the machine jumped.
//!
//! # Number formats
//! Table entries: gauge codes Q8 (`i32`, |entry| ≤ 2²⁵). Angle: the binary
//! spindle angle (2³² per revolution); a bin is 2²⁴. Outputs: position Q8
//! codes, velocity Q16 codes per tick, acceleration Q16 codes per tick², all
//! `i32`. Products of an entry difference (< 2²⁷) and a fraction or an
//! angle step (< 2²²) are single 32×32 → 64-bit multiplies, shifted back to
//! 32 bits once.

use super::fixed::sat_i32;
use crate::units::SpindleAngle;

/// Bins per revolution.
pub const BINS: usize = 256;
const BIN_BITS: u32 = 24;
const MASK: usize = BINS - 1;
/// |entry| ≤ 2¹⁷ codes (a quarter of the gauge range), Q8.
const ENTRY_LIMIT: i32 = 1 << 25;
/// The correction at bin i reads bins i−1..i+2; an update at i − lead
/// (and the bin after it) must not touch them in the same revolution, or
/// the learning would feed back within the revolution (an integrator at
/// the tick rate that amplifies gauge noise) instead of from one
/// revolution to the next.
pub const MIN_LEAD: usize = 3;
/// Largest angle step per tick the learning accepts (1/4 bin: 1170 rpm at
/// 20 kHz); larger steps are a jump, not motion.
const MAX_DPHI: i32 = 1 << (BIN_BITS - 2);

/// Why the learning is not running.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Freeze {
    /// Learning gain 0 in the configuration.
    Disabled,
    /// The loop is not engaged on the table (arming, ramping, disarmed).
    NotEngaged,
    /// No spindle angle (before the first index, or no spindle).
    NoAngle,
    /// The angle stepped backwards or by more than a quarter bin in a tick.
    SpindleJump,
    /// X moved by more than the configured step between two updates.
    XJump,
    /// A fault is latched.
    Fault,
    /// The table's command is null (X in the null zone, no X or no angle
    /// yet): the slide is held at zero, nothing periodic to learn, and
    /// learning would only write gauge noise into the table.
    Null,
}

/// The learned reference correction at one angle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Correction {
    /// Gauge codes Q8.
    pub position_q8: i32,
    /// Gauge codes per tick Q16.
    pub velocity_q16: i32,
    /// Gauge codes per tick² Q16.
    pub accel_q16: i32,
}

/// The learning table and its state.
#[derive(Clone, Debug)]
pub struct Repetitive {
    table: [i32; BINS],
    gain_q16: i32,
    lead: usize,
    q_shift: u32,
    last_bin: Option<usize>,
    frozen: Option<Freeze>,
    /// Ticks to stay frozen after a jump.
    hold: u32,
    hold_reason: Freeze,
    passes: u32,
}

impl Repetitive {
    pub fn new(gain_q16: i32, lead_bins: u32, q_shift: u32) -> Self {
        Self {
            table: [0; BINS],
            gain_q16: gain_q16.clamp(0, 65_535),
            lead: (lead_bins as usize).clamp(MIN_LEAD, MASK),
            q_shift: q_shift.clamp(1, 16),
            last_bin: None,
            frozen: if gain_q16 > 0 {
                None
            } else {
                Some(Freeze::Disabled)
            },
            hold: 0,
            hold_reason: Freeze::SpindleJump,
            passes: 0,
        }
    }

    /// The correction to add to the reference at `phi`, with its rates for
    /// an angle step of `dphi` per tick (the feedforward's input).
    #[inline]
    pub fn correction(&self, phi: SpindleAngle, dphi: i32) -> Correction {
        let i = (phi.0 >> BIN_BITS) as usize;
        // The position inside the bin, Q16.
        let f = ((phi.0 >> (BIN_BITS - 16)) & 0xFFFF) as i32;
        let t = |k: usize| self.table[k & MASK];
        let (t0, t1, t2, t3) = (t(i + MASK), t(i), t(i + 1), t(i + 2));
        // |entries| ≤ 2²⁵: differences < 2²⁶, slopes' differences < 2²⁷.
        let c_q8 = t1 + ((i64::from(t2 - t1) * i64::from(f)) >> 16) as i32;
        // Slopes at the nodes (codes Q8 per bin, times 2), interpolated.
        let (s1, s2) = (t2 - t0, t3 - t1);
        let slope2 = s1 + ((i64::from(s2 - s1) * i64::from(f)) >> 16) as i32;
        let d = dphi.clamp(-MAX_DPHI, MAX_DPHI);
        // slope/2 · dphi / 2²⁴ codes Q8 per tick → Q16: ·2⁸ → >> 17
        // (< 2³²: saturated).
        let v = sat_i32((i64::from(slope2) * i64::from(d)) >> (BIN_BITS - 7));
        // (s2 − s1)/2 per bin² · dphi² / 2⁴⁸, Q8 → Q16: >> 41 in two
        // steps (< 2²⁹, then < 2³⁰).
        let a1 = ((i64::from(s2 - s1) * i64::from(d)) >> 20) as i32;
        let a = ((i64::from(a1) * i64::from(d)) >> (2 * BIN_BITS - 27)) as i32;
        Correction {
            position_q8: c_q8,
            velocity_q16: v,
            accel_q16: a,
        }
    }

    /// Learns the tracking error `error_q16` (reference − measured, gauge
    /// codes Q16) seen at `phi` after a step `dphi`, unless `freeze` says
    /// why not.
    #[inline]
    pub fn learn(&mut self, phi: SpindleAngle, dphi: i32, error_q8: i32, freeze: Option<Freeze>) {
        if self.gain_q16 == 0 {
            self.frozen = Some(Freeze::Disabled);
            return;
        }
        let freeze = freeze.or(if dphi <= 0 || dphi > MAX_DPHI {
            Some(Freeze::SpindleJump)
        } else {
            None
        });
        if let Some(r) = freeze {
            if matches!(r, Freeze::SpindleJump | Freeze::XJump) {
                self.hold_for(r, 0);
            }
            self.frozen = Some(r);
            self.last_bin = None;
            return;
        }
        if self.hold > 0 {
            self.hold -= 1;
            self.frozen = Some(self.hold_reason);
            self.last_bin = None;
            return;
        }
        self.frozen = None;
        let i = (phi.0 >> BIN_BITS) as usize;
        if let Some(b) = self.last_bin {
            if b != i {
                // Bin b is left: the bin whose last update it was is complete;
                // smooth it, and its predecessor a second time (two passes of
                // the 3-tap kernel = a 5-tap binomial for shift 2).
                let k = (b + BINS - self.lead) & MASK;
                self.q_filter(k);
                self.q_filter(k + MASK);
                if i == 0 {
                    self.passes = self.passes.saturating_add(1);
                }
            }
        }
        self.last_bin = Some(i);
        let j = (i + BINS - self.lead) & MASK;
        let f = ((phi.0 >> (BIN_BITS - 16)) & 0xFFFF) as i32;
        // κ · e · Δφ / bin: Σ over a bin is κ·ē. κ·Δφ/2⁷ < 2³¹ (κ < 1 in
        // Q16, 0 < Δφ ≤ 2²²), and its product with e (|e| ≤ 2²⁸, Q8) over
        // 2³³ is below 2²⁶.
        let e_q8 = error_q8.clamp(-(1 << 28), 1 << 28);
        let k_dphi = (dphi >> 7) * self.gain_q16;
        let inc = ((i64::from(e_q8) * i64::from(k_dphi)) >> (BIN_BITS + 9)) as i32;
        // Shared between the two bins around the angle (|inc| < 2²⁶).
        let lo = ((i64::from(inc) * i64::from(65_536 - f)) >> 16) as i32;
        let hi = inc - lo;
        self.add(j, lo);
        self.add((j + 1) & MASK, hi);
    }

    /// Keeps the learning frozen for `ticks` more ticks (after a jump of
    /// the spindle phase or of X: the next revolution is not comparable).
    pub fn hold_for(&mut self, reason: Freeze, ticks: u32) {
        self.hold = self.hold.max(ticks);
        self.hold_reason = reason;
        self.frozen = Some(reason);
        self.last_bin = None;
    }

    #[inline(always)]
    fn add(&mut self, k: usize, inc: i32) {
        if let Some(t) = self.table.get_mut(k) {
            *t = t.saturating_add(inc).clamp(-ENTRY_LIMIT, ENTRY_LIMIT);
        }
    }

    #[inline(always)]
    fn q_filter(&mut self, k: usize) {
        let t = |k: usize| self.table[k & MASK];
        // |entries| ≤ 2²⁵: the second difference is below 2²⁷.
        let d = (t(k + MASK) - 2 * t(k) + t(k + 1)) >> self.q_shift;
        self.add(k & MASK, d);
    }

    /// Forgets everything learned.
    pub fn clear(&mut self) {
        self.table = [0; BINS];
        self.last_bin = None;
        self.passes = 0;
    }

    /// Why the learning is not running now (`None`: it is).
    pub fn frozen(&self) -> Option<Freeze> {
        self.frozen
    }

    /// Completed learning revolutions since the last clear.
    pub fn revolutions(&self) -> u32 {
        self.passes
    }

    /// Largest |entry|, gauge codes (reports: the table must not grow
    /// without bound).
    pub fn peak_code(&self) -> i32 {
        self.table
            .iter()
            .map(|v| v.unsigned_abs())
            .max()
            .unwrap_or(0) as i32
            >> 8
    }

    /// The table, gauge codes Q8 (reports, plots).
    pub fn table(&self) -> &[i32; BINS] {
        &self.table
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    use super::*;

    const TURN: f64 = 4_294_967_296.0;

    /// A constant error at every angle is learned to κ·e per revolution
    /// per bin, and the table ends at the error (the loop is not closed
    /// here: the "plant" is the table itself, y = c).
    #[test]
    fn learning_converges_on_a_periodic_error_at_any_speed() {
        for ticks_per_rev in [3000u32, 4000, 5000] {
            let mut r = Repetitive::new((0.3 * 65536.0) as i32, 3, 2);
            let dphi = (TURN / f64::from(ticks_per_rev)) as u32;
            let mut phi = 0u32;
            for _ in 0..(ticks_per_rev * 40) {
                let ph = SpindleAngle(phi);
                let target =
                    1000.0 * libm::sin(2.0 * core::f64::consts::TAU * f64::from(phi) / TURN);
                let c = f64::from(r.correction(ph, dphi as i32).position_q8) / 256.0;
                let e = ((target - c) * 256.0) as i32;
                r.learn(ph, dphi as i32, e, None);
                phi = phi.wrapping_add(dphi);
            }
            // residual after 40 revolutions at κ = 0.3: (0.7)^40 ~ 6e-7 plus
            // the Q-filter's steady forgetting at harmonic 2:
            // (1 − cos⁴(2π/256))/κ ≈ 0.8 %.
            let mut worst: f64 = 0.0;
            for k in 0..360 {
                let p = (k as f64 / 360.0 * TURN) as u32;
                let target = 1000.0 * libm::sin(2.0 * core::f64::consts::TAU * f64::from(p) / TURN);
                let c = f64::from(r.correction(SpindleAngle(p), 0).position_q8) / 256.0;
                worst = worst.max((target - c).abs());
            }
            assert!(worst < 10.0, "{ticks_per_rev}: {worst} codes of 1000");
        }
    }

    /// The velocity and acceleration of the correction are the angular
    /// derivatives of the learned shape times the angle step: for a learned
    /// A·sin(kθ) they match A·k·ω and −A·k²·ω² within the table's
    /// resolution.
    #[test]
    fn correction_rates_are_derivatives_of_the_table() {
        let mut r = Repetitive::new(1, 0, 8);
        let a = 10_000.0;
        for (i, t) in r.table.iter_mut().enumerate() {
            *t = (a * 256.0 * libm::sin(2.0 * core::f64::consts::TAU * i as f64 / BINS as f64))
                as i32;
        }
        let dphi = (TURN / 4000.0) as i32;
        let w = core::f64::consts::TAU / 4000.0; // rad per tick
        for k in 0..64 {
            let p = (k as f64 / 64.0 * TURN) as u32;
            let th = core::f64::consts::TAU * f64::from(p) / TURN;
            let c = r.correction(SpindleAngle(p), dphi);
            let v = f64::from(c.velocity_q16) / 65536.0;
            let acc = f64::from(c.accel_q16) / 65536.0;
            let v_exact = a * 2.0 * w * libm::cos(2.0 * th);
            let a_exact = -a * 4.0 * w * w * libm::sin(2.0 * th);
            assert!(
                (v - v_exact).abs() < 0.002 * a * 2.0 * w + 0.01,
                "{k}: {v} vs {v_exact}"
            );
            assert!(
                (acc - a_exact).abs() < 0.05 * a * 4.0 * w * w + 1e-4,
                "{k}: {acc} vs {a_exact}"
            );
        }
    }

    #[test]
    fn backward_or_huge_angle_steps_freeze_the_learning() {
        let mut r = Repetitive::new(20_000, 0, 8);
        r.learn(SpindleAngle(1000), -5, 1 << 12, None);
        assert_eq!(r.frozen(), Some(Freeze::SpindleJump));
        r.learn(SpindleAngle(1000), 1 << 23, 1 << 12, None);
        assert_eq!(r.frozen(), Some(Freeze::SpindleJump));
        assert_eq!(r.peak_code(), 0);
        r.learn(SpindleAngle(1000), 1000, 1 << 12, Some(Freeze::NoAngle));
        assert_eq!(r.frozen(), Some(Freeze::NoAngle));
        r.hold_for(Freeze::XJump, 3);
        for _ in 0..3 {
            r.learn(SpindleAngle(1000), 1000, 1 << 12, None);
            assert_eq!(r.frozen(), Some(Freeze::XJump));
        }
        r.learn(SpindleAngle(1000), 1000, 1 << 12, None);
        assert_eq!(r.frozen(), None);
    }

    /// A constant error forever cannot grow the table beyond its clamp.
    #[test]
    fn table_is_bounded() {
        let mut r = Repetitive::new(60_000, 0, 16);
        let mut phi = 0u32;
        for _ in 0..400_000 {
            r.learn(SpindleAngle(phi), 1 << 20, i32::MAX / 4, None);
            phi = phi.wrapping_add(1 << 20);
        }
        assert!(r.peak_code() <= ENTRY_LIMIT >> 8);
    }
}
