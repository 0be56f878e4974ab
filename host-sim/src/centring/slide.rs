//! One cross slide (Y-1594 ch. III-IV): power amplifier, two-phase servo
//! motor, 400:1 gear, 0.2 in/rev leadscrew, tachometer, and the mechanics
//! that limited the real machine.
//!
//! * Amplifier: unity gain from the firmware's motor-voltage DAC, its
//!   0.59 ms pole (T_A of ch. VI), output limited to the rail that gives the
//!   motor's 365 rad/s (`zslide::centring::servo::RAIL_MV`).
//! * Motor: `θ_m/E_m = 150·417/[s(s + 53)(s + 417)]` (eqs 24, 52),
//!   stepped by the exact zero-order hold of `plant::linear` with the
//!   amplifier output held over each sub-step.
//! * Tachometer on the motor shaft, 0.062 V/(rad/s), with white noise, read
//!   by a 16-bit converter over ±25 V.
//! * Free play and deflection between the ball nut and the slide: while the
//!   nut drives, the slide lags it by the elastic windup `deflection_in`
//!   plus half the free play (a play operator: motion of the nut inside the
//!   play does not move the slide); when the motor comes to rest after
//!   dragging the slide, the slide settles where static friction catches
//!   it: the windup stays (slide short by `deflection_in` in the direction
//!   of travel) and its place within the free play is random (uniform in
//!   ±free_play/2, seeded). The firmware
//!   cannot see either: its only slide sensor is the tachometer on the
//!   motor, as in 1967.

use crate::plant::gauge::gaussian;
use crate::plant::linear::{Discrete, LinearSystem};
use nalgebra::{DMatrix, DVector};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use zslide::centring::servo::{GEAR_RATIO, LEAD_IN, RAIL_MV, TACH_V_PER_RAD_S};

const AMP_TAU_S: f64 = 0.00059;
const TACH_FULL_V: f64 = 25.0;
/// Below this motor speed the drive is at rest (for the free-play model).
const REST_RAD_S: f64 = 0.05;

/// Mechanical imperfections of one slide.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Mechanics {
    pub free_play_in: f64,
    pub deflection_in: f64,
    /// A left-hand leadscrew fitted: the slide runs opposite to the motor
    /// (a wiring or assembly error the sequence must refuse, not chase).
    pub reversed: bool,
    /// The slide is jammed: the motor stalls whatever its voltage.
    pub jammed: bool,
}

#[derive(Clone, Debug)]
pub struct Slide {
    motor: Discrete,
    /// Electrical lag state, motor speed (rad/s), motor angle (rad).
    x: DVector<f64>,
    amp_v: f64,
    amp_decay: f64,
    sub_steps: u32,
    mech: Mechanics,
    tach_noise_v: f64,
    /// Where the slide is, inches (the nut is at motor angle × lead/gear).
    slide_in: f64,
    moving_dir: f64,
    /// The slide moved with the nut since the drive was last at rest.
    dragged: bool,
}

/// Motor angle to nut travel, inches per radian.
pub fn in_per_rad() -> f64 {
    LEAD_IN / (GEAR_RATIO * std::f64::consts::TAU)
}

impl Slide {
    /// A slide stepped at `tick_hz` with `sub_steps` plant steps per tick.
    pub fn new(tick_hz: u32, sub_steps: u32, mech: Mechanics, tach_noise_v: f64) -> Self {
        let a =
            DMatrix::from_row_slice(3, 3, &[-417.0, 0.0, 0.0, 150.0, -53.0, 0.0, 0.0, 1.0, 0.0]);
        let b = DMatrix::from_row_slice(3, 1, &[417.0, 0.0, 0.0]);
        let c = DMatrix::from_row_slice(1, 3, &[0.0, 0.0, 1.0]);
        let d = DMatrix::zeros(1, 1);
        let h = 1.0 / f64::from(tick_hz) / f64::from(sub_steps);
        Self {
            motor: LinearSystem::new(a, b, c, d).zoh(h),
            x: DVector::zeros(3),
            amp_v: 0.0,
            amp_decay: (-h / AMP_TAU_S).exp(),
            sub_steps,
            mech,
            tach_noise_v,
            slide_in: 0.0,
            moving_dir: 0.0,
            dragged: false,
        }
    }

    /// Advances one tick with the DAC holding `motor_mv`.
    pub fn step(&mut self, motor_mv: i32, rng: &mut ChaCha8Rng) {
        let rail = f64::from(RAIL_MV) / 1000.0;
        let u = f64::from(motor_mv) / 1000.0;
        for _ in 0..self.sub_steps {
            self.amp_v = (u + (self.amp_v - u) * self.amp_decay).clamp(-rail, rail);
            if !self.mech.jammed {
                self.x = &self.motor.phi * &self.x + &self.motor.gamma * self.amp_v;
            }
            self.play(rng);
        }
    }

    fn play(&mut self, rng: &mut ChaCha8Rng) {
        let w = self.x[1];
        let half = self.mech.deflection_in + self.mech.free_play_in / 2.0;
        if w.abs() > REST_RAD_S {
            // The nut drags the slide only once it has crossed the play.
            let nut = self.nut_in();
            let rel = self.slide_in - nut;
            let clamped = rel.clamp(-half, half);
            if clamped != rel {
                self.dragged = true;
                self.moving_dir = w.signum();
                self.slide_in = nut + clamped;
            }
        } else if self.dragged {
            let seat = if self.mech.free_play_in > 0.0 {
                rng.random_range(-0.5..0.5) * self.mech.free_play_in
            } else {
                0.0
            };
            let rel = (-self.moving_dir * self.mech.deflection_in + seat).clamp(-half, half);
            self.slide_in = self.nut_in() + rel;
            self.dragged = false;
        }
    }

    pub fn motor_rad_s(&self) -> f64 {
        self.x[1]
    }

    pub fn nut_in(&self) -> f64 {
        let sign = if self.mech.reversed { -1.0 } else { 1.0 };
        sign * self.x[2] * in_per_rad()
    }

    /// Where the slide (and the part on it) is, inches.
    pub fn position_in(&self) -> f64 {
        self.slide_in
    }

    /// The tachometer through its converter, µV.
    pub fn tach_uv(&self, rng: &mut ChaCha8Rng) -> i32 {
        let v = TACH_V_PER_RAD_S * self.x[1] + self.tach_noise_v * gaussian(rng);
        let lsb = 2.0 * TACH_FULL_V / 65536.0;
        let v = ((v / lsb).round() * lsb).clamp(-TACH_FULL_V, TACH_FULL_V);
        (v * 1e6).round() as i32
    }
}
