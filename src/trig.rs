//! Fixed-point sine and cosine of the binary spindle angle.
//!
//! # Method
//!
//! A table of sin at 1024 points per turn (plus a quarter turn more, so cos is
//! the same table shifted by 256), then a third-order Taylor step from the
//! node: with `d` the angle past the node (|d| < 2π/1024 = 6.1e-3 rad),
//!
//! ```text
//! sin(a + d) = s0 (1 − d²/2) + c0 (d − d³/6)      (+ s0 d⁴/24 + …)
//! cos(a + d) = c0 (1 − d²/2) − s0 (d − d³/6)      (+ c0 d⁴/24 + …)
//! ```
//!
//! Each evaluation gives both functions (the derivatives and the harmonics
//! need both), costs four 32×32→64 multiplies per function, no division and
//! no branch on the angle.
//!
//! # Error budget (units of the result: 1.0 = 2³⁰, LSB = 9.3e-10)
//!
//! | source | bound |
//! |---|---|
//! | table rounding (nodes rounded to Q30) | 0.5 LSB |
//! | truncated series, d⁴/24 < 5.9e-11 | 0.07 LSB |
//! | angle scaling (2π rounded to 29 fraction bits), d error < 4e-17 | ≪ 0.01 LSB |
//! | four products rounded to nearest | 2 LSB |
//! | **total** | **< 3 LSB = 2.8e-9** |
//!
//! The test `error_bound_over_the_whole_turn` checks this bound against the
//! host's libm on a dense grid plus every table node and its neighbours. In
//! the command path the largest term multiplied by a sine is ≈ 0.0025 in (C₂
//! at X = 7.2 in), so the sine contributes < 7e-12 in: nothing against the
//! 0.1 µin (1e-7 in) goal.

use crate::units::SpindleAngle;

/// Fraction bits of [`SinCos`] values: 1.0 = 2³⁰.
pub const FRAC_BITS: u32 = 30;
/// 1.0 in the [`SinCos`] format.
pub const ONE: i32 = 1 << FRAC_BITS;

/// log2 of the table points per turn.
const TABLE_BITS: u32 = 10;
const POINTS_PER_TURN: usize = 1 << TABLE_BITS;
/// Table length: one turn plus a quarter, so `cos(k) = sin(k + N/4)` needs no wrap.
const TABLE_LEN: usize = POINTS_PER_TURN + POINTS_PER_TURN / 4;
/// Bits of the binary angle below the table index.
const REM_BITS: u32 = 32 - TABLE_BITS;
/// 2π with 29 fraction bits (3373259426.2 rounded): `rem · 2π / 2³²` rad in Q32
/// is `rem · 2π` with the binary point moved, so `d = (rem · TWO_PI_Q29) >> 29`.
const TWO_PI_Q29: u64 = 3_373_259_426;

/// Sine and cosine, both with [`FRAC_BITS`] fraction bits (1.0 = 2³⁰).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SinCos {
    pub sin: i32,
    pub cos: i32,
}

/// sin x for |x| ≤ π/2 by its Taylor series, in f64, at compile time only.
const fn taylor_sin(x: f64) -> f64 {
    let mut term = x;
    let mut sum = x;
    let mut n = 1.0;
    while n < 40.0 {
        term = -term * x * x / ((n + 1.0) * (n + 2.0));
        sum += term;
        n += 2.0;
    }
    sum
}

const fn taylor_cos(x: f64) -> f64 {
    let mut term = 1.0;
    let mut sum = 1.0;
    let mut n = 0.0;
    while n < 40.0 {
        term = -term * x * x / ((n + 1.0) * (n + 2.0));
        sum += term;
        n += 2.0;
    }
    sum
}

const fn round_q30(v: f64) -> i32 {
    let s = v * (ONE as f64);
    (if s >= 0.0 { s + 0.5 } else { s - 0.5 }) as i32
}

/// The sine table, built by the compiler (its constant evaluation is IEEE
/// and deterministic, so host and target images hold identical bits); a
/// `static`, because a `const` was copied into every function that inlined
/// `sin_cos` (four times 5 KiB of flash on the NUCLEO). Symmetry
/// folds every node into the first quadrant, where the series is exact to
/// f64 precision, so nodes a quarter turn apart are exactly ± each other.
static SIN_TABLE: [i32; TABLE_LEN] = {
    let mut t = [0i32; TABLE_LEN];
    let quarter = POINTS_PER_TURN / 4;
    let mut k = 0;
    while k < TABLE_LEN {
        let q = (k / quarter) % 4;
        let r = k % quarter;
        let x = (r as f64) * (core::f64::consts::TAU / (POINTS_PER_TURN as f64));
        let v = match q {
            0 => taylor_sin(x),
            1 => taylor_cos(x),
            2 => -taylor_sin(x),
            _ => -taylor_cos(x),
        };
        t[k] = round_q30(v);
        k += 1;
    }
    t
};

/// Product of a Q30 value and a Q32 value below 2³¹, rounded, in Q30: one
/// `SMMULR` on the Cortex-M4 (both operands are `i32`, so the compiler
/// sees a 32×32 multiply).
#[inline(always)]
fn mul_q32(a: i32, b_q32: u32) -> i32 {
    ((i64::from(a) * i64::from(b_q32 as i32) + (1 << 31)) >> 32) as i32
}

/// sin φ and cos φ of a binary angle. Never panics; total on every input.
#[inline]
pub fn sin_cos(angle: SpindleAngle) -> SinCos {
    // Both indices are provably inside the table (≤ 1023 + 256 < 1280), so
    // the compiler drops the bounds checks.
    let idx = (angle.0 >> REM_BITS) as usize & (POINTS_PER_TURN - 1);
    let s0 = SIN_TABLE[idx];
    let c0 = SIN_TABLE[idx + POINTS_PER_TURN / 4];
    let rem = u64::from(angle.0 & ((1 << REM_BITS) - 1));
    // d < 2^22 · 2π < 2^25 in Q32 (i.e. < 6.2e-3 rad).
    let d = ((rem * TWO_PI_Q29) >> 29) as u32;
    let dd = u64::from(d);
    // d²/2 and d³/6 in Q32; the divisions are by constants (multiplies).
    let d2h = ((dd * dd) >> 33) as u32;
    // < 2^25: a 32-bit division by a constant (a multiply), not a 64-bit call.
    let d3s = ((u64::from(d2h) * dd) >> 32) as u32 / 3;
    // All in i32: |s0|, |c0| ≤ 2³⁰ and each correction is below 2²⁵, so
    // the sums cannot overflow (and stay 32-bit values for the multiplies
    // of the series that use them).
    let s = s0 + mul_q32(c0, d) - mul_q32(s0, d2h) - mul_q32(c0, d3s);
    let c = c0 - mul_q32(s0, d) - mul_q32(c0, d2h) + mul_q32(s0, d3s);
    // |s|, |c| ≤ 2^30 + 3: the clamp only guards the format's edge.
    SinCos {
        sin: s.clamp(-ONE, ONE),
        cos: c.clamp(-ONE, ONE),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    extern crate std;
    use super::*;

    fn err_lsb(a: SpindleAngle) -> (f64, f64) {
        let sc = sin_cos(a);
        let x = f64::from(a.0) * core::f64::consts::TAU / 4_294_967_296.0;
        let one = f64::from(ONE);
        (
            (f64::from(sc.sin) - x.sin() * one).abs(),
            (f64::from(sc.cos) - x.cos() * one).abs(),
        )
    }

    #[test]
    fn error_bound_over_the_whole_turn() {
        let mut worst = 0.0f64;
        // A dense, irregular sweep (a step coprime to the table spacing) …
        let mut a: u32 = 0;
        for _ in 0..400_000 {
            let (es, ec) = err_lsb(SpindleAngle(a));
            worst = worst.max(es).max(ec);
            a = a.wrapping_add(10_737_421);
        }
        // … and every node with its immediate neighbours and the cell's end.
        for k in 0..1024u32 {
            let n = k << REM_BITS;
            for off in [0u32, 1, (1 << REM_BITS) - 1, (1 << REM_BITS) / 2] {
                let (es, ec) = err_lsb(SpindleAngle(n.wrapping_add(off)));
                worst = worst.max(es).max(ec);
                let (es, ec) = err_lsb(SpindleAngle(n.wrapping_sub(off)));
                worst = worst.max(es).max(ec);
            }
        }
        assert!(
            worst < 3.0,
            "worst error {worst} LSB exceeds the 3 LSB budget"
        );
    }

    #[test]
    fn exact_at_the_quadrant_points_and_odd_even() {
        assert_eq!(sin_cos(SpindleAngle(0)), SinCos { sin: 0, cos: ONE });
        assert_eq!(sin_cos(SpindleAngle(1 << 30)), SinCos { sin: ONE, cos: 0 });
        assert_eq!(sin_cos(SpindleAngle(1 << 31)), SinCos { sin: 0, cos: -ONE });
        assert_eq!(sin_cos(SpindleAngle(3 << 30)), SinCos { sin: -ONE, cos: 0 });
        // sin(−φ) = −sin φ, cos(−φ) = cos φ, within the rounding of the step.
        let mut a: u32 = 12345;
        for _ in 0..10_000 {
            let p = sin_cos(SpindleAngle(a));
            let m = sin_cos(SpindleAngle(a.wrapping_neg()));
            assert!((p.sin + m.sin).abs() <= 4 && (p.cos - m.cos).abs() <= 4);
            a = a.wrapping_mul(1_103_515_245).wrapping_add(12345);
        }
    }

    mod prop {
        use super::*;
        use proptest::prelude::*;

        proptest! {
            /// Any angle of the turn: both functions within the 3 LSB budget
            /// of the host's libm (the sweeps above are fixed grids).
            #[test]
            fn within_budget_at_any_angle(a in any::<u32>()) {
                let (es, ec) = err_lsb(SpindleAngle(a));
                prop_assert!(es < 3.0 && ec < 3.0, "{a}: {es} / {ec} LSB");
            }

            /// sin is odd and cos even, and a half turn negates both, within
            /// the rounding of two evaluations (2 × 3 LSB).
            #[test]
            fn odd_even_and_half_turn_symmetry(a in any::<u32>()) {
                let p = sin_cos(SpindleAngle(a));
                let m = sin_cos(SpindleAngle(a.wrapping_neg()));
                let h = sin_cos(SpindleAngle(a.wrapping_add(1 << 31)));
                prop_assert!((p.sin + m.sin).abs() <= 6 && (p.cos - m.cos).abs() <= 6);
                prop_assert!((p.sin + h.sin).abs() <= 6 && (p.cos + h.cos).abs() <= 6);
            }

            /// sin² + cos² = 1 to the budget: 2·3 LSB relative to 2³⁰.
            #[test]
            fn pythagorean_identity(a in any::<u32>()) {
                let p = sin_cos(SpindleAngle(a));
                let one = f64::from(ONE);
                let r = (f64::from(p.sin).powi(2) + f64::from(p.cos).powi(2)) / one - one;
                prop_assert!(r.abs() <= 6.0, "{a}: {r} LSB");
            }
        }
    }
}
