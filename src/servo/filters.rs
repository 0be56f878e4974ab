//! Second-order filters of the loop: the 120 Hz hum canceller on the feedback and
//! the coil-frame-mode notch on the amplifier command.
//!
//! The arithmetic is `idsp`'s (quartiq): a biquad in direct form I with
//! `Q2.30` coefficients, 32-bit state and first-order error feedback
//! ([`idsp::iir::DirectForm1Dither`]: the recursion's rounding error is fed
//! back into the next sample, which shapes it away from low frequencies).
//! A notch at 120 Hz sampled at 20 kHz has its poles within 0.001 of the
//! unit circle, where a plain 32-bit recursion amplifies its own rounding
//! several hundred times; with the error feedback the rounding stays
//! within a few LSB of the input (measured in `notch_rounding_is_a_few_lsb`:
//! about 5 LSB RMS, 20 peak on the 120 Hz Q 20 notch; in the loop's Q8 codes that is
//! 0.02 gauge codes, 4e-4 µin), at 5 multiply-accumulates a sample instead
//! of the 64-bit output state's nine. The same integer operations run on
//! the host and the target, so the filter is bit-exact across them.
//!
//! Signals are `i32` in whatever fixed-point format the caller chooses; the
//! gain at DC is exactly one (b0 + b1 + b2 = 1 − a1 − a2 in the rounded
//! coefficients, see [`Notch::design`]), so a notch never offsets a
//! position.

use dsp_fixedpoint::Q32;
use dsp_process::SplitProcess;
use idsp::iir::{coefficients::Filter, Biquad, DirectForm1Dither};

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
    state: DirectForm1Dither,
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
            state: DirectForm1Dither::default(),
        })
    }

    /// A notch from coefficient bits made by [`Self::design`] (a parameter
    /// block), with a zero state.
    pub fn from_bits(ba: [i32; 5]) -> Self {
        Self {
            coeff: Biquad {
                ba: ba.map(Q32::<30>::from_bits),
            },
            state: DirectForm1Dither::default(),
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
        self.state.xy.x = [x, x];
        self.state.xy.y = [[x, x]];
        self.state.e = 0;
    }

    /// The coefficients `[b0, b1, b2, a1, a2]` as `Q2.30` bits (reports,
    /// parameter blocks).
    pub fn coefficient_bits(&self) -> [i32; 5] {
        self.coeff.ba.map(|c| c.into_bits())
    }
}

/// The hum canceller: `y = x − R(x)`, `R` a resonator at the hum's
/// frequency that estimates the hum in `x` (the linear equivalent of a
/// synchronous, adaptive feed-forward canceller whose adaptation has a phase
/// advance θ: Widrow's adaptive noise canceller with a sinusoidal reference
/// is a notch). One biquad and a subtraction.
///
/// `R = B / (A + B)` with `A(z) = z² − 2 cos ω₀ z + 1` (zeros of `1 − R` on
/// the unit circle at `f0`: the hum is removed whatever θ) and
/// `B(z) = (z − 1)(c₁z + c₀)` (`R(1) = 0`: DC passes with gain one, exactly
/// in the integer coefficients), fixed by `B(z₀) = α(1 + z₀)·e^{−jθ}` at
/// `z₀ = e^{jω₀}`, `α = sin ω₀ / 2Q`: `c₁ = α sin(ω₀/2 − θ) / sin(ω₀/2)`,
/// `c₀ = 2α cos(ω₀/2) cos(ω₀/2 − θ) − c₁ cos ω₀`. With θ = 0, `R` is the RBJ
/// band-pass and `1 − R` the RBJ notch of the same Q.
///
/// Why θ: in a loop with sensitivity `S`, a narrow notch's pole pair moves
/// to `s ≈ jω₀ − (ω₀/2Q)·e^{−jθ}·S(jω₀)`: it stays damped while
/// `|arg S(jω₀) − θ| < 90°`, and the peak of `|S|` the notch raises beside
/// `f0` falls as θ follows `arg S(jω₀)`. The engaged part's spring sweeps
/// `arg S(120 Hz)` over ≈ 55° .. 80° (docs/TUNING.md). The continuous
/// prototype of `1 − R` is `(s² + ω₀²) / ((1 − sin θ / Q) s² + (ω₀/Q) cos θ
/// · s + ω₀²)`: its gain far above `f0` is `1 / (1 − sin θ / Q)` (1.026 at
/// θ 30°, Q 20), more than the `Q2.30` range of a direct-form notch's
/// `b1` allows, hence `x − R(x)` (R's coefficients are small).
#[derive(Clone, Debug)]
pub struct Canceller {
    coeff: Biquad<Q32<30>>,
    state: DirectForm1Dither,
}

impl Canceller {
    /// The canceller at `f0_hz` sampled at `fs_hz`, quality factor `q` (of
    /// the equivalent notch: centre / −3 dB width), advance `turn_rad`
    /// (|θ| < 90°: beyond it the notch alone, S = 1, is unstable).
    pub fn design(f0_hz: f64, fs_hz: f64, q: f64, turn_rad: f64) -> Result<Self, FilterError> {
        if !(f0_hz > 0.0 && fs_hz > 0.0 && f0_hz < fs_hz / 2.0 && f0_hz.is_finite()) {
            return Err(FilterError::Frequency);
        }
        if !(q > 0.0 && q.is_finite() && libm::fabs(turn_rad) < 0.5 * core::f64::consts::PI) {
            return Err(FilterError::Quality);
        }
        let w0 = core::f64::consts::TAU * f0_hz / fs_hz;
        let al = libm::sin(w0) / (2.0 * q);
        let (h, c) = (0.5 * w0, libm::cos(w0));
        let c1 = al * libm::sin(h - turn_rad) / libm::sin(h);
        let c0 = 2.0 * al * libm::cos(h) * libm::cos(h - turn_rad) - c1 * c;
        // Poles inside the unit circle: a0 > 0, |a2| < 1, |a1| < 1 + a2.
        let a0 = 1.0 + c1;
        let (a1, a2) = ((c0 - c1 - 2.0 * c) / a0, (1.0 - c0) / a0);
        if !(a0 > 0.0 && libm::fabs(a2) < 1.0 && libm::fabs(a1) < 1.0 + a2) {
            return Err(FilterError::Quality);
        }
        let one = (1u64 << 30) as f64;
        let r = |x: f64| libm::round(x * one) as i64;
        let (b0, b2) = (r(c1 / a0), r(-c0 / a0));
        // R(1) = 0 exactly: DC passes the canceller untouched.
        let b1 = -b0 - b2;
        // idsp's sign convention: y0 = b·x + a1·y1 + a2·y2.
        let (a1, a2) = (-r(a1), -r(a2));
        let fits = |v: i64| v >= i64::from(i32::MIN) && v <= i64::from(i32::MAX);
        if ![b0, b1, b2, a1, a2].into_iter().all(fits) {
            return Err(FilterError::Quality);
        }
        Ok(Self::from_bits([b0, b1, b2, a1, a2].map(|v| v as i32)))
    }

    /// A canceller from the resonator's coefficient bits made by
    /// [`Self::design`] (a parameter block), with a zero state.
    pub fn from_bits(ba: [i32; 5]) -> Self {
        Self {
            coeff: Biquad {
                ba: ba.map(Q32::<30>::from_bits),
            },
            state: DirectForm1Dither::default(),
        }
    }

    /// One sample: the input less the resonator's estimate of the hum.
    #[inline]
    pub fn process(&mut self, x: i32) -> i32 {
        x.saturating_sub(self.coeff.process(&mut self.state, x))
    }

    /// The resonator's coefficients `[b0, b1, b2, a1, a2]`, `Q2.30` bits.
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
        response_at(&mut |x| n.process(x), f_hz, fs)
    }

    /// Steady-state gain of `process` at `f_hz`, measured by running it.
    fn response_at(process: &mut dyn FnMut(i32) -> i32, f_hz: f64, fs: f64) -> f64 {
        let amp = 1_000_000.0;
        let total = (fs * 2.0) as usize;
        let mut peak: f64 = 0.0;
        for k in 0..total {
            let x = amp * libm::sin(core::f64::consts::TAU * f_hz * k as f64 / fs);
            let y = process(libm::round(x) as i32);
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
        // DC gain one: the error feedback leaves no offset.
        assert!((y - 123_456).abs() <= 1, "{y}");
    }

    /// The recursion's rounding against the same filter in f64 on the same
    /// integer input (a loop-like signal in Q8 codes: DC, a 10 Hz command,
    /// white noise): a few LSB for the 120 Hz Q 20 hum notch, whose poles
    /// lie within 0.001 of the unit circle (a plain 32-bit recursion is off
    /// by hundreds of LSB there), and about one for the 3150 Hz mode notch.
    #[test]
    fn notch_rounding_is_a_few_lsb() {
        let fs = 20_000.0;
        for (f0, q, rms_max, peak_max) in [(120.0, 20.0, 8.0, 40.0), (3150.0, 0.7, 1.0, 3.0)] {
            let mut n = Notch::design(f0, fs, q).unwrap();
            let c = n
                .coefficient_bits()
                .map(|v| f64::from(v) / f64::from(1u32 << 30));
            let (mut x1, mut x2, mut y1, mut y2) = (0.0, 0.0, 0.0, 0.0);
            let mut seed = 12_345u64;
            let (mut sum, mut peak, mut count) = (0.0f64, 0.0f64, 0.0);
            for k in 0..200_000 {
                seed = seed
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                let noise = ((seed >> 33) as f64 / (1u64 << 31) as f64) * 2.0 - 1.0;
                let t = f64::from(k) / fs;
                let codes = 50_000.0
                    + 20_000.0 * libm::sin(core::f64::consts::TAU * 10.0 * t)
                    + 500.0 * noise;
                let x = libm::round(codes * 256.0) as i32;
                let y = n.process(x);
                let xf = f64::from(x);
                let exact = c[0] * xf + c[1] * x1 + c[2] * x2 + c[3] * y1 + c[4] * y2;
                (x2, x1, y2, y1) = (x1, xf, y1, exact);
                if k > 50_000 {
                    let e = f64::from(y) - exact;
                    sum += e * e;
                    peak = peak.max(e.abs());
                    count += 1.0;
                }
            }
            let rms = libm::sqrt(sum / count);
            assert!(
                rms < rms_max && peak < peak_max,
                "{f0} Hz: {rms} RMS, {peak} peak"
            );
        }
    }

    /// Steady-state gain of the canceller at `f_hz`, measured by running it.
    fn canceller_gain_at(c: &mut Canceller, f_hz: f64, fs: f64) -> f64 {
        response_at(&mut |x| c.process(x), f_hz, fs)
    }

    /// The hum canceller removes its frequency and passes DC exactly,
    /// turned or not; beside it (±3 Hz, half its width) and away from it its
    /// |H| is the continuous prototype's closed form `|ω₀² − ω²| / |ω₀² −
    /// (1 − sin θ/Q) ω² + j (ω₀/Q) cos θ ω|`, lopsided when turned; with no
    /// turn it is the plain notch of the same Q.
    #[test]
    fn canceller_rejects_its_frequency_with_the_prototype_response() {
        let fs = 20_000.0;
        let (f0, q) = (120.0, 20.0);
        for turn_deg in [-45.0f64, 0.0, 30.0, 60.0] {
            let th = turn_deg.to_radians();
            let mut c = Canceller::design(f0, fs, q, th).unwrap();
            let g0 = canceller_gain_at(&mut c, f0, fs);
            assert!(g0 < 2e-3, "{turn_deg}: {g0} at {f0} Hz");
            for f in [f0 - 3.0, f0 + 3.0, 60.0, 300.0] {
                let mut c = Canceller::design(f0, fs, q, th).unwrap();
                let g = canceller_gain_at(&mut c, f, fs);
                let (w0, w) = (core::f64::consts::TAU * f0, core::f64::consts::TAU * f);
                let re = w0 * w0 - (1.0 - libm::sin(th) / q) * w * w;
                let im = w0 / q * libm::cos(th) * w;
                let closed = libm::fabs(w0 * w0 - w * w) / libm::sqrt(re * re + im * im);
                assert!(
                    (g / closed - 1.0).abs() < 0.02,
                    "turn {turn_deg}: {f} Hz {g} vs {closed}"
                );
            }
            let mut c = Canceller::design(f0, fs, q, th).unwrap();
            let mut y = 0;
            for _ in 0..40_000 {
                y = c.process(123_456);
            }
            assert!((y - 123_456).abs() <= 1, "{turn_deg}: {y}");
        }
        assert_eq!(
            Canceller::design(f0, fs, q, 1.6).err(),
            Some(FilterError::Quality)
        );
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
