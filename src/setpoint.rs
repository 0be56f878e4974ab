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
//! # Formats
//! ∂Z/∂φ Q30 in/rad, ∂²Z/∂φ² Q30 in/rad², Δφ in the binary angle (2³² per
//! revolution); outputs Q16 codes per tick and per tick².

use crate::codes::gauge_code_from_z;
use crate::command::{Coefficients, CommandGen};
use crate::servo::Reference;
use crate::units::SpindleAngle;

/// Gauge codes per tick (Q16) from ∂Z/∂φ (Q30 in/rad) × Δφ (binary angle):
/// `v = p · 2π · 25 · 2²¹ / 2⁶² · 2¹⁶ = p · K / 2²⁵`, K = 50π, here Q16.
const FF_K_Q16: i64 = 10_294_371;
/// 100π² in Q8: codes/tick² from ∂²Z/∂φ² (Q30 in/rad²) × Δφ² (binary angle):
/// `a = d2 · Δφ² · (2π/2³²)² · 25·2²¹ / 2³⁰`, here as `d2·Δφ²·100π²/2⁷³`.
const FF_K2_Q8: i64 = 252_662;
/// Codes/tick² Q16 from ∂Z/∂φ (Q30 in/rad) × Δ²φ (binary angle per tick²,
/// Q8): `2π · 52 428 800 codes/in · 2¹⁶ / 2⁶² / 2⁸ · 2⁴⁰ = 20 106.3`, applied
/// as `((d1 · α) >> 20) · K >> 20`.
const FF_K_ALPHA: i64 = 20_106;
/// Smoothing of Δφ for the angular acceleration: 2⁻⁶ per tick.
const ALPHA_SHIFT: u32 = 6;

/// The angle history the rates need.
#[derive(Clone, Debug, Default)]
pub struct SetpointState {
    last_phi: Option<SpindleAngle>,
    /// Smoothed angle step, binary angle per tick, Q8.
    dphi_q8: Option<i64>,
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

    /// The angle of the last tick (`None`: not known).
    pub fn angle(&self) -> Option<SpindleAngle> {
        self.last_phi
    }

    /// The smoothed angle step, binary angle per tick, Q8 (the speed).
    pub fn step_q8(&self) -> Option<i64> {
        self.dphi_q8
    }

    /// Forgets the angle (no spindle angle this tick).
    pub fn lose_angle(&mut self) {
        self.last_phi = None;
        self.dphi_q8 = None;
    }
}

/// The table's setpoint at `phi` (a null one without a table or angle);
/// updates the angle history.
#[inline(always)]
pub fn setpoint(
    gen: Option<&CommandGen<'static>>,
    coeffs: &Coefficients,
    phi: Option<SpindleAngle>,
    st: &mut SetpointState,
) -> Reference {
    let dphi = st.dphi(phi);
    // Bounds that make every product below plain 64-bit arithmetic (no
    // saturating multiplies on the M4): |Δφ| ≤ 2²⁶ (1/64 turn per tick,
    // 18 750 rpm at 20 kHz), |∂Z/∂φ| ≤ 2²⁷ (1/8 in/rad), |∂²Z/∂φ²| ≤ 2²⁸:
    // far beyond any real cut.
    let dphi64 = i64::from(dphi.clamp(-(1 << 26), 1 << 26));
    let alpha_q8 = match (st.last_phi, phi, st.dphi_q8) {
        (Some(_), Some(_), Some(f)) => {
            let next = f + (((dphi64 << 8) - f) >> ALPHA_SHIFT);
            st.dphi_q8 = Some(next);
            (next - f).clamp(-(1 << 24), 1 << 24)
        }
        (Some(_), Some(_), None) => {
            st.dphi_q8 = Some(dphi64 << 8);
            0
        }
        _ => 0,
    };
    st.last_phi = phi;
    match (gen, phi) {
        (Some(g), Some(phi)) => {
            let c = g.evaluate_phi(coeffs, phi);
            let d1 = i64::from(c.dz_dphi.to_bits().clamp(-(1 << 27), 1 << 27));
            let d2 = i64::from(c.d2z_dphi2.to_bits().clamp(-(1 << 28), 1 << 28));
            // |p >> 16| ≤ 2³⁷, times K < 2²⁴.
            let v = (((d1 * dphi64) >> 16) * FF_K_Q16) >> 25;
            // ∂²Z/∂φ²·Δφ² in codes/tick², Q16: d2·Δφ²·100π²/2⁵⁷, in two
            // steps (≤ 2³⁰ and ≤ 2³² before the constant).
            let t = (((d2 * dphi64) >> 24) * dphi64) >> 24;
            let a2 = (t * FF_K2_Q8) >> 17;
            // ∂Z/∂φ·Δ²φ: |d1·α| ≤ 2⁵¹ → 2³¹ · K (< 2¹⁵).
            let a1 = (((d1 * alpha_q8) >> 20) * FF_K_ALPHA) >> 20;
            Reference {
                code: gauge_code_from_z(c.z),
                velocity_q16: v,
                accel_q16: (a2 + a1).clamp(-(1 << 24), 1 << 24),
            }
        }
        _ => Reference::default(),
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
        // v[Q16] = d1/2³⁰ · Δφ·rad · cpi · 2¹⁶ = d1·Δφ·K/2⁴¹
        let k1 = rad * cpi * 65_536.0 / (1u64 << 30) as f64 * (1u64 << 41) as f64;
        assert!((k1 / FF_K_Q16 as f64 - 1.0).abs() < 1e-7, "{k1}");
        // a[Q16] = d2/2³⁰ · (Δφ·rad)² · cpi · 2¹⁶ = d2·Δφ²·K2/2⁶⁵
        let k2 = rad * rad * cpi * 65_536.0 / (1u64 << 30) as f64 * 2f64.powi(65);
        assert!((k2 / FF_K2_Q8 as f64 - 1.0).abs() < 1e-5, "{k2}");
        // a[Q16] = d1/2³⁰ · α/2⁸·rad · cpi · 2¹⁶ = d1·α·K/2⁴⁰
        let k3 = rad * cpi * 65_536.0 / (1u64 << 30) as f64 / 256.0 * 2f64.powi(40);
        assert!((k3 / FF_K_ALPHA as f64 - 1.0).abs() < 1e-4, "{k3}");
    }
}
