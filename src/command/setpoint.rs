//! The setpoint the loop follows: the table's Z command at the spindle
//! angle in gauge codes, with its rates from the command's exact analytic
//! derivatives (not from differencing the command, which would add noise
//! and half a tick of lag):
//!
//! ```text
//! velocity      ∂Z/∂φ · Δφ                      codes per tick
//! acceleration  ∂²Z/∂φ² · Δφ² + ∂Z/∂φ · Δ²φ      codes per tick²
//! ```
//!
//! Δφ is the angle step of the last tick; Δ²φ, the spindle's angular
//! acceleration (it sags under cutting torque, brief §2), is the change of
//! a smoothed Δφ (time constant 64 ticks, 3.2 ms at 20 kHz), because the
//! tachometer's angle steps carry its noise and a raw second difference
//! would pass it to the feedforward 64 times larger.
//!
//! # Where they are formed
//! The tick forms the velocity, from ∂Z/∂φ stepped to its own angle and
//! its own Δφ ([`setpoint`]), and keeps the smoothing of Δφ
//! ([`SetpointState::advance`]); the acceleration is formed below it, at
//! the predicted angle with the step and Δ²φ the tick posts
//! (`acceleration`, `crate::command::expansion`, where its error is bounded), or in
//! the tick with its own when it evaluates the command itself.
//!
//! # Formats
//! ∂Z/∂φ Q30 in/rad, ∂²Z/∂φ² Q30 in/rad², Δφ in the binary angle (2³² per
//! revolution); outputs Q16 codes per tick and per tick² (`i32`). Each
//! rate is a unit constant times derivative times angle steps: the
//! constant is applied first to the derivative (one rounded 32×32 high
//! product, `SMMULR`), then the angle steps (`SMULL` and a shift each), so
//! every product is a 32-bit multiply. Relative to a product formed exactly
//! the high product's rounding costs at most half an LSB of the scaled
//! derivative: 1.3e-4 codes per tick of velocity at 300 rpm (2.4e-6 µin
//! per tick), plus the final shift's truncation of 1.5e-5.

use super::expansion::{rate_step, Expansion};
#[cfg(test)]
use super::expansion::{FF_K, FF_K2};
#[cfg(test)]
use crate::servo::fixed::mul_hi;
use crate::servo::fixed::{sat_i32, ssat};
use crate::servo::Reference;
use crate::units::SpindleAngle;

/// Smoothing of Δφ for the angular acceleration: 2⁻⁶ per tick.
const ALPHA_SHIFT: u32 = 6;
/// The angle history the rates need.
#[derive(Clone, Debug, Default)]
pub struct SetpointState {
    last_phi: Option<SpindleAngle>,
    /// Smoothed angle step, binary angle per tick, Q4 (|Δφ| ≤ 2²⁶: < 2³⁰).
    dphi_q4: Option<i32>,
}

impl SetpointState {
    /// The angle step since the last tick (0 without two angles).
    #[inline(always)]
    pub fn dphi(&self, phi: Option<SpindleAngle>) -> i32 {
        match (self.last_phi, phi) {
            (Some(p), Some(q)) => q.0.wrapping_sub(p.0) as i32,
            _ => 0,
        }
    }

    /// Takes this tick's angle `phi` (its step `dphi` = [`Self::dphi`]):
    /// returns the step for the rates (`rate_step`) and Δ²φ, the change
    /// of the smoothed step (binary angle per tick², Q4, −2²⁴ ≤ Δ²φ < 2²⁴; 0
    /// without two angles, and on the first tick that has them).
    #[inline(always)]
    pub fn advance(&mut self, phi: Option<SpindleAngle>, dphi: i32) -> (i32, i32) {
        let dphi = rate_step(dphi);
        let alpha_q4 = match (self.last_phi, phi, self.dphi_q4) {
            (Some(_), Some(_), Some(f)) => {
                // An average of steps within ±2³⁰ stays within them.
                let next = f + ((dphi << 4).saturating_sub(f) >> ALPHA_SHIFT);
                self.dphi_q4 = Some(next);
                ssat::<25>(next - f)
            }
            (Some(_), Some(_), None) => {
                self.dphi_q4 = Some(dphi << 4);
                0
            }
            _ => 0,
        };
        self.last_phi = phi;
        (dphi, alpha_q4)
    }

    /// The angle of the last tick (`None`: not known).
    pub fn angle(&self) -> Option<SpindleAngle> {
        self.last_phi
    }

    /// The smoothed angle step, binary angle per tick, Q8 (the speed; the
    /// link's unit, kept Q8 while the setpoint smooths in Q4).
    pub fn step_q8(&self) -> Option<i64> {
        self.dphi_q4.map(|q| i64::from(q) << 4)
    }

    /// Forgets the angle (no spindle angle this tick).
    pub fn lose_angle(&mut self) {
        self.last_phi = None;
        self.dphi_q4 = None;
    }
}

/// The table's setpoint from the command's expansion at the tick's angle
/// (`None`: a null one) and the tick's step `dphi` (`rate_step`): the
/// velocity formed here from ∂Z/∂φ at the tick's angle, the acceleration
/// the expansion's.
#[inline(always)]
pub fn setpoint(command: Option<&Expansion>, dphi: i32) -> Reference {
    match command {
        Some(e) => {
            // |p1| < 2²⁷, times |Δφ| ≤ 2²⁶, >> 16: < 2³⁷ before the
            // saturation to 2³⁰ (6 in/s).
            let v = (i64::from(e.p1) * i64::from(dphi)) >> 16;
            Reference {
                code: e.code(),
                velocity_q16: ssat::<31>(sat_i32(v)),
                accel_q16: e.accel_q16,
            }
        }
        None => Reference::default(),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    use super::*;

    /// The constants are the unit conversions they claim (gauge 2¹⁹ codes
    /// per 0.010 in, angle 2³² per turn), checked in f64.
    #[test]
    fn feedforward_constants_are_the_unit_conversions() {
        let cpi = 524_288.0 / 0.010;
        let rad = core::f64::consts::TAU / 4_294_967_296.0;
        // v[Q16] = d1/2³⁰ · Δφ·rad · cpi · 2¹⁶ = d1·Δφ·K/2⁴⁸
        let k1 = rad * cpi * 65_536.0 / (1u64 << 30) as f64 * 2f64.powi(48);
        assert!((k1 / f64::from(FF_K) - 1.0).abs() < 1e-9, "{k1}");
        // a[Q16] = d2/2³⁰ · (Δφ·rad)² · cpi · 2¹⁶ = d2·Δφ²·K2/2⁷⁸
        let k2 = rad * rad * cpi * 65_536.0 / (1u64 << 30) as f64 * 2f64.powi(78);
        assert!((k2 / f64::from(FF_K2) - 1.0).abs() < 1e-9, "{k2}");
        // a[Q16] = d1/2³⁰ · α/2⁴·rad · cpi · 2¹⁶ = d1·α·K/2⁵²
        let k3 = rad * cpi * 65_536.0 / (1u64 << 30) as f64 / 16.0 * 2f64.powi(52);
        assert!((k3 / f64::from(FF_K) - 1.0).abs() < 1e-9, "{k3}");
    }

    /// The rates against f64 from the same derivatives: a velocity of
    /// 0.25 in/s and an acceleration of 15.8 in/s² at 300 rpm (the brief's
    /// worst 10 Hz case) within 1.5e-4 codes per tick (the bound in the
    /// module doc) and 1e-4 codes per tick².
    #[test]
    fn rates_match_the_exact_products() {
        let cpi = 524_288.0 / 0.010;
        let rad = core::f64::consts::TAU / 4_294_967_296.0;
        let dphi = (4_294_967_296.0 / 4000.0) as i32; // 300 rpm at 20 kHz
        let w = f64::from(dphi) * rad; // rad per tick
                                       // Z = A sin(2φ): ∂Z/∂φ = 2A cos, ∂²Z/∂φ² = −4A sin, A = 0.004 in.
        for k in 0..32 {
            let th = f64::from(k) * 0.2;
            let d1 = 2.0 * 0.004 * libm::cos(2.0 * th);
            let d2 = -4.0 * 0.004 * libm::sin(2.0 * th);
            let (b1, b2) = (
                libm::round(d1 * f64::from(1u32 << 30)) as i32,
                libm::round(d2 * f64::from(1u32 << 30)) as i32,
            );
            let v = (i64::from(mul_hi(b1, FF_K)) * i64::from(dphi)) >> 16;
            let q2 = i64::from(mul_hi(b2, FF_K2)) * i64::from(dphi);
            let a2 = (((q2 >> 23) as i32 as i64) * i64::from(dphi)) >> 23;
            let v_exact = f64::from(b1) / f64::from(1u32 << 30) * w * cpi;
            let a_exact = f64::from(b2) / f64::from(1u32 << 30) * w * w * cpi;
            assert!(
                (v as f64 / 65_536.0 - v_exact).abs() < 1.5e-4,
                "{k}: v {v} vs {v_exact}"
            );
            assert!(
                (a2 as f64 / 65_536.0 - a_exact).abs() < 1e-4,
                "{k}: a {a2} vs {a_exact}"
            );
        }
    }
}
