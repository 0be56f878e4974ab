//! Plant identification's excitation (`zslide identify`): a sine added to
//! the amplifier DAC after the servo, for a bounded number of loop ticks.
//!
//! Added after the servo, the sine is a known disturbance of the closed
//! loop: the capture records the DAC code u that reached the amplifier and
//! the gauge y, and y/u at the sine's frequency is the plant, whatever the
//! loop does (the loop only makes u differ from the sine).
//!
//! Safety. The sine runs only while the loop is engaged at null: no fault
//! latched, the command null (no X, X outside the table, no table) and no
//! operator offset. The tick checks this on every tick and stops the sine
//! for good when it no longer holds (an arm, a disarm, a fault, a command),
//! so a sine never outlives the state it was allowed in. The amplitude is
//! bounded by [`max_amplitude_codes`] (checked by the link's station before
//! the tick sees it, and the tick clamps again), and the servo's own
//! limits (following error, estimated current, gauge range) stay armed.
//!
//! The frequency is a phase step per tick in the binary angle (2³² per
//! turn): a capture of 2ⁿ ticks holds a whole number of periods when the
//! step is a multiple of 2³²⁻ⁿ.

use crate::servo::design::DAC_CODES_PER_V;
use crate::trig::{sin_cos, FRAC_BITS};
use crate::units::SpindleAngle;

/// Amplitude bound below [`EXCITE_CORNER_HZ`], volts at the DAC: ×10 at the
/// amplifier, 5 V into the Model 15's 1.4 Ω coil is 3.6 A at most, under
/// the firmware's 6 A estimated-current limit and the amplifier's 8 A fuse.
pub const EXCITE_LOW_V: f64 = 0.5;
/// Above this frequency the coil's inductance carries the voltage
/// (L/R = 0.26 ms: 612 Hz), so the bound rises with the frequency and the
/// current stays at ≈ 3.6 A.
pub const EXCITE_CORNER_HZ: f64 = 612.0;
/// The bound at any frequency, volts at the DAC (25 V at the coil).
pub const EXCITE_MAX_V: f64 = 2.5;
/// The longest excitation, seconds of loop ticks.
pub const EXCITE_MAX_S: f64 = 10.0;

/// Largest amplitude allowed at `f_hz`, DAC codes.
pub fn max_amplitude_codes(f_hz: f64) -> u32 {
    let v = (EXCITE_LOW_V * (f_hz / EXCITE_CORNER_HZ).max(1.0)).min(EXCITE_MAX_V);
    (v * DAC_CODES_PER_V) as u32
}

/// Frequency of a phase step `step` at `loop_hz`, Hz.
pub fn step_hz(step: u32, loop_hz: u32) -> f64 {
    f64::from(step) * f64::from(loop_hz) / 4_294_967_296.0
}

/// Why an excitation request is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum ExciteError {
    /// Above a quarter of the loop rate (fewer than 4 ticks per period).
    Frequency,
    /// Above [`max_amplitude_codes`] at its frequency (the bound, codes).
    Amplitude { max: u32 },
    /// Longer than [`EXCITE_MAX_S`] (the bound, ticks).
    Duration { max: u32 },
    /// The loop is not engaged at null (disarmed, faulted, or commanded).
    NotAtNull,
    /// The start tick `at` was not ahead of the loop's tick `now` when the
    /// loop took the request (a late arm), or more than [`EXCITE_MAX_S`]
    /// ahead of it.
    StartTick { at: u32, now: u32 },
}

impl core::fmt::Display for ExciteError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ExciteError::Frequency => f.write_str(
                "excitation refused: the frequency must be below a quarter of the loop rate",
            ),
            ExciteError::Amplitude { max } => write!(
                f,
                "excitation refused: the amplitude must be at most {max} DAC codes ({:.3} V) at this frequency",
                f64::from(*max) / DAC_CODES_PER_V
            ),
            ExciteError::Duration { max } => write!(
                f,
                "excitation refused: at most {max} loop ticks ({EXCITE_MAX_S} s)"
            ),
            ExciteError::NotAtNull => f.write_str(
                "excitation refused: the loop must be armed, engaged and at null (no fault, no command, no offset): arm it with X outside the table",
            ),
            ExciteError::StartTick { at, now } => write!(
                f,
                "excitation refused: its start tick {at} was not ahead of the loop's tick {now} \
                 when the loop took the request (a late arm), or more than {EXCITE_MAX_S} s \
                 ahead of it: ask for a tick further ahead"
            ),
        }
    }
}

/// Checks a request against the bounds (not the loop's state).
pub fn check(step: u32, amplitude: u32, ticks: u32, loop_hz: u32) -> Result<(), ExciteError> {
    if step > 1 << 30 {
        return Err(ExciteError::Frequency);
    }
    let max = max_amplitude_codes(step_hz(step, loop_hz));
    if amplitude > max {
        return Err(ExciteError::Amplitude { max });
    }
    let max = (EXCITE_MAX_S * f64::from(loop_hz)) as u32;
    if ticks > max {
        return Err(ExciteError::Duration { max });
    }
    Ok(())
}

/// The sine's state in the loop tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Excitation {
    step: u32,
    phase: u32,
    amplitude: i32,
    left: u32,
    /// Ticks of zeros before phase 0 (an anchored start).
    wait: u32,
}

impl Excitation {
    pub const OFF: Self = Self {
        step: 0,
        phase: 0,
        amplitude: 0,
        left: 0,
        wait: 0,
    };

    /// Starts a sine of `amplitude` codes, `step` per tick, for `ticks`
    /// ticks, from phase 0 after `wait` ticks of zeros (the amplitude
    /// clamped to the bound of the largest step allowed: the station
    /// checked the exact bound).
    pub fn start(&mut self, step: u32, amplitude: u32, ticks: u32, wait: u32) {
        let cap = (EXCITE_MAX_V * DAC_CODES_PER_V) as u32;
        *self = Self {
            step: step.min(1 << 30),
            phase: 0,
            amplitude: amplitude.min(cap) as i32,
            left: ticks,
            wait,
        };
    }

    pub fn stop(&mut self) {
        self.left = 0;
    }

    pub fn active(&self) -> bool {
        self.left != 0
    }

    /// This tick's DAC codes (0 once done).
    #[inline(always)]
    pub fn sample(&mut self) -> i32 {
        if self.left == 0 {
            return 0;
        }
        if self.wait != 0 {
            self.wait -= 1;
            return 0;
        }
        self.left -= 1;
        let s = sin_cos(SpindleAngle(self.phase)).sin;
        self.phase = self.phase.wrapping_add(self.step);
        ((i64::from(s) * i64::from(self.amplitude)) >> FRAC_BITS) as i32
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn the_sine_has_its_amplitude_period_and_length() {
        let mut e = Excitation::OFF;
        // 1024 ticks per period at step 2^22.
        e.start(1 << 22, 10_000, 2048, 0);
        let v: heapless::Vec<i32, 2048> = (0..2048).map(|_| e.sample()).collect();
        assert_eq!(e.sample(), 0, "stops after its ticks");
        assert_eq!(v[0], 0);
        assert!(
            (v[256] - 10_000).abs() <= 1,
            "peak a quarter period in: {}",
            v[256]
        );
        assert!((v[768] + 10_000).abs() <= 1, "trough: {}", v[768]);
        assert_eq!(v[100], v[1124], "periodic");
    }

    /// An anchored start: `wait` zeros, then the same sine from phase 0,
    /// still `ticks` long.
    #[test]
    fn a_delayed_sine_is_the_same_sine_after_its_zeros() {
        let (mut now, mut later) = (Excitation::OFF, Excitation::OFF);
        now.start(1 << 22, 10_000, 300, 0);
        later.start(1 << 22, 10_000, 300, 37);
        assert!((0..37).all(|_| later.sample() == 0 && later.active()));
        for i in 0..300 {
            assert_eq!(later.sample(), now.sample(), "tick {i} of the sine");
        }
        assert!(!later.active());
    }

    #[test]
    fn requests_beyond_the_bounds_are_refused() {
        // 100 Hz at 20 kHz: step 2^32 / 200.
        let step = (4_294_967_296.0 / 200.0) as u32;
        let max = max_amplitude_codes(100.0);
        assert_eq!(max, (0.5 * DAC_CODES_PER_V) as u32);
        assert!(check(step, max, 20_000, 20_000).is_ok());
        assert_eq!(
            check(step, max + 1, 20_000, 20_000),
            Err(ExciteError::Amplitude { max })
        );
        assert_eq!(
            check(step, 1, 200_001, 20_000),
            Err(ExciteError::Duration { max: 200_000 })
        );
        assert_eq!(
            check((1 << 30) + 1, 1, 1, 20_000),
            Err(ExciteError::Frequency)
        );
        // 3 kHz: the coil's inductance allows 2.45 V.
        let m3k = max_amplitude_codes(3000.0);
        assert!((f64::from(m3k) / DAC_CODES_PER_V - 0.5 * 3000.0 / 612.0).abs() < 1e-4);
    }
}
