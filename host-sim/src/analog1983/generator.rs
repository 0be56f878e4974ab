//! The 1983 command generator's analog half (chapter 3, Figs 3-5..3-8):
//! the sine-of-the-spindle-angle oscillator and the multiplier network
//! that forms eq 2-19, `Z = C00 + C01 s + C02 s² + C03 s³`, from the
//! coefficients the microcomputer writes to its DACs (the firmware's
//! legacy coefficient output, `zslide::xpos::legacy_output`).
//!
//! **The oscillator (eq 3-1..3-4).** Two integrators in a loop, each fed
//! through an analog multiplier by the attenuated tachometer voltage `E_t`
//! (calibrated to +5 V at 300 rpm); with `E_t` steady the loop is an
//! oscillator of frequency `∝ E_t`, i.e. of the spindle's angle. At the
//! index the photodiode's one-shot resets the integrators to their initial
//! conditions (sine 0, cosine at the calibrated amplitude), holds them for
//! the pulse and lets them run: the angle error never outlives a
//! revolution. Stepped here as the circuit, not as its solution:
//!
//! ```text
//! dc/dt = −a (E_t + e₁) s / 1 V,   ds/dt = a (E_t + e₂) c / 1 V
//! ```
//!
//! `e₁, e₂` the multipliers' offsets on their `E_t` inputs. The tests
//! (`host-sim/tests/analog1983_generator.rs`) hold the stepped circuit
//! against the closed forms derived from it.
//!
//! **Its named error sources** (issue 21; levels in the scenario's
//! `[errors]`, every one a labelled assumption):
//! - *tachometer rate error* ε: `E_t = 5 V (1 + ε) Ω/Ω_cal`, so within a
//!   revolution the generator's angle is `(1 + ε) θ`, θ the true angle
//!   since the index: a sawtooth error `ε θ` reset at every index;
//! - *integrator reset at the index*: the one-shot's pulse `t_r` holds the
//!   sine at zero while the spindle turns `Ω t_r`: the generator lags the
//!   spindle by that angle, more at 360 rpm than at 300;
//! - *amplitude calibrated at one speed*: the amplitude of the sine is
//!   `c₀ √((E_t + e₂)/(E_t + e₁))` (the ratio of the two integration rates),
//!   so with mismatched offsets it depends on the speed. The shop trimmed
//!   the initial condition `c₀` and the rate `a` at the calibration speed
//!   (chapter 6: "the sine wave generator required that the amplitude be
//!   tuned to a specific spindle speed"); at another speed the sine has the
//!   gain `g = √((E+e₂)(E_c+e₁)/((E+e₁)(E_c+e₂)))` ≈ `1 + (e₁−e₂)(1/E_c −
//!   1/E)/2`, and the command `Σ C0j s^j` carries `(g^j − 1)·C0j sin^j`.

/// The attenuated tachometer at the calibration speed, V (chapter 3: "a
/// calibrated +5 volts at 300 rpm").
pub const TACH_V_AT_CALIBRATION: f64 = 5.0;
/// The sine's calibrated amplitude, V (Wong and Ott's 10 V).
pub const SINE_AMPLITUDE_V: f64 = 10.0;

/// The generator's error levels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GeneratorLevels {
    /// Tachometer rate error ε (fraction; + = the generator runs fast).
    pub tach_rate_error: f64,
    /// The reset one-shot's pulse: the integrators are held this long after
    /// the index, s.
    pub reset_hold_s: f64,
    /// Mismatch of the two multipliers' offsets on the `E_t` input, V:
    /// `e₁ = +m/2` (cosine integrator's multiplier), `e₂ = −m/2`.
    pub multiplier_offset_v: f64,
    /// Speed at which the rate and the amplitude were trimmed, rpm.
    pub calibrated_rpm: f64,
}

impl GeneratorLevels {
    /// The ideal generator trimmed at `calibrated_rpm`.
    pub fn ideal(calibrated_rpm: f64) -> Self {
        Self {
            tach_rate_error: 0.0,
            reset_hold_s: 0.0,
            multiplier_offset_v: 0.0,
            calibrated_rpm,
        }
    }

    fn offsets(&self) -> (f64, f64) {
        (
            0.5 * self.multiplier_offset_v,
            -0.5 * self.multiplier_offset_v,
        )
    }
}

/// The sine oscillator of Fig 3-8, run in the time domain.
#[derive(Clone, Debug)]
pub struct SineGenerator {
    lv: GeneratorLevels,
    /// Integration rate per volt of the multiplied input, 1/(V·s) (the
    /// trimmed `1/(R_i C_f · 10 V)`).
    a: f64,
    /// The cosine integrator's initial condition, V (trimmed).
    c0: f64,
    c: f64,
    s: f64,
    /// Time left in the reset pulse, s.
    hold_s: f64,
}

impl SineGenerator {
    /// Trimmed at the calibration speed: the rate so that the sine turns
    /// once per revolution, the initial condition so that its amplitude is
    /// 10 V; reset (sine 0, as just after an index).
    pub fn new(lv: GeneratorLevels) -> Self {
        let (e1, e2) = lv.offsets();
        let ec = TACH_V_AT_CALIBRATION;
        let omega_c = lv.calibrated_rpm / 60.0 * std::f64::consts::TAU;
        let a = omega_c / ((ec + e1) * (ec + e2)).sqrt();
        let c0 = SINE_AMPLITUDE_V * ((ec + e1) / (ec + e2)).sqrt();
        Self {
            lv,
            a,
            c0,
            c: c0,
            s: 0.0,
            hold_s: 0.0,
        }
    }

    pub fn levels(&self) -> &GeneratorLevels {
        &self.lv
    }

    /// The index mark: integrators to their initial conditions, held for
    /// the reset pulse.
    pub fn index(&mut self) {
        self.c = self.c0;
        self.s = 0.0;
        self.hold_s = self.lv.reset_hold_s;
    }

    /// The attenuated tachometer at `rpm`, V.
    pub fn tach_v(&self, rpm: f64) -> f64 {
        TACH_V_AT_CALIBRATION * (1.0 + self.lv.tach_rate_error) * rpm / self.lv.calibrated_rpm
    }

    /// Runs the circuit `dt_s` with the spindle at `rpm` (classical RK4 in
    /// steps of at most 50 µs: at 10 Hz its error per step is ~1e-14).
    pub fn advance(&mut self, dt_s: f64, rpm: f64) {
        let mut dt = dt_s;
        if self.hold_s > 0.0 {
            let h = self.hold_s.min(dt);
            self.hold_s -= h;
            dt -= h;
        }
        if dt <= 0.0 {
            return;
        }
        let e = self.tach_v(rpm);
        let (e1, e2) = self.lv.offsets();
        let (k1, k2) = (self.a * (e + e1), self.a * (e + e2));
        let f = |c: f64, s: f64| (-k1 * s, k2 * c);
        let n = (dt / 50e-6).ceil().max(1.0);
        let h = dt / n;
        for _ in 0..n as u32 {
            let (c, s) = (self.c, self.s);
            let (a1, b1) = f(c, s);
            let (a2, b2) = f(c + 0.5 * h * a1, s + 0.5 * h * b1);
            let (a3, b3) = f(c + 0.5 * h * a2, s + 0.5 * h * b2);
            let (a4, b4) = f(c + h * a3, s + h * b3);
            self.c = c + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
            self.s = s + h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4);
        }
    }

    /// The sine output as a fraction of its calibrated 10 V.
    pub fn sine(&self) -> f64 {
        self.s / SINE_AMPLITUDE_V
    }
}

/// The multiplier network of eq 2-19: the command (V = mil at Table 3-1's
/// ±10 V ↔ ±0.010 in) from the coefficient DACs' outputs `c_v` (C00..C03,
/// V) and the generator's sine `s` (fraction of 10 V).
pub fn command_v(c_v: [f64; 4], s: f64) -> f64 {
    c_v.iter().rev().fold(0.0, |acc, &c| acc * s + c)
}
