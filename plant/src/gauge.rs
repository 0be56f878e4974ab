//! The capacitance gauge: 1 V per mil, ±0.010 in (±10 V) range with
//! saturation, and its noise: band-limited white noise plus power-supply
//! hum at 120 Hz (chapter 4, Fig 4-8: "a 120 Hz, 5 mV noise signal ...
//! over wider time traces appeared as 10 mV"; chapter 5: ≈ 20 µin reached
//! the error signal with the loop closed).
//!
//! The broadband part is an Ornstein–Uhlenbeck process (white noise through
//! a first-order low-pass of bandwidth `white_bw_hz`), updated exactly
//! between samples: `n ← e^{−h/τ} n + σ sqrt(1 − e^{−2h/τ}) w`, so its RMS
//! and spectrum are right for any sample spacing. Seeded xoshiro256++ with
//! the ziggurat normal: the same seed and the same sample instants give
//! bit-identical noise.

// The f64 functions of `libm` where std's are missing (no_std builds);
// with std the inherent methods are used and the import is idle.
#[allow(unused_imports)]
use num_traits::Float;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use rand_xoshiro::Xoshiro256PlusPlus;

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct GaugeParams {
    /// Sensitivity, V/in (1 V/mil).
    pub v_per_in: f64,
    /// Output saturation, ±V (±0.010 in).
    pub range_v: f64,
    /// The gauge reads −Z as positive volts (the 1983 gauge after it was
    /// moved to the 7 o'clock position, chapter 4).
    pub reversed: bool,
    /// RMS of the broadband noise, in.
    pub white_rms_in: f64,
    /// Bandwidth of the broadband noise, Hz.
    pub white_bw_hz: f64,
    /// Amplitude (peak) of the hum at `hum_hz`, in.
    pub hum_amp_in: f64,
    pub hum_hz: f64,
    /// Amplitude of the second hum harmonic (240 Hz), in.
    pub hum2_amp_in: f64,
}

impl GaugeParams {
    /// The 1983 gauge: 5 µin peak of 120 Hz hum (Fig 4-8's 5 mV) and
    /// broadband noise making 10 µin RMS in total.
    pub fn legacy() -> Self {
        let hum: f64 = 5.0e-6;
        let total: f64 = 10.0e-6;
        let white = (total * total - hum * hum / 2.0).sqrt();
        Self {
            v_per_in: 1000.0,
            range_v: 10.0,
            reversed: false,
            white_rms_in: white,
            white_bw_hz: 5000.0,
            hum_amp_in: hum,
            hum_hz: 120.0,
            hum2_amp_in: 0.0,
        }
    }
    /// A modern low-noise gauge with clean supplies: 0.2 µin RMS, no hum.
    pub fn modern() -> Self {
        Self {
            white_rms_in: 0.2e-6,
            hum_amp_in: 0.0,
            ..Self::legacy()
        }
    }
    /// Noise off: for transfer-function measurements and closed-form tests.
    pub fn noiseless() -> Self {
        Self {
            white_rms_in: 0.0,
            hum_amp_in: 0.0,
            hum2_amp_in: 0.0,
            ..Self::legacy()
        }
    }
    /// Total noise RMS, in.
    pub fn total_rms_in(&self) -> f64 {
        (self.white_rms_in.powi(2) + self.hum_amp_in.powi(2) / 2.0 + self.hum2_amp_in.powi(2) / 2.0)
            .sqrt()
    }
}

#[derive(Clone, Debug)]
pub struct Gauge {
    pub params: GaugeParams,
    rng: Xoshiro256PlusPlus,
    ou: f64,
    last_ns: Option<u64>,
    hum_phase: f64,
    hum2_phase: f64,
    /// OU coefficients for the last sample spacing: (h ns, a, sqrt(1 − a²)).
    ou_coef: (u64, f64, f64),
    /// Hum phasor (sin, cos of the hum phase) at `hum_t_ns`, advanced by
    /// rotation when samples are evenly spaced (the loop timer): no `sin`
    /// per sample. Recomputed exactly every `HUM_EXACT_EVERY` samples and on
    /// any change of spacing, so rounding drift stays below 1e-12.
    hum_sc: (f64, f64),
    hum_t_ns: Option<u64>,
    hum_rot: (u64, f64, f64),
    hum_n: u32,
}

const HUM_EXACT_EVERY: u32 = 4096;

impl Gauge {
    pub fn new(params: GaugeParams, seed: u64) -> Self {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let hum_phase = rng.random::<f64>() * core::f64::consts::TAU;
        let hum2_phase = rng.random::<f64>() * core::f64::consts::TAU;
        let ou = params.white_rms_in * gaussian(&mut rng);
        Self {
            params,
            rng,
            ou,
            last_ns: None,
            hum_phase,
            hum2_phase,
            ou_coef: (0, 1.0, 0.0),
            hum_sc: (0.0, 1.0),
            hum_t_ns: None,
            hum_rot: (0, 0.0, 1.0),
            hum_n: 0,
        }
    }

    /// Noise at `t_ns`, in. Must be called with non-decreasing times.
    pub fn noise_in(&mut self, t_ns: u64) -> f64 {
        let p = &self.params;
        if p.white_rms_in > 0.0 {
            let h_ns = self.last_ns.map_or(0, |l| t_ns.saturating_sub(l));
            if h_ns > 0 {
                if self.ou_coef.0 != h_ns {
                    let tau = 1.0 / (core::f64::consts::TAU * p.white_bw_hz);
                    let a = (-(h_ns as f64 * 1e-9) / tau).exp();
                    self.ou_coef = (h_ns, a, (1.0 - a * a).sqrt());
                }
                let w = gaussian(&mut self.rng);
                self.ou = self.ou_coef.1 * self.ou + p.white_rms_in * self.ou_coef.2 * w;
            }
        }
        self.last_ns = Some(t_ns);
        let mut n = self.ou;
        if p.hum_amp_in != 0.0 || p.hum2_amp_in != 0.0 {
            let w = core::f64::consts::TAU * p.hum_hz;
            let h = self.hum_t_ns.map(|l| t_ns.saturating_sub(l));
            match h {
                Some(h) if h == self.hum_rot.0 && self.hum_n < HUM_EXACT_EVERY => {
                    let (s0, c0) = self.hum_sc;
                    let (_, rs, rc) = self.hum_rot;
                    self.hum_sc = (s0 * rc + c0 * rs, c0 * rc - s0 * rs);
                    self.hum_n += 1;
                }
                _ => {
                    let t = t_ns as f64 * 1e-9;
                    self.hum_sc = (w * t + self.hum_phase).sin_cos();
                    if let Some(h) = h {
                        if h != self.hum_rot.0 {
                            let (rs, rc) = (w * h as f64 * 1e-9).sin_cos();
                            self.hum_rot = (h, rs, rc);
                        }
                    }
                    self.hum_n = 0;
                }
            }
            self.hum_t_ns = Some(t_ns);
            let (s1, c1) = self.hum_sc;
            n += p.hum_amp_in * s1;
            if p.hum2_amp_in != 0.0 {
                // sin(2θ + φ2 − 2φ1) from the phasor of θ + φ1.
                let (s2, c2) = (2.0 * s1 * c1, c1 * c1 - s1 * s1);
                let d = self.hum2_phase - 2.0 * self.hum_phase;
                n += p.hum2_amp_in * (s2 * d.cos() + c2 * d.sin());
            }
        }
        n
    }

    /// The hum's phases (fundamental, second harmonic), rad at t = 0.
    pub fn hum_phases(&self) -> (f64, f64) {
        (self.hum_phase, self.hum2_phase)
    }

    /// The broadband noise's state, in (the last sample's, without hum).
    pub fn noise_state(&self) -> f64 {
        self.ou
    }

    /// Continues the broadband noise from `ou_in` at `t_ns` (a model that
    /// carried the same process until then hands it back).
    pub fn continue_noise_from(&mut self, ou_in: f64, t_ns: u64) {
        self.ou = ou_in;
        self.last_ns = Some(t_ns);
    }

    /// Gauge output volts at `t_ns` for the position it sees `z_in`
    /// (saturated at ±range).
    pub fn volts(&mut self, t_ns: u64, z_in: f64) -> f64 {
        let n = self.noise_in(t_ns);
        self.volts_noiseless(z_in + n)
    }

    /// Output for a position without noise (saturated).
    pub fn volts_noiseless(&self, z_in: f64) -> f64 {
        let sign = if self.params.reversed { -1.0 } else { 1.0 };
        crate::fastmath::clamp_symmetric(sign * z_in * self.params.v_per_in, self.params.range_v)
    }
}

/// Full scale of the gauge ADC (AD4020 class, 20 bits), ±V.
pub const ADC_FULL_SCALE_V: f64 = 10.0;

/// The gauge ADC's conversion of `volts`: code = round(V · 2¹⁹ / 10 V),
/// clamped to [−2¹⁹, 2¹⁹ − 1] (NaN → 0), and the over-range flag (input
/// at or beyond full scale, or NaN). 1 LSB = 19.07 µV = 0.019 µin.
#[inline]
pub fn adc_convert(volts: f64) -> (i32, bool) {
    let max = (1i32 << 19) - 1;
    let min = -(1i32 << 19);
    let raw = crate::fastmath::round_i64(volts * f64::from(1u32 << 19) / ADC_FULL_SCALE_V);
    let code = raw.clamp(i64::from(min), i64::from(max)) as i32;
    let ov = volts.abs() >= ADC_FULL_SCALE_V || volts.is_nan();
    (code, ov)
}

/// Standard normal deviate: the ziggurat of `rand_distr` (≈ 15
/// instructions in the common case; Marsaglia's polar method with its `ln`
/// and `sqrt` was ≈ 80 a deviate). Deterministic for a seeded generator.
pub fn gaussian<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    rng.sample(StandardNormal)
}
