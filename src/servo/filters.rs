//! Second-order filters of the loop: the 120 Hz hum notch on the gauge and
//! the coil-frame-mode notch on the amplifier command.
//!
//! The arithmetic is `idsp`'s (quartiq): a biquad in direct form I with a
//! 64-bit output state ([`idsp::iir::DirectForm1Wide`]) and `Q2.30`
//! coefficients. A notch at 120 Hz sampled at 20 kHz has its poles within
//! 0.02 of the unit circle; the wide output state keeps the recursion's
//! rounding below one LSB of the input there, which a 32-bit state would
//! not. The same integer operations run on the host and the target, so the
//! filter is bit-exact across them.
//!
//! Signals are `i32` in whatever fixed-point format the caller chooses; the
//! gain at DC is exactly one (b0 + b1 + b2 = 1 − a1 − a2 in the rounded
//! coefficients, see [`Notch::design`]), so a notch never offsets a
//! position.

use dsp_fixedpoint::Q32;
use dsp_process::SplitProcess;
use idsp::iir::{coefficients::Filter, Biquad, DirectForm1Wide};

/// Why a filter could not be built from its parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FilterError {
    /// Centre frequency not inside (0, Nyquist).
    Frequency,
    /// Quality factor not positive and finite.
    Quality,
}

/// A notch (band-stop) biquad with its state.
#[derive(Clone, Debug)]
pub struct Notch {
    coeff: Biquad<Q32<30>>,
    state: DirectForm1Wide,
}

impl Notch {
    /// A notch at `f0_hz` for a filter sampled at `fs_hz`, with quality
    /// factor `q` (centre frequency / −3 dB bandwidth).
    ///
    /// The rounded numerator is corrected so that the DC gain is exactly
    /// one in the integer arithmetic: `b0 + b1 + b2 = 2³⁰ − a1 − a2`, the
    /// correction going to `b1` (the symmetric term), which moves the notch
    /// frequency by far less than a millihertz.
    pub fn design(f0_hz: f64, fs_hz: f64, q: f64) -> Result<Self, FilterError> {
        if !(f0_hz > 0.0 && fs_hz > 0.0 && f0_hz < fs_hz / 2.0 && f0_hz.is_finite()) {
            return Err(FilterError::Frequency);
        }
        if !(q > 0.0 && q.is_finite()) {
            return Err(FilterError::Quality);
        }
        let ba = Filter::default().frequency(f0_hz, fs_hz).q(q).notch();
        let a0 = ba[1][0];
        let one = (1u64 << 30) as f64;
        let c = |x: f64| libm::round(x / a0 * one) as i64;
        let (b0, b2) = (c(ba[0][0]), c(ba[0][2]));
        // idsp's sign convention: y0 = b·x + a1·y1 + a2·y2.
        let (a1, a2) = (-c(ba[1][1]), -c(ba[1][2]));
        let b1 = (1i64 << 30) - a1 - a2 - b0 - b2;
        let fits = |v: i64| v >= i64::from(i32::MIN) && v <= i64::from(i32::MAX);
        if ![b0, b1, b2, a1, a2].into_iter().all(fits) {
            return Err(FilterError::Frequency);
        }
        let q = |v: i64| Q32::<30>::from_bits(v as i32);
        Ok(Self {
            coeff: Biquad {
                ba: [q(b0), q(b1), q(b2), q(a1), q(a2)],
            },
            state: DirectForm1Wide::default(),
        })
    }

    /// A notch from coefficient bits made by [`Self::design`] (a parameter
    /// block), with a zero state.
    pub fn from_bits(ba: [i32; 5]) -> Self {
        Self {
            coeff: Biquad {
                ba: ba.map(Q32::<30>::from_bits),
            },
            state: DirectForm1Wide::default(),
        }
    }

    /// One sample through the filter.
    #[inline]
    pub fn process(&mut self, x: i32) -> i32 {
        self.coeff.process(&mut self.state, x)
    }

    /// Sets the state as if `x` had been applied forever (no transient when
    /// the loop engages on a slide that is not at zero).
    pub fn settle_at(&mut self, x: i32) {
        self.state.x = [x, x];
        let y = i64::from(x) << 32;
        self.state.y = [y, y];
    }

    /// The coefficients `[b0, b1, b2, a1, a2]` as `Q2.30` bits (reports,
    /// parameter blocks).
    pub fn coefficient_bits(&self) -> [i32; 5] {
        self.coeff.ba.map(|c| c.into_bits())
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    use super::*;

    /// Amplitude of the filter's steady-state response to a sinusoid at
    /// `f_hz`, measured by running it.
    fn gain_at(n: &mut Notch, f_hz: f64, fs: f64) -> f64 {
        let amp = 1_000_000.0;
        let total = (fs * 2.0) as usize;
        let mut peak: f64 = 0.0;
        for k in 0..total {
            let x = amp * libm::sin(core::f64::consts::TAU * f_hz * k as f64 / fs);
            let y = n.process(libm::round(x) as i32);
            if k > total / 2 {
                peak = peak.max(f64::from(y).abs());
            }
        }
        peak / amp
    }

    /// The notch removes its centre frequency and passes DC exactly and
    /// frequencies far from it within the closed-form |H| of the
    /// continuous notch (s² + ω0²)/(s² + ω0/Q s + ω0²).
    #[test]
    fn hum_notch_rejects_120_hz_and_passes_dc_and_10_hz() {
        let fs = 20_000.0;
        let mut n = Notch::design(120.0, fs, 2.0).unwrap();
        assert!(gain_at(&mut n, 120.0, fs) < 2e-3);
        let mut n = Notch::design(120.0, fs, 2.0).unwrap();
        let g10 = gain_at(&mut n, 10.0, fs);
        let w = 10.0 / 120.0;
        let closed: f64 =
            (1.0 - w * w) / libm::sqrt((1.0 - w * w) * (1.0 - w * w) + (w / 2.0) * (w / 2.0));
        assert!((g10 - closed).abs() < 2e-3, "{g10} vs {closed}");
        let mut n = Notch::design(120.0, fs, 2.0).unwrap();
        let mut y = 0;
        for _ in 0..40_000 {
            y = n.process(123_456);
        }
        // DC gain one; idsp's truncating recursion leaves at most 1 LSB.
        assert!((y - 123_456).abs() <= 1, "{y}");
    }

    #[test]
    fn settled_notch_has_no_transient() {
        let mut n = Notch::design(3150.0, 20_000.0, 1.0).unwrap();
        n.settle_at(-77_000);
        for _ in 0..100 {
            assert_eq!(n.process(-77_000), -77_000);
        }
    }

    #[test]
    fn notch_refuses_frequency_beyond_nyquist_and_bad_q() {
        assert_eq!(
            Notch::design(12_000.0, 20_000.0, 1.0).err(),
            Some(FilterError::Frequency)
        );
        assert_eq!(
            Notch::design(100.0, 20_000.0, 0.0).err(),
            Some(FilterError::Quality)
        );
    }
}
