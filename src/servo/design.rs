//! From physical design parameters (f64, at configuration time) to the
//! integer coefficients the loop tick runs ([`ServoConfig`]).
//!
//! The design, continuous time, in the loop's units (gauge codes for
//! position, amplifier-DAC codes for the input; both 2¹⁹ codes per 10 V):
//!
//! ```text
//! plant   P(s) = K / (s (s + a)),  K = G·Kf/(R·M)·(gauge V/in),  a = (B + Kf·Kb/R)/M
//! law     u = (r̈ + a ṙ)/K                      feedforward: the rigid plant's inverse
//!           + (ω²/K)(r − ẑ) + ((2ζω − a)/K)(ṙ − v̂)   state feedback on the error
//!           − d̂                                 disturbance (integral action)
//! ```
//!
//! With perfect estimates the tracking error obeys ë + 2ζω ė + ω² e = 0, so
//! `bandwidth_hz` and `damping` are the error dynamics' natural frequency
//! and damping; the observer's three poles sit at `observer_hz` (real,
//! triple, by Ackermann's formula on the sampled model). The electrical pole
//! (L/R = 0.26 ms, 610 Hz) is neglected in the model: it is 15× above the
//! default bandwidth, and the robustness test covers the error.
//!
//! Why the bandwidth is low (16 Hz by default, where the 1983 loop had
//! more than 100 Hz): the gauge noise is measurement noise, and any feedback that
//! follows the gauge at a frequency moves the slide with the noise there.
//! The gauge's broadband noise (9.35 µin RMS, 5 kHz corner) has a density of
//! ≈ 0.106 µin/√Hz, so a loop that follows it to 90 Hz already moves the
//! slide 1 µin RMS. Tracking does not need the bandwidth: the feedforward
//! inverts the plant, and the spindle-synchronous learning removes what the
//! model misses at every harmonic of the spindle.

use super::filters::{Canceller, FilterError, Notch};
use super::observer::ObserverCoeffs;

/// Amplifier-DAC codes per volt.
pub const DAC_CODES_PER_V: f64 = 524_288.0 / 10.0;

// The slide model's and the design's fields and defaults, from the one
// parameter table (`super::parameters`).
macro_rules! design_types {
    (
        design { $(($id:literal, $name:ident, $ty:ident, $unit:literal, $default:expr,
            $min:expr, $max:expr, $doc:literal)),+ $(,)? }
        slide { $(($sid:literal, $sname:ident, $sfield:ident, $sty:ident, $sunit:literal,
            $sdefault:expr, $smin:expr, $smax:expr, $sdoc:literal)),+ $(,)? }
    ) => {
        /// The physical slide as the loop's model sees it (the brief's numbers,
        /// chapter 4; inch units as in `docs/PLANT.md`). Its fields are the
        /// parameter table's `slide` part (`super::parameters`).
        #[derive(Clone, Copy, Debug, PartialEq)]
        pub struct SlideModel {
            $(#[doc = $sdoc] pub $sfield: $sty,)+
        }

        impl SlideModel {
            /// The brief's slide: Model 15 motor (Kf 2.9 lbf/A, Kb 4.002 V·s/ft,
            /// R 1.4 Ω), 6.25 lbm, B = 51.2 lbf·s/ft, ×10 amplifier, 1 V/mil gauge.
            pub const BRIEF: Self = Self {
                $($sfield: $sdefault,)+
            };
        }

        /// Design parameters of the loop. Every field has a physical unit;
        /// the `[servo]` section of a scenario file sets them. Besides the rate
        /// and the slide, the fields are the parameter table's `design` part
        /// (`super::parameters`).
        #[derive(Clone, Copy, Debug, PartialEq)]
        pub struct ServoDesign {
            /// Loop tick rate, Hz (≥ 20 kHz in the brief; the default design needs
            /// ≥ 8 kHz: fast observer below rate / 10).
            pub rate_hz: u32,
            pub slide: SlideModel,
            $(#[doc = $doc] pub $name: $ty,)+
        }

        impl ServoDesign {
            /// The default loop for the brief's slide at `rate_hz`.
            ///
            /// Bandwidth and observer are set by the cut, not by the slide alone:
            /// while cutting, the tool's engagement is a spring to the part (the
            /// edge force on the nose's contact chord, ≈ 2200 lbf/in at 0.0003 in
            /// depth, a 58 Hz spring-mass with the slide). A disturbance observer
            /// at 40 Hz treats that spring as a slow disturbance and leaves a
            /// lightly damped mode near 60 Hz (ζ 0.3; `docs/TUNING.md`); at 250 Hz
            /// it cancels the spring across the band and the 45 Hz error dynamics
            /// stay damped. The price is more gauge noise passed to the slide, and
            /// a narrow hum notch (Q 20) so that its phase lag stays out of the
            /// ≈ 95 Hz crossover (`docs/TUNING.md` has the figures).
            pub const fn brief(rate_hz: u32) -> Self {
                Self {
                    rate_hz,
                    slide: SlideModel::BRIEF,
                    $($name: $default,)+
                }
            }
        }
    };
}
crate::servo_parameters!(design_types);

impl SlideModel {
    /// K of P(s) = K/(s(s+a)), gauge codes per DAC code per s².
    pub fn gain_per_s2(&self) -> f64 {
        // DAC code → V → ×G motor V → Kf/R lbf → /M in/s² → gauge V; the
        // ADC and DAC have the same codes per volt, so gauge V are codes.
        self.amp_gain * self.kf_lbf_per_a / (self.r_ohm * self.mass_lbf_s2_per_in)
            * self.gauge_v_per_in
    }

    /// Gauge codes per inch.
    pub fn codes_per_in(&self) -> f64 {
        self.gauge_v_per_in * DAC_CODES_PER_V
    }

    /// a of P(s), 1/s: friction plus back-EMF damping over mass.
    pub fn pole_per_s(&self) -> f64 {
        (self.b_lbf_s_per_in + self.kf_lbf_per_a * self.kb_v_s_per_in / self.r_ohm)
            / self.mass_lbf_s2_per_in
    }
}

impl ServoDesign {
    /// Contour monitoring's depth guard, µin: the depth of cut less the
    /// retract's stopping distance (docs/SAFETY.md, "Contour monitoring").
    /// The tool crossing the guard moves on at its speed `v` for the
    /// detection (`DEPTH_GUARD_TICKS` + the tick that latches) and, once
    /// the retract's loop takes it back, for about one time constant of
    /// the error dynamics, 1/ω (ω = 2π·`bandwidth_hz`): `v·(t_d + 1/ω)`.
    /// The fastest error motion the oscillation limit lets pass is a ring
    /// at the loop's bandwidth with RMS `oscillation_uin`: `v = ω·√2·σ`,
    /// so the stop is `√2·σ·(1 + ω·t_d)`. A faster swing is an oscillation
    /// (`Fault::Oscillation`).
    pub fn depth_guard_uin(&self) -> f64 {
        let w = core::f64::consts::TAU * self.bandwidth_hz;
        let t_d = f64::from(DEPTH_GUARD_TICKS + 1) / f64::from(self.rate_hz);
        self.depth_of_cut_uin - core::f64::consts::SQRT_2 * self.oscillation_uin * (1.0 + w * t_d)
    }

    /// The integer configuration, or the first parameter out of range.
    // Every range test is written `!(in range)` so that a NaN is refused.
    #[allow(clippy::nonminimal_bool)]
    pub fn config(&self) -> Result<ServoConfig, DesignError> {
        use DesignError as E;
        let fs = f64::from(self.rate_hz);
        if !(1_000.0..=200_000.0).contains(&fs) {
            return Err(E::Rate);
        }
        let h = 1.0 / fs;
        let s = &self.slide;
        let physical = [
            s.kf_lbf_per_a,
            s.kb_v_s_per_in,
            s.r_ohm,
            s.mass_lbf_s2_per_in,
            s.b_lbf_s_per_in,
            s.amp_gain,
            s.gauge_v_per_in,
        ];
        if !physical.iter().all(|v| v.is_finite() && *v > 0.0) {
            return Err(E::Slide);
        }
        let k = s.gain_per_s2();
        let a = s.pole_per_s();
        if !(self.bandwidth_hz > 0.0 && self.bandwidth_hz < fs / 20.0) {
            return Err(E::Bandwidth);
        }
        if !(self.damping > 0.0 && self.damping <= 5.0) {
            return Err(E::Damping);
        }
        if !(self.observer_hz > 0.0 && self.observer_hz < fs / 10.0) {
            return Err(E::Observer);
        }
        let w = core::f64::consts::TAU * self.bandwidth_hz;
        if !(self.bandwidth_fast_hz >= self.bandwidth_hz && self.bandwidth_fast_hz < fs / 20.0) {
            return Err(E::BandwidthFast);
        }
        let wf = core::f64::consts::TAU * self.bandwidth_fast_hz;
        let q24 = (1u64 << 24) as f64;
        let kp = w * w / k;
        let kd = (2.0 * self.damping * w - a) / (k * h);
        let kff = a / (k * h);
        let ka = 1.0 / (k * h * h);
        let gain = |v: f64, one: f64| -> Result<i32, DesignError> {
            let bits = libm::round(v * one);
            if bits.is_finite() && bits.abs() < 2_147_483_647.0 {
                Ok(bits as i32)
            } else {
                Err(E::GainRange)
            }
        };

        // Observer on the sampled rigid model.
        let e = libm::exp(-a * h);
        let a12 = (1.0 - e) / (a * h);
        let a22 = e;
        let b1 = k * (h / a - (1.0 - e) / (a * a));
        let b2 = k * h * (1.0 - e) / a;
        let pole = |hz: f64| libm::exp(-core::f64::consts::TAU * hz * h);
        let l = observer_gains(a12, a22, b1, b2, pole(self.observer_hz)).ok_or(E::Observer)?;
        if !(self.observer_fast_hz >= self.observer_hz && self.observer_fast_hz < fs / 10.0)
            || !(self.observer_switch_uin > 0.0 && self.observer_switch_uin <= 10_000.0)
            || !(self.observer_hold_ms >= 0.0 && self.observer_hold_ms <= 10_000.0)
        {
            return Err(E::ObserverFast);
        }
        let lf =
            observer_gains(a12, a22, b1, b2, pole(self.observer_fast_hz)).ok_or(E::ObserverFast)?;
        let q30 = (1u64 << 30) as f64;
        let coeff = |v: f64| -> Result<i32, DesignError> {
            if v.abs() < 1.999 {
                Ok(libm::round(v * q30) as i32)
            } else {
                Err(E::Observer)
            }
        };
        let observer = ObserverCoeffs {
            c1: coeff(1.0 - a12)?,
            c2: coeff(1.0 - a22)?,
            b1: coeff(b1)?,
            b2: coeff(b2)?,
            l1: coeff(l[0])?,
            l2: coeff(l[1])?,
            l3: gain(l[2], q24).map_err(|_| E::Observer)?,
            fast: [
                coeff(lf[0])?,
                coeff(lf[1])?,
                gain(lf[2], q24).map_err(|_| E::ObserverFast)?,
            ],
            switch_q8: (self.observer_switch_uin * 1e-6 * s.codes_per_in() * 256.0) as i32,
            hold_ticks: libm::round(self.observer_hold_ms * 1e-3 * fs) as u32,
        };

        let notch = |f0: f64, q: f64, err: DesignError| -> Result<Option<[i32; 5]>, DesignError> {
            if q == 0.0 {
                return Ok(None);
            }
            Notch::design(f0, fs, q)
                .map(|n| Some(n.coefficient_bits()))
                .map_err(|e| match e {
                    FilterError::Frequency | FilterError::Quality => err,
                })
        };
        let hum = if self.hum_notch_q == 0.0 {
            None
        } else {
            let turn = self.hum_notch_turn_deg.to_radians();
            let c = Canceller::design(self.hum_notch_hz, fs, self.hum_notch_q, turn)
                .map_err(|_| E::HumNotch)?;
            Some(c.coefficient_bits())
        };
        let mode = notch(self.mode_notch_hz, self.mode_notch_q, E::ModeNotch)?;

        if !(0.0..1.0).contains(&self.learning_gain) {
            return Err(E::Learning);
        }
        if !(3..=32).contains(&self.learning_lead_bins)
            || !(1..=3).contains(&self.learning_q_shift)
            || !(self.learning_clip_uin > 0.0 && self.learning_clip_uin <= 10_000.0)
            || !(self.learning_lowpass_hz >= 0.0 && self.learning_lowpass_hz < fs / 10.0)
        {
            return Err(E::Learning);
        }
        let cpi = s.codes_per_in();
        let codes_per_tick = |in_per_s: f64| in_per_s * cpi * h;
        if !(self.slew_in_per_s > 0.0 && self.slew_in_per_s <= 10.0)
            || !(self.slew_accel_in_per_s2 > 0.0 && self.slew_accel_in_per_s2 <= 1_000.0)
        {
            return Err(E::Slew);
        }
        if !(self.command_limit_in > 0.0 && self.command_limit_in <= 0.010) {
            return Err(E::CommandLimit);
        }
        if !(self.current_limit_a > 0.0 && self.current_limit_a <= 100.0)
            || !(self.current_limit_ms > 0.0 && self.current_limit_ms <= 10_000.0)
        {
            return Err(E::CurrentLimit);
        }
        if !(self.following_error_in > 0.0 && self.following_error_in <= 0.010)
            || !(self.following_error_ms >= 0.0 && self.following_error_ms <= 10_000.0)
        {
            return Err(E::FollowingError);
        }
        if !(self.sign_check_v >= 0.0 && self.sign_check_v <= 2.0)
            || !(self.sign_check_ms > 0.0 && self.sign_check_ms <= 20.0)
        {
            return Err(E::SignCheck);
        }
        if !(self.depth_of_cut_uin >= 1.0 && self.depth_of_cut_uin <= 10_000.0) {
            return Err(E::DepthOfCut);
        }
        if self.edge_feedforward > 1 {
            return Err(E::EdgeFeedforward);
        }
        let depth_guard_uin = self.depth_guard_uin();
        if !(depth_guard_uin >= self.depth_of_cut_uin / 2.0
            && depth_guard_uin <= self.depth_of_cut_uin)
            || !(self.oscillation_uin > 0.0 && self.oscillation_uin <= 10_000.0)
            || !(self.gauge_frozen_ms > 0.0 && self.gauge_frozen_ms <= 10_000.0)
            || self.x_stall_revs > 10_000
            || !(self.retract_z_in >= -0.010 && self.retract_z_in <= 0.010)
        {
            return Err(E::Monitor);
        }
        let ticks = |ms: f64| libm::round(ms * 1e-3 * fs).max(1.0) as u32;
        // DAC volts that hold `current_limit_a` through the coil at rest.
        let i_lim_code = self.current_limit_a * s.r_ohm / s.amp_gain * DAC_CODES_PER_V;
        // DAC codes of back-EMF per gauge code per tick of velocity.
        let k_emf = s.kb_v_s_per_in / s.amp_gain * DAC_CODES_PER_V / (cpi * h);
        // Expected gauge move at the end of the first half of the doublet:
        // z(t) = K p (t/a − (1 − e^{−at})/a²).
        let t = self.sign_check_ms * 1e-3;
        let pulse_code = self.sign_check_v * DAC_CODES_PER_V;
        let expected = k * pulse_code * (t / a - (1.0 - libm::exp(-a * t)) / (a * a));

        Ok(ServoConfig {
            rate_hz: self.rate_hz,
            observer,
            kp_q24: gain(kp, q24)?,
            kd_q24: gain(kd, q24)?,
            kp_fast_q24: gain(wf * wf / k, q24)?,
            kd_fast_q24: gain((2.0 * self.damping * wf - a) / (k * h), q24)?,
            kff_q24: gain(kff, q24)?,
            ka_q16: gain(ka, 65_536.0)?,
            hum_canceller: hum,
            mode_notch: mode,
            learning_gain_q16: libm::round(self.learning_gain * 65_536.0) as i32,
            learning_lead_bins: self.learning_lead_bins,
            learning_q_shift: self.learning_q_shift,
            // ≤ 10 000 µin: 1.34·10⁸ < 2²⁸, the learner's product bound.
            learning_clip_q8: libm::round(self.learning_clip_uin * 1e-6 * cpi * 256.0).max(1.0)
                as i32,
            // α = 1 − e^{−2π f h} < 1 − e^{−π/5} = 0.47 (f < rate/10): Q16.
            learning_lowpass_q16: if self.learning_lowpass_hz > 0.0 {
                libm::round(
                    (1.0 - libm::exp(-core::f64::consts::TAU * self.learning_lowpass_hz * h))
                        * 65_536.0,
                )
                .max(1.0) as i32
            } else {
                0
            },
            slew_q16: (codes_per_tick(self.slew_in_per_s) * 65_536.0).max(1.0) as i64,
            slew_accel_q16: (self.slew_accel_in_per_s2 * cpi * h * h * 65_536.0).max(1.0) as i64,
            command_limit_code: (self.command_limit_in * cpi) as i32,
            current_limit_code: gain(i_lim_code, 1.0)?,
            k_emf_q24: gain(k_emf, q24)?,
            current_limit_ticks: ticks(self.current_limit_ms),
            following_error_code: (self.following_error_in * cpi) as i32,
            following_error_ticks: ticks(self.following_error_ms),
            sign_check_code: libm::round(pulse_code) as i32,
            sign_check_ticks: ticks(self.sign_check_ms),
            sign_check_expected_code: libm::round(expected) as i32,
            settle_ticks: libm::round(10.0 / (self.damping * w) * fs) as u32,
            monitor: MonitorConfig {
                // ≤ 10 000 µin: 1.34·10⁸ < 2³¹ Q8.
                depth_guard_q8: libm::round(depth_guard_uin * 1e-6 * cpi * 256.0).max(1.0) as i32,
                // Squared whole codes: ≤ (524 288)² < 2⁴⁰.
                oscillation_sq: {
                    let c = self.oscillation_uin * 1e-6 * cpi;
                    libm::round(c * c).max(1.0) as u64
                },
                gauge_frozen_ticks: ticks(self.gauge_frozen_ms),
                x_stall_revs: self.x_stall_revs,
                retract_code: libm::round(self.retract_z_in * cpi) as i32,
                edge_settle_ticks: libm::round(3.0 / (self.damping * w) * fs) as u32,
            },
            depth_of_cut_uin: libm::round(self.depth_of_cut_uin) as u32,
            edge_feedforward: self.edge_feedforward == 1,
        })
    }

    /// RMS of the velocity estimate (in/s) per µin RMS of white gauge noise
    /// at the loop rate: the observer's noise gain, Σ of its impulse
    /// response squared from the gauge to v̂ (open loop: the estimate's own
    /// filtering, which is what the velocity estimate adds).
    pub fn velocity_noise_gain(&self) -> Option<f64> {
        let fs = f64::from(self.rate_hz);
        let h = 1.0 / fs;
        let k = self.slide.gain_per_s2();
        let a = self.slide.pole_per_s();
        let e = libm::exp(-a * h);
        let (a12, a22) = ((1.0 - e) / (a * h), e);
        let (b1, b2) = (k * (h / a - (1.0 - e) / (a * a)), k * h * (1.0 - e) / a);
        let l = observer_gains(
            a12,
            a22,
            b1,
            b2,
            libm::exp(-core::f64::consts::TAU * self.observer_hz * h),
        )?;
        let (mut z, mut v, mut d) = (0.0, 0.0, 0.0);
        let mut sum = 0.0;
        for n in 0..200_000 {
            let y = if n == 0 { 1.0 } else { 0.0 };
            let zp = z + a12 * v + b1 * d;
            let vp = a22 * v + b2 * d;
            let inn = y - zp;
            z = zp + l[0] * inn;
            v = vp + l[1] * inn;
            d += l[2] * inn;
            sum += v * v;
        }
        // v is codes per tick per code: ×fs = per second; codes → µin cancel.
        Some(libm::sqrt(sum) * fs * 1e-6)
    }
}

/// Observer gains `[l1, l2, l3]` placing all three poles of the current
/// estimator at `p` (Ackermann: L = φ(A)·[CA; CA²; CA³]⁻¹·e₃ with
/// φ(z) = (z − p)³, A the sampled model with the disturbance state, C = [1 0 0]).
fn observer_gains(a12: f64, a22: f64, b1: f64, b2: f64, p: f64) -> Option<[f64; 3]> {
    type M = [[f64; 3]; 3];
    let a: M = [[1.0, a12, b1], [0.0, a22, b2], [0.0, 0.0, 1.0]];
    let mul = |x: &M, y: &M| -> M {
        let mut r = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                r[i][j] = (0..3).map(|k| x[i][k] * y[k][j]).sum();
            }
        }
        r
    };
    let a2 = mul(&a, &a);
    let a3 = mul(&a2, &a);
    // φ(A) = A³ − 3p A² + 3p² A − p³ I
    let mut phi = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let id = if i == j { 1.0 } else { 0.0 };
            phi[i][j] = a3[i][j] - 3.0 * p * a2[i][j] + 3.0 * p * p * a[i][j] - p * p * p * id;
        }
    }
    let o: M = [a[0], a2[0], a3[0]];
    let inv = invert3(&o)?;
    // inv · e3 = third column of inv.
    let col = [inv[0][2], inv[1][2], inv[2][2]];
    let mut l = [0.0; 3];
    for (i, li) in l.iter_mut().enumerate() {
        *li = (0..3).map(|k| phi[i][k] * col[k]).sum();
    }
    // Current estimator: the error obeys e⁺ = (I − L C) A e = (A − L (C A)) e,
    // an observer of the pair (A, C A), hence the observability matrix above.
    l.iter().all(|v| v.is_finite()).then_some(l)
}

fn invert3(m: &[[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    if det.abs() < 1e-300 || !det.is_finite() {
        return None;
    }
    let c = |i: usize, j: usize| {
        let (r0, r1) = ((i + 1) % 3, (i + 2) % 3);
        let (c0, c1) = ((j + 1) % 3, (j + 2) % 3);
        m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0]
    };
    let mut r = [[0.0; 3]; 3];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            // adjugate = transpose of the cofactors
            *v = c(j, i) / det;
        }
    }
    Some(r)
}

/// A design parameter out of its range: `crate::safety::DesignError`,
/// named where the faults are (a refused parameter block latches
/// `Fault::Parameters`).
pub use crate::safety::DesignError;

impl DesignError {
    /// The `[servo]` field (or group) at fault and its limit, in words.
    pub const fn reason(self) -> &'static str {
        match self {
            Self::Rate => "rate_hz: must be 1000..=200000",
            Self::Slide => "slide model: every constant must be positive and finite",
            Self::Bandwidth => "bandwidth_hz: must be > 0 and below rate_hz / 20",
            Self::BandwidthFast => {
                "bandwidth_fast_hz: must be at least bandwidth_hz and below rate_hz / 20"
            }
            Self::Damping => "damping: must be in (0, 5]",
            Self::Observer => "observer_hz: must be > 0 and below rate_hz / 10",
            Self::ObserverFast => "observer_fast_hz in [observer_hz, rate_hz / 10), observer_switch_uin in (0, 10000], observer_hold_ms in [0, 10000]",
            Self::GainRange => "bandwidth_hz/damping: a loop gain exceeds its fixed-point format",
            Self::HumNotch => "hum_notch_hz/hum_notch_q/hum_notch_turn_deg: frequency in (0, rate/2), q > 0 (0 = off), |turn| < 90 with stable poles",
            Self::ModeNotch => {
                "mode_notch_hz/mode_notch_q: frequency in (0, rate/2), q > 0 (0 = off)"
            }
            Self::Learning => {
                "learning_gain in [0, 1), learning_lead_bins 3..=32, learning_q_shift 1..=3 (a weaker Q-filter leaves the harmonics the lead turns past 90° unstable), learning_clip_uin in (0, 10000], learning_lowpass_hz in [0, rate_hz / 10) (0 = off)"
            }
            Self::Slew => "slew_in_per_s in (0, 10], slew_accel_in_per_s2 in (0, 1000]",
            Self::CommandLimit => "command_limit_in: must be in (0, 0.010]",
            Self::CurrentLimit => "current_limit_a in (0, 100], current_limit_ms in (0, 10000]",
            Self::FollowingError => {
                "following_error_in in (0, 0.010], following_error_ms in [0, 10000]"
            }
            Self::SignCheck => "sign_check_v in [0, 2], sign_check_ms in (0, 20]",
            Self::Monitor => {
                "oscillation_uin in (0, 10000], the depth guard (depth_of_cut_uin − √2·oscillation_uin·(1 + 2π·bandwidth_hz·detection)) at least half the depth of cut, gauge_frozen_ms in (0, 10000], x_stall_revs 0..=10000, retract_z_in in [-0.010, 0.010]"
            }
            Self::DepthOfCut => "depth_of_cut_uin: must be in [1, 10000] µin (0.010 in, the gauge's range)",
            Self::EdgeFeedforward => "edge_feedforward: 0 (off) or 1 (on)",
        }
    }
}

/// The loop's integer configuration (what a parameter block stores).
/// Formats are in the names: `_q24` = value·2²⁴, gains in DAC codes per
/// gauge code (per tick, per tick² for the derivative and feedforward
/// terms), limits in codes and ticks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct ServoConfig {
    pub rate_hz: u32,
    pub observer: ObserverCoeffs,
    pub kp_q24: i32,
    pub kd_q24: i32,
    /// The state-feedback gains while the fast observer is on.
    pub kp_fast_q24: i32,
    pub kd_fast_q24: i32,
    pub kff_q24: i32,
    pub ka_q16: i32,
    /// The hum canceller's resonator `[b0, b1, b2, a1, a2]`, Q30
    /// (`filters::Canceller`; None = off).
    pub hum_canceller: Option<[i32; 5]>,
    /// Notch coefficients `[b0, b1, b2, a1, a2]`, Q30 (None = off).
    pub mode_notch: Option<[i32; 5]>,
    pub learning_gain_q16: i32,
    pub learning_lead_bins: u32,
    pub learning_q_shift: u32,
    /// The clip on the error the learning takes in, gauge codes Q8
    /// (`learning_clip_uin`; `servo::repetitive`).
    pub learning_clip_q8: i32,
    /// The learning's low-pass on the error, `α = 1 − e^{−2π f h}` Q16
    /// (`learning_lowpass_hz`; 0 = off; `servo::repetitive`).
    pub learning_lowpass_q16: i32,
    /// Largest command step per tick, gauge codes Q16.
    pub slew_q16: i64,
    /// Largest change of that step per tick, gauge codes Q16.
    pub slew_accel_q16: i64,
    pub command_limit_code: i32,
    /// DAC code that drives the current limit through the coil at rest.
    pub current_limit_code: i32,
    /// DAC codes of back-EMF per gauge code per tick, Q24.
    pub k_emf_q24: i32,
    pub current_limit_ticks: u32,
    pub following_error_code: i32,
    pub following_error_ticks: u32,
    pub sign_check_code: i32,
    pub sign_check_ticks: u32,
    /// Gauge move expected at the end of the doublet's first half, codes.
    pub sign_check_expected_code: i32,
    /// Ticks the loop needs to settle after engaging (ten time constants
    /// of the error dynamics) before the learning starts.
    pub settle_ticks: u32,
    pub monitor: MonitorConfig,
    /// The part program's depth of cut, whole µin (1..=10 000,
    /// `depth_of_cut_uin` rounded): the hole edges' contact chord
    /// (`servo::edges::contact_chord_uin`).
    pub depth_of_cut_uin: u32,
    /// The hole edges' expected force change goes to the tick
    /// (`edge_feedforward`).
    pub edge_feedforward: bool,
}

/// Ticks beyond the depth guard before it is a fault: a single sample of
/// ADC noise cannot make it (the guard is ≥ 60 σ of the noisiest gauge).
pub const DEPTH_GUARD_TICKS: u32 = 3;

/// Contour monitoring's limits (`servo::monitor`), in the units it
/// compares: gauge codes (Q8 for the error, whole codes squared for its
/// mean square), loop ticks, revolutions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct MonitorConfig {
    /// The depth guard, codes Q8 (`depth_guard_uin`).
    pub depth_guard_q8: i32,
    /// The oscillation limit's square, codes² (`oscillation_uin`).
    pub oscillation_sq: u64,
    pub gauge_frozen_ticks: u32,
    /// 0: no X stall check.
    pub x_stall_revs: u32,
    /// The retract position, gauge codes along +Z (`retract_z_in`).
    pub retract_code: i32,
    /// Ticks the depth and ring checks stand down after a hole (the
    /// edges' transient): three time constants of the error dynamics.
    pub edge_settle_ticks: u32,
}

impl ServoConfig {
    /// The default loop ([`ServoDesign::brief`]) at `rate_hz`, clamped to
    /// the design's 1 kHz..200 kHz.
    pub fn at_rate(rate_hz: u32) -> Result<Self, DesignError> {
        ServoDesign::brief(rate_hz.clamp(1_000, 200_000)).config()
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    extern crate std;
    use super::*;

    /// eq 4-33 with Model 15 constants: a = (B + Kf·Kb/R)/M = 306.6 1/s and
    /// K = 1.281e6 codes per code per s² (the same numbers as the
    /// simulator's plant, derived independently in `docs/PLANT.md`).
    #[test]
    fn brief_slide_plant_constants_match_chapter_4() {
        let s = SlideModel::BRIEF;
        assert!((s.pole_per_s() - 306.6).abs() < 0.5, "{}", s.pole_per_s());
        assert!(
            (s.gain_per_s2() / 1.281e6 - 1.0).abs() < 2e-3,
            "{}",
            s.gain_per_s2()
        );
    }

    /// The observer's error dynamics A − L'CA have the triple pole asked
    /// for: its characteristic polynomial is (z − p)³.
    #[test]
    fn observer_poles_are_placed() {
        let (a12, a22, b1, b2) = (0.99, 0.98, 1.6e-3, 3.2e-3);
        let p = 0.96;
        let l = observer_gains(a12, a22, b1, b2, p).unwrap();
        let a = [[1.0, a12, b1], [0.0, a22, b2], [0.0, 0.0, 1.0]];
        // E = (I − L C) A
        let mut e = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                e[i][j] = a[i][j] - l[i] * a[0][j];
            }
        }
        // char poly coefficients: trace, sum of principal minors, det
        let tr = e[0][0] + e[1][1] + e[2][2];
        let m2 = e[0][0] * e[1][1] - e[0][1] * e[1][0] + e[0][0] * e[2][2] - e[0][2] * e[2][0]
            + e[1][1] * e[2][2]
            - e[1][2] * e[2][1];
        let det = e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1])
            - e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0])
            + e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
        assert!((tr - 3.0 * p).abs() < 1e-9);
        assert!((m2 - 3.0 * p * p).abs() < 1e-9);
        assert!((det - p * p * p).abs() < 1e-9);
    }

    /// The velocity estimate's noise gain, against the raw difference it
    /// replaces: a difference of two samples of white noise σ has RMS
    /// √2·σ·fs (0.028 in/s per µin at 20 kHz); the observer's estimate at
    /// 250 Hz passes under a fiftieth of that (measured 4.8e-4: the 40 Hz
    /// observer of the first design passed 1.2e-5, but could not hold the
    /// cut's process spring, `docs/TUNING.md`).
    #[test]
    fn velocity_estimate_noise_gain_is_far_below_a_raw_difference() {
        let g = ServoDesign::brief(20_000).velocity_noise_gain().unwrap();
        let raw = core::f64::consts::SQRT_2 * 20_000.0 * 1e-6;
        std::eprintln!("velocity noise gain {g:.3e} in/s per µin RMS (raw difference {raw:.3e})");
        assert!(g < raw / 50.0, "{g} vs {raw}");
    }

    #[test]
    fn brief_design_builds_and_bad_fields_are_named() {
        assert!(ServoDesign::brief(20_000).config().is_ok());
        let mut d = ServoDesign::brief(20_000);
        d.bandwidth_hz = 5_000.0;
        assert_eq!(d.config().unwrap_err(), DesignError::Bandwidth);
        assert!(DesignError::Bandwidth.reason().starts_with("bandwidth_hz"));
        let mut d = ServoDesign::brief(20_000);
        d.learning_gain = 1.5;
        assert_eq!(d.config().unwrap_err(), DesignError::Learning);
        let mut d = ServoDesign::brief(20_000);
        d.hum_notch_hz = 15_000.0;
        assert_eq!(d.config().unwrap_err(), DesignError::HumNotch);
    }

    /// The sign check's expected gauge move after the doublet's first half,
    /// by hand: K = 1.2796e6 codes per code per s², a = 306.24 1/s (eq
    /// 4-33, Model 15), the pulse 0.35 V = 18 350 DAC codes for T = 1 ms:
    /// z(T) = K·p·(T/a − (1 − e^(−aT))/a²) = 2.3481e10 · 4.5264e-7
    /// = 10 628 codes.
    #[test]
    fn the_sign_checks_expected_move_is_the_doublets_first_half_by_hand() {
        let d = ServoDesign::brief(20_000);
        assert_eq!((d.sign_check_v, d.sign_check_ms), (0.35, 1.0));
        let cfg = d.config().unwrap();
        assert_eq!(cfg.sign_check_code, 18_350);
        let got = f64::from(cfg.sign_check_expected_code);
        assert!((got / 10_628.0 - 1.0).abs() < 1e-3, "{got}");
    }

    /// A gain beyond its format's 32 bits is refused, not saturated: at
    /// 999 Hz on a slide with a tenth of the brief's amplifier gain,
    /// kp = ω²/K = (2π·999)²/1.28e5 = 308 > 2³¹/2²⁴ = 128.
    #[test]
    fn a_gain_beyond_its_format_is_refused() {
        let mut d = ServoDesign::brief(20_000);
        d.bandwidth_hz = 999.0;
        d.bandwidth_fast_hz = 999.0;
        d.slide.amp_gain = 1.0;
        assert_eq!(d.config().unwrap_err(), DesignError::GainRange);
    }
}
