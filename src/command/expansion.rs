//! The command ahead of the loop tick: Z, ∂Z/∂φ, ∂²Z/∂φ², the command's
//! acceleration and the learned correction by spindle angle, evaluated by
//! the handler below the tick (the learning's, `crate::firmware::learning`)
//! at the angle the next tick is predicted to read, handed over in
//! `crate::handoff::ahead`, and stepped in the tick to
//! the angle it does read (a few multiplies instead of the sine, the
//! Horner series, the acceleration's products and the learned table's
//! reads: `docs/BOARD.md`, interrupt cost).
//!
//! # The expansion and its error
//! [`Expansion`] holds, at an angle φ₀, Z in gauge codes Q8 and the two
//! derivatives already scaled to the setpoint's rate units
//! (`p1 = ∂Z/∂φ·FF_K/2³²`, `p2 = ∂²Z/∂φ²·FF_K2/2³²`, see `setpoint`). At
//! φ = φ₀ + δ (δ in the binary angle, |δ| ≤ [`DELTA_LIMIT`]):
//!
//! ```text
//! p1(φ) = p1 + p2·δ/2³⁰                 (∂Z/∂φ to first order)
//! Z(φ)  = Z(φ₀) + (p1 + p1(φ))·δ/2²⁵    (Q8 codes: Z(φ₀) + Z'δ + Z''δ²/2)
//! ```
//!
//! The Taylor remainders bound the error against Z and ∂Z/∂φ evaluated
//! at φ: |ΔZ| ≤ M₃·|δ_rad|³/6 and |Δ∂Z/∂φ| ≤ M₃·δ_rad²/2, where M₃ bounds
//! |∂³Z/∂φ³|: 0.0222 in/rad³ on the default table (sampled over X and φ,
//! with 10 % margin; tested). The tick forms the velocity ∂Z/∂φ(φ)·Δφ
//! from p1(φ) and its own Δφ: exact to first order in δ. Per δ:
//!
//! | δ | Z error | velocity error at 1200 rpm | acceleration error at 1200 rpm |
//! |---|---|---|---|
//! | one tick at 300 rpm (2²⁰) | 0.0007 codes | 0.009 codes/tick | 0.07 codes/tick² |
//! | one tick at 1200 rpm (2²²) | 0.045 codes (0.0009 µin) | 0.14 codes/tick | 0.28 codes/tick² |
//! | two ticks at 1200 rpm | 0.38 codes (0.007 µin) | 0.58 codes/tick | 0.56 codes/tick² |
//! | the limit, 3·2²² (0.0184 rad) | 1.2 codes (0.023 µin) | 1.2 codes/tick | 0.85 codes/tick² |
//!
//! Where the handler runs after every tick (the NUCLEO, host-sim) δ is the
//! prediction's error (the spindle's speed change over a tick: a fraction
//! of a count); on QEMU (its timer 1 runs every 2.3 ticks) δ is zero, one
//! or two ticks of angle. The rounding adds half an LSB of each product:
//! < 0.01 Q8 codes. A third-order term (∂³Z/∂φ³ from the handler) would
//! bring the limit's error to the fourth-order remainder; not done.
//!
//! # The acceleration
//! `Expansion::accel_q16` is the setpoint's acceleration ∂²Z/∂φ²·Δφ² +
//! ∂Z/∂φ·Δ²φ (`setpoint::acceleration`), formed by the handler at φ₀ with
//! the step Δφ₀ and the smoothed Δ²φ₀ the requesting tick posted (the next
//! tick is predicted to repeat them), and not stepped: the tick takes it
//! as it is. Against the closed form at the tick's φ, Δφ and Δ²φ:
//!
//! ```text
//! |Δa| ≤ M₃|δ|Δφ₀² + M₂|Δφ² − Δφ₀²| + M₂|δ||Δ²φ₀| + M₁|Δ²φ − Δ²φ₀|   (radians)
//! ```
//!
//! with M₁ = 0.0063 in/rad and M₂ = 0.0119 in/rad² on the default table
//! (sampled as M₃; tested,
//! `acceleration_from_below_is_within_its_bound_of_the_closed_form`, plus
//! 0.002 codes per tick² of rounding). The first term is the table's
//! last column (the acceleration itself is up to 62 codes per tick² at
//! 1800 rpm on the default table: 1 % of it per tick of δ at 1200 rpm).
//! The second is the speed's change since the request: a 1 % different
//! step at 1200 rpm, 0.49 codes per tick² (the tick formed Δφ² from its
//! own step before, with the same noise one tick later now). The last is
//! Δ²φ one tick late: its smoothing (64 ticks) moves it by 1/64 of the
//! step's change per tick; a 1 % step change at 1200 rpm, 0.32 codes per
//! tick². (This module's docs used to put the first term below 1e-5
//! codes per tick²: the gauge's codes per inch were missing.)

use super::{Coefficients, CommandGen};
use crate::codes::{CODE_MAX, CODE_MIN};
use crate::servo::fixed::{mul_hi, sat_i32, ssat};
use crate::servo::repetitive::DELTA_LIMIT;
use crate::units::SpindleAngle;

/// Q8 codes kept for Z: −2²⁹ ≤ Z < 2²⁹ (4× the gauge's range, clamped to
/// it later; one `SSAT`).
const Z_Q8_LIMIT: i32 = 1 << 29;

/// Gauge codes per tick (Q16) from ∂Z/∂φ (Q30 in/rad) × Δφ (binary angle):
/// `v = p · Δφ · (2π/2³²) · 52 428 800 codes/in · 2¹⁶ / 2³⁰ = p · Δφ · K / 2⁴⁸`
/// with K = 50π · 2²³ = 1 317 679 463 (filling an i32), applied as
/// `((p · K) >> 32) · Δφ >> 16`; the same constant gives the angular
/// acceleration's term from Δ²φ in Q4: `((p · K) >> 32) · α >> 20`.
pub(crate) const FF_K: i32 = 1_317_679_463;
/// Codes per tick² (Q16) from ∂²Z/∂φ² (Q30 in/rad²) × Δφ² (binary angle):
/// `a = d2 · Δφ² · (2π/2³²)² · 52 428 800 · 2¹⁶ / 2³⁰ = d2 · Δφ² · K2 / 2⁷⁸`
/// with K2 = 100π² · 2²¹ = 2 069 806 061, applied as
/// `(((d2 · K2) >> 32) · Δφ >> 23) · Δφ >> 23`.
pub(crate) const FF_K2: i32 = 2_069_806_061;

/// The angle step the rates use: −2²⁶ ≤ Δφ < 2²⁶, 1/64 turn per tick
/// (18 750 rpm at 20 kHz), far beyond any real spindle (one `SSAT`).
#[inline(always)]
pub(crate) fn rate_step(dphi: i32) -> i32 {
    ssat::<27>(dphi)
}

/// The command's acceleration ∂²Z/∂φ²·Δφ² + ∂Z/∂φ·Δ²φ, Q16 codes per
/// tick², from the scaled derivatives `p1`, `p2` of an [`Expansion`]
/// (|p1| < 2²⁷, |p2| < 2²⁷), the step `dphi` (`rate_step`) and Δ²φ
/// (Q4, |Δ²φ| ≤ 2²⁴). Formed below the tick at the predicted angle and
/// step (`crate::firmware::learning`), or in the tick at its own when it evaluates the
/// command itself.
#[inline(always)]
pub(crate) fn acceleration(p1: i32, p2: i32, dphi: i32, alpha_q4: i32) -> i32 {
    // ∂²Z/∂φ²·Δφ²: < 2²⁷, then < 2³⁰, then < 2³³ before saturation.
    let q2 = i64::from(p2) * i64::from(dphi);
    let a2 = (((q2 >> 23) as i32 as i64) * i64::from(dphi)) >> 23;
    // ∂Z/∂φ·Δ²φ: < 2²⁷ · 2²⁴ >> 20 = 2³¹ before saturation.
    let a1 = (i64::from(p1) * i64::from(alpha_q4)) >> 20;
    ssat::<25>(sat_i32(a2 + a1))
}

/// Z and its scaled φ-derivatives at one angle (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Expansion {
    /// φ₀, where the values hold.
    pub phi: SpindleAngle,
    /// Z, gauge codes Q8 (saturated to −2²⁹..2²⁹).
    pub z_q8: i32,
    /// ∂Z/∂φ (clamped to ±2²⁷ Q30 in/rad) times `FF_K`/2³², rounded.
    pub p1: i32,
    /// ∂²Z/∂φ² (clamped to ±2²⁸ Q30 in/rad²) times `FF_K2`/2³², rounded.
    pub p2: i32,
    /// The command's acceleration at φ₀ for the step and Δ²φ it was made
    /// for (`setpoint::acceleration`), Q16 codes per tick²; not stepped.
    pub accel_q16: i32,
}

impl Expansion {
    /// The command at `phi`, evaluated (non-null coefficients), with its
    /// acceleration for the step `dphi` (`setpoint::rate_step`) and Δ²φ
    /// `alpha_q4` (Q4).
    #[inline]
    pub fn direct(
        gen: &CommandGen,
        c: &Coefficients,
        phi: SpindleAngle,
        dphi: i32,
        alpha_q4: i32,
    ) -> Self {
        let cmd = gen.evaluate_phi(c, phi);
        // Bounds that keep every product of the rates a 32-bit multiply:
        // |∂Z/∂φ| ≤ 2²⁷ (1/8 in/rad), |∂²Z/∂φ²| ≤ 2²⁸: far beyond any cut.
        let d1 = cmd.dz_dphi.to_bits().clamp(-(1 << 27), 1 << 27);
        let d2 = cmd.d2z_dphi2.to_bits().clamp(-(1 << 28), 1 << 28);
        // Codes = Z·25·2²¹/2³⁰; Q8 truncated, so that rounding the Q8 value
        // to a code gives exactly `gauge_code_from_z` (tested).
        let z = (i64::from(cmd.z.to_bits()) * 25) >> 1;
        let (p1, p2) = (mul_hi(d1, FF_K), mul_hi(d2, FF_K2));
        Self {
            phi,
            z_q8: z.clamp(-i64::from(Z_Q8_LIMIT), i64::from(Z_Q8_LIMIT) - 1) as i32,
            p1,
            p2,
            accel_q16: acceleration(p1, p2, dphi, alpha_q4),
        }
    }

    /// The expansion moved to `phi` (None beyond [`DELTA_LIMIT`]).
    #[inline(always)]
    pub fn step(&self, phi: SpindleAngle) -> Option<Self> {
        let d = phi.0.wrapping_sub(self.phi.0) as i32;
        if !(-DELTA_LIMIT..=DELTA_LIMIT).contains(&d) {
            return None;
        }
        // |p2| < 2²⁷, |δ| ≤ 2²⁴: < 2²¹ after the shift.
        let p1 = self.p1 + ((i64::from(self.p2) * i64::from(d) + (1 << 29)) >> 30) as i32;
        // |p1 + p1(φ)| < 2²⁸, times 2²⁴: < 2²⁷ codes Q8 after the shift.
        let dz = ((i64::from(self.p1 + p1) * i64::from(d) + (1 << 24)) >> 25) as i32;
        Some(Self {
            phi,
            z_q8: ssat::<30>(self.z_q8.saturating_add(dz)),
            p1,
            p2: self.p2,
            accel_q16: self.accel_q16,
        })
    }

    /// Z in whole gauge codes (rounded), within the gauge's range.
    #[inline(always)]
    pub fn code(&self) -> i32 {
        ((self.z_q8 + (1 << 7)) >> 8).clamp(CODE_MIN, CODE_MAX)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests;
