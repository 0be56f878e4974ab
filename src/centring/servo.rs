//! One cross slide's position servo (Y-1594 ch. IV-VII), digital.
//!
//! The 1967 loop had no slide position sensor: the storage capacitor held
//! the measured error `E` and the tachometer current discharged it, so the
//! capacitor voltage was `e_e = E − 295·y` with `y` the slide travel since
//! the cycle began (eq 32; 295 V/in = K_T·N/(R₇C₅P)). The slide stops where
//! `e_e = 0`, i.e. after moving `K·D` for an off-centre `D` (`K` = 0.95 set
//! by R₇). Here the same: the tachometer voltage is integrated in fixed
//! point (exact sum of ADC codes), scaled by the gear and leadscrew to
//! slide inches, and the error is `e_e = 295·(target − y)` in volts.
//!
//! Two of the seed's designs ([`LoopDesign`]):
//! * `Critical` (ch. V): `u = A·(e_e − K₁·v_tach)`, A = 700, K₁ = 0.01,
//!   critically damped, closed loop 8.33/(s² + 118 s + 2460) in slide inches.
//! * `Compensated` (ch. VI, Fig. 26): the tachometer through the network
//!   `G_C = T_C s/(s + 1/T_C)` (T_C = 0.01 s, K₁ = 0.92) and the outer
//!   error through `A₁(s + 40)/(s + 120)` (A₁ = 4.8), A = 2000. `G_C` is
//!   the network *as the seed analysed it*: its eq 56 coefficients (b₂ =
//!   … + 1.31·10¹⁰ K₁T_C) carry a high-frequency gain of T_C, and only with
//!   it are the inner-loop roots the seed's −17, −1750, −250 ± j250 (with a
//!   unit-gain `T_C s/(1 + T_C s)` the inner loop crosses over near
//!   2000 rad/s with −213° of phase and oscillates; we tried it).
//!
//! The filters are Tustin-discretised at the tick rate when the servo is
//! built (f64 arithmetic once, at configuration; IEEE basic operations give
//! the same bits on host and target), then run in integer arithmetic:
//! signals in volts Q32 (`i64`, 1 V = 2³²), coefficients Q30. The output is
//! the motor control-winding voltage in millivolts, clamped to the
//! amplifier rail that gives the motor's 365 rad/s.

/// Motor control voltage at which the motor reaches its 365 rad/s limit:
/// 365 rad/s over the motor's DC gain 150/53 rad/s/V (eq 24).
pub const RAIL_MV: i32 = 128_967;
/// Tachometer, V per rad/s of the motor shaft (eq 26).
pub const TACH_V_PER_RAD_S: f64 = 0.062;
/// Motor revolutions per leadscrew revolution.
pub const GEAR_RATIO: f64 = 400.0;
/// Leadscrew lead, inches per revolution.
pub const LEAD_IN: f64 = 0.2;
/// Integrator scale of eq 32, volts of `e_e` per inch of slide travel.
pub const VOLTS_PER_IN: i64 = 295;

const Q30: f64 = (1u64 << 30) as f64;

/// Which of the seed's loop designs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoopDesign {
    Critical,
    Compensated,
}

/// First-order section `(b0 + b1 z⁻¹)/(1 + a1 z⁻¹)`, coefficients Q30.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Section {
    b0: i64,
    b1: i64,
    a1: i64,
    x1: i64,
    y1: i64,
}

impl Section {
    /// Tustin image of `g·(s + z)/(s + p)` at `tick_hz`.
    fn tustin(g: f64, z: f64, p: f64, tick_hz: f64) -> Self {
        let c = 2.0 * tick_hz;
        let q = |v: f64| (v * Q30) as i64;
        Self {
            b0: q(g * (c + z) / (c + p)),
            b1: q(g * (z - c) / (c + p)),
            a1: q((p - c) / (c + p)),
            x1: 0,
            y1: 0,
        }
    }

    #[inline]
    fn step(&mut self, x: i64) -> i64 {
        let acc = i128::from(self.b0) * i128::from(x) + i128::from(self.b1) * i128::from(self.x1)
            - i128::from(self.a1) * i128::from(self.y1);
        let y = (acc >> 30).clamp(i128::from(i64::MIN >> 2), i128::from(i64::MAX >> 2)) as i64;
        self.x1 = x;
        self.y1 = y;
        y
    }

    fn reset(&mut self) {
        self.x1 = 0;
        self.y1 = 0;
    }
}

/// Servo configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ServoConfig {
    pub design: LoopDesign,
    pub tick_hz: u32,
    /// Settled: |target − y| below this (inches, I2F30 bits) ...
    pub settle_err_bits: i32,
    /// ... and |tach| below this (µV) ...
    pub settle_tach_uv: i32,
    /// ... for this many ticks in a row.
    pub settle_ticks: u32,
}

impl ServoConfig {
    pub fn new(design: LoopDesign, tick_hz: u32) -> Self {
        Self {
            design,
            tick_hz,
            // 1 µin; 20 mV is 0.32 rad/s at the motor, 2.6 µin/s at the slide.
            settle_err_bits: 1074,
            settle_tach_uv: 20_000,
            settle_ticks: tick_hz / 20,
        }
    }
}

/// One slide's servo.
#[derive(Clone, Debug)]
pub struct SlideServo {
    cfg: ServoConfig,
    /// Slide inches (Q80) per microvolt-tick of tachometer.
    in_per_uv_tick_q80: i64,
    amp_gain: i64,
    /// K₁ in Q30.
    k1_q30: i64,
    outer: Option<Section>,
    tach_net: Option<Section>,
    active: bool,
    target_q30: i64,
    tach_sum: i64,
    quiet: u32,
    err_q30: i64,
}

impl SlideServo {
    /// `None` for a tick rate of zero.
    pub fn new(cfg: ServoConfig) -> Option<Self> {
        if cfg.tick_hz == 0 {
            return None;
        }
        let hz = f64::from(cfg.tick_hz);
        let rad_per_in = GEAR_RATIO * core::f64::consts::TAU / LEAD_IN;
        let in_per_uv_tick = 1e-6 / TACH_V_PER_RAD_S / hz / rad_per_in;
        let (amp_gain, k1, outer, tach_net) = match cfg.design {
            LoopDesign::Critical => (700, 0.01, None, None),
            LoopDesign::Compensated => (
                2000,
                0.92,
                Some(Section::tustin(4.8, 40.0, 120.0, hz)),
                Some(Section::tustin(0.01, 0.0, 1.0 / 0.01, hz)),
            ),
        };
        Some(Self {
            cfg,
            in_per_uv_tick_q80: (in_per_uv_tick * (1u128 << 80) as f64) as i64,
            amp_gain,
            k1_q30: (k1 * Q30) as i64,
            outer,
            tach_net,
            active: false,
            target_q30: 0,
            tach_sum: 0,
            quiet: 0,
            err_q30: 0,
        })
    }

    /// Starts a correction: move the slide by `travel` from where it is
    /// (the capacitor charged with a new `E`, switch S-A closed).
    pub fn start(&mut self, travel: crate::units::TableInches) {
        if let Some(s) = self.outer.as_mut() {
            s.reset();
        }
        if let Some(s) = self.tach_net.as_mut() {
            s.reset();
        }
        self.active = false;
        self.retarget(travel);
    }

    /// Moves the target to `travel` from where the slide is now, without
    /// disturbing a correction in progress (its filter states are kept).
    pub fn retarget(&mut self, travel: crate::units::TableInches) {
        if !self.active {
            if let Some(s) = self.outer.as_mut() {
                s.reset();
            }
            if let Some(s) = self.tach_net.as_mut() {
                s.reset();
            }
        }
        self.target_q30 = self
            .position_q30()
            .saturating_add(i64::from(travel.to_bits()));
        self.err_q30 = i64::from(travel.to_bits());
        self.quiet = 0;
        self.active = true;
    }

    /// Opens the loop (S-A open): the motor gets zero volts.
    pub fn stop(&mut self) {
        self.active = false;
    }

    pub fn active(&self) -> bool {
        self.active
    }

    /// Slide position from the integrated tachometer since the servo was
    /// built (the only position the firmware has), inches I2F30 bits.
    pub fn position_q30(&self) -> i64 {
        ((i128::from(self.tach_sum) * i128::from(self.in_per_uv_tick_q80)) >> 50) as i64
    }

    /// Whether the slide has come to rest at its target (or was never sent).
    pub fn settled(&self) -> bool {
        !self.active || self.quiet >= self.cfg.settle_ticks
    }

    /// One loop tick: the tachometer reading (µV, positive when the slide
    /// moves positive); returns the motor voltage command (mV).
    pub fn tick(&mut self, tach_uv: i32) -> i32 {
        // Integrated always: a slide coasting with the loop open still moves.
        self.tach_sum = self.tach_sum.saturating_add(i64::from(tach_uv));
        if !self.active {
            return 0;
        }
        self.err_q30 = self.target_q30.saturating_sub(self.position_q30());
        if self.err_q30.abs() < i64::from(self.cfg.settle_err_bits)
            && tach_uv.saturating_abs() < self.cfg.settle_tach_uv
        {
            self.quiet = self.quiet.saturating_add(1);
        } else {
            self.quiet = 0;
        }
        // e_e in volts Q32: inches Q30 × 295 V/in × 4.
        let e_e = self.err_q30.saturating_mul(VOLTS_PER_IN * 4);
        let u1 = match self.outer.as_mut() {
            Some(s) => s.step(e_e),
            None => e_e,
        };
        // Tach volts Q32 = µV × 2³²/10⁶ (the constant is that in Q20).
        let v_t = (i64::from(tach_uv) * 4_503_599_627) >> 20;
        let shaped = match self.tach_net.as_mut() {
            Some(s) => s.step(v_t),
            None => v_t,
        };
        let fb = ((i128::from(self.k1_q30) * i128::from(shaped)) >> 30) as i64;
        let u = u1.saturating_sub(fb).saturating_mul(self.amp_gain);
        // Volts Q32 → mV, clamped to the rail.
        let mv = (i128::from(u) * 1000) >> 32;
        mv.clamp(-i128::from(RAIL_MV), i128::from(RAIL_MV)) as i32
    }

    /// Remaining error, inches I2F30 bits (for telemetry).
    pub fn error_q30(&self) -> i64 {
        self.err_q30
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    use super::*;

    #[test]
    fn tach_integral_scales_to_leadscrew_travel() {
        // 1 V of tach for 1 s: 1/0.062 rad at the motor, /400 turns·2π... .
        let mut s = SlideServo::new(ServoConfig::new(LoopDesign::Critical, 10_000)).unwrap();
        s.start(crate::units::TableInches::from_f64(0.1));
        for _ in 0..10_000 {
            s.tick(1_000_000);
        }
        let expect = 1.0 / 0.062 / (400.0 * core::f64::consts::TAU / 0.2);
        let got = s.position_q30() as f64 / (1u64 << 30) as f64;
        // Within one I2F30 LSB (0.93 nin).
        assert!((got - expect).abs() < 2f64.powi(-30), "{got} vs {expect}");
    }

    #[test]
    fn critical_output_is_a_times_error_volts_then_rails() {
        let mut s = SlideServo::new(ServoConfig::new(LoopDesign::Critical, 10_000)).unwrap();
        // 10 µin of error: e_e = 2.95 mV, × 700 = 2.065 V at rest.
        s.start(crate::units::TableInches::from_f64(10e-6));
        assert!((s.tick(0) - 2065).abs() <= 1);
        s.start(crate::units::TableInches::from_f64(-0.25));
        assert_eq!(s.tick(0), -RAIL_MV);
    }
}
