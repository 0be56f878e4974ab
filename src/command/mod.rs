//! The Z command: Z(X, φ) from the interpolated coefficients and the spindle
//! angle, its analytic derivatives for feedforward, the null zone, and the
//! legacy coefficients C00..C03 (the 1983 analog electronics' columns; their
//! DAC output per X event is `crate::xpos::legacy_output`). Its expansion
//! ahead of the tick is [`expansion`]; the loop's setpoint, [`setpoint`].
//!
//! # Split by rate
//! [`CommandGen::coefficients_into`] depends on X only (the X event, or
//! every loop tick in modern mode); [`CommandGen::evaluate_phi`] (Z, ∂Z/∂φ,
//! ∂²Z/∂φ²) or [`CommandGen::evaluate`] (also ∂Z/∂X) depends on φ and runs
//! every loop tick. `crate::xpos::legacy_output` serves the legacy X event in the
//! coefficient-output mode. All are integer-only, allocation-free, total.
//!
//! # Formats and error budget
//! Coefficients at X arrive in Q30 inches (`I2F30`, LSB 9.3e-10 in), each
//! rounded once by [`crate::table::interp`]. Sines are Q30 with < 3 LSB error
//! ([`crate::trig`]).
//! * Harmonic tables: every product `C_k cos kφ` is formed exactly in Q60
//!   and summed exactly; Z is rounded once. Error ≤ Σ|C_k|·3·2⁻³⁰ +
//!   (columns/2 + 1/2) LSB ≈ 7e-9 in for 7 harmonics (15 columns).
//! * Sin-power tables: Horner in Q30, one rounding per step: ≤ (terms) LSB +
//!   Σ j|c_j|·3·2⁻³⁰ ≈ 5e-9 in for the default table's five terms
//!   (`host-sim accuracy` measures 0.004 µin for the whole fixed-point share).
//!
//! Both are below 0.01 µin (1e-8 in), a tenth of the 0.1 µin goal; the rest
//! belongs to the table (series truncation, grid, coefficient rounding).
//!
//! Units: Z in inches along +Y_t (eq 2-8; a correct command is ≤ 0);
//! ∂Z/∂φ in in/rad, ∂²Z/∂φ² in in/rad², ∂Z/∂X in in/in; all `I2F30`,
//! saturating.

pub mod expansion;
pub mod setpoint;

use crate::safety::Fault;
use crate::table::interp::{Interpolator, Located, Locus};
use crate::table::{CoeffTable, Representation, MAX_TERMS};
use crate::trig::{sin_cos, SinCos};
use crate::units::{SpindleAngle, XInches, ZInches};
use fixed::types::I2F30;

/// Columns a coefficient set can hold: one per table term.
pub(crate) const COLS: usize = MAX_TERMS as usize;
/// Coefficients saturate at ±1/8 in (Q30), twelve times the slide's whole
/// travel: no real table comes near it, and it bounds every sum in
/// the harmonic series without per-step saturation.
pub const COEFF_LIMIT: i32 = 1 << 27;

/// The coefficients at one X, ready for [`CommandGen::evaluate`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Coefficients {
    /// Column values at X, Q30 inches.
    pub value: [i32; COLS],
    /// Column changes across the interval holding X, Q30 inches (for ∂Z/∂X;
    /// filled by [`CommandGen::coefficients_into`], not by the loop tick's
    /// hand-off, which carries values only).
    pub delta: [i32; COLS],
    /// Slope scale of the interval: `delta · per_inch_q16 >> 16` = in/in.
    terms: u8,
    /// X lies in the null zone: the command is zero.
    pub null: bool,
    x: XInches,
}

impl Coefficients {
    /// The null command (X in the null zone, or no table).
    pub const NULL: Self = Self {
        value: [0; COLS],
        delta: [0; COLS],
        terms: 0,
        null: true,
        x: XInches::ZERO,
    };
    /// X these coefficients were computed for.
    pub fn x(&self) -> XInches {
        self.x
    }
    /// Declares `value`/`delta` (filled by the caller, e.g. from a hand-off
    /// buffer) to hold `terms` live columns at `x`.
    pub fn set_live(&mut self, terms: u8, x: XInches) {
        self.terms = terms.min(COLS as u8);
        self.null = false;
        self.x = x;
    }
    /// Makes these the null command at `x` (null zone).
    pub fn set_null(&mut self, x: XInches) {
        self.terms = 0;
        self.null = true;
        self.x = x;
    }
    /// Live columns (0 when null).
    pub fn terms(&self) -> u8 {
        self.terms
    }
}

/// Z and its derivatives at (X, φ).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Command {
    pub z: ZInches,
    /// ∂Z/∂φ, in/rad.
    pub dz_dphi: I2F30,
    /// ∂²Z/∂φ², in/rad².
    pub d2z_dphi2: I2F30,
    /// ∂Z/∂X, in/in (slope of the interpolated coefficients).
    pub dz_dx: I2F30,
}

/// One of the four coefficients of eq 2-19, as carried by the 1983 DACs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Legacy {
    C00 = 0,
    C01 = 1,
    C02 = 2,
    C03 = 3,
}

/// The command generator for one table.
#[derive(Clone, Copy, Debug)]
pub struct CommandGen<'a> {
    pub(crate) interp: Interpolator<'a>,
    pub(crate) repr: Representation,
    terms: u8,
    x_null: XInches,
    /// Every Horner state of a sin-power evaluation stays below 2²⁹ (proved
    /// from the table's largest coefficient at load), so the single-multiply
    /// product [`mul_small`] and plain adds give the same bits as the
    /// saturating path.
    small: bool,
}

#[inline(always)]
pub(crate) fn sat_i32(v: i64) -> i32 {
    v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
}

/// Q60 → Q30, rounded.
#[inline(always)]
fn q60_to_q30(v: i64) -> i64 {
    (v >> 30) + ((v >> 29) & 1)
}

#[inline(always)]
fn fx30(v: i64) -> I2F30 {
    I2F30::from_bits(sat_i32(v))
}

impl<'a> CommandGen<'a> {
    pub fn new(table: CoeffTable<'a>) -> Self {
        let interp = Interpolator::new(table);
        // |P|, |P'|, |P''| and the change series are all bounded by
        // 2·max|c|·Σ_j (j² + 1) (Horner partial sums with |sin φ| ≤ 1; the
        // changes are at most twice the values).
        let weight: i128 = (0..i128::from(table.terms())).map(|j| j * j + 1).sum();
        let bound = 2 * i128::from(interp.max_abs_q30().min(i64::from(COEFF_LIMIT))) * weight;
        Self {
            interp,
            repr: table.representation(),
            terms: table.terms(),
            x_null: table.x_null(),
            small: bound < (1 << 29),
        }
    }

    pub fn interpolator(&self) -> &Interpolator<'a> {
        &self.interp
    }

    /// Start of the null zone (the table's; 7.2 in for the default table).
    pub fn x_null(&self) -> XInches {
        self.x_null
    }

    /// Where X lies, with the null zone applied: `Ok(None)` in the null zone
    /// (X beyond `x_null`, including beyond the last node), an error below
    /// the first node.
    #[inline]
    pub fn locate(&self, x: XInches) -> Result<Option<Locus>, Fault> {
        if x > self.x_null {
            return Ok(None);
        }
        match self.interp.locate(x) {
            Located::In(l) => Ok(Some(l)),
            Located::Above => Ok(None),
            Located::Below => Err(Fault::XOutsideTable),
        }
    }

    /// All columns at X. Below the table: [`Fault::XOutsideTable`] (the
    /// reaction is a ramp to null). In the null zone: [`Coefficients::NULL`].
    pub fn coefficients(&self, x: XInches) -> Result<Coefficients, Fault> {
        let mut c = Coefficients::NULL;
        self.coefficients_into(x, &mut c)?;
        Ok(c)
    }

    /// [`CommandGen::coefficients`] in place (no copy of the arrays: the
    /// loop-tick path). On a fault `c` is left as it was.
    pub fn coefficients_into(&self, x: XInches, c: &mut Coefficients) -> Result<(), Fault> {
        c.x = x;
        let Some(at) = self.locate(x)? else {
            c.null = true;
            c.terms = 0;
            return Ok(());
        };
        c.null = false;
        c.terms = self.terms;
        let n = usize::from(self.terms).min(COLS);
        let (v, d) = (&mut c.value[..n], &mut c.delta[..n]);
        self.interp.columns(at, v, d);
        // Interpolated values lie between node values, and changes are at
        // most twice them: a table within COEFF_LIMIT/2 (all real ones, by
        // orders of magnitude) needs no clamp on this hot path.
        if self.interp.max_abs_q30() > i64::from(COEFF_LIMIT / 2) {
            for x in v.iter_mut().chain(d.iter_mut()) {
                *x = (*x).clamp(-COEFF_LIMIT, COEFF_LIMIT);
            }
        }
        Ok(())
    }

    /// Z, ∂Z/∂φ, ∂²Z/∂φ² and ∂Z/∂X at φ for the coefficients of one X.
    pub fn evaluate(&self, c: &Coefficients, phi: SpindleAngle) -> Command {
        if c.null {
            return Command::default();
        }
        let n = usize::from(c.terms).min(COLS);
        let (v, d) = (&c.value[..n], &c.delta[..n]);
        let (z, d1, d2, dn) = match self.repr {
            Representation::Harmonic => {
                let (z, d1, d2, dn) = harmonic::<true>(v, d, phi);
                (fx30(z), fx30(d1), fx30(d2), dn)
            }
            Representation::SinPower => {
                let [z, d1, d2, dn] = if self.small {
                    sin_power::<true, true>(v, d, sin_cos(phi))
                } else {
                    sin_power::<true, false>(v, d, sin_cos(phi))
                };
                let q30 = I2F30::from_bits;
                (q30(z), q30(d1), q30(d2), i64::from(dn))
            }
        };
        Command {
            z: ZInches(z),
            dz_dphi: d1,
            d2z_dphi2: d2,
            dz_dx: fx30(self.interp.per_inch(dn)),
        }
    }

    /// Z, ∂Z/∂φ and ∂²Z/∂φ² (`dz_dx` left zero): the loop-tick path for
    /// feedforward, without the series of the coefficient changes (∂Z/∂X·Ẋ
    /// is below 1 % of ∂Z/∂φ·ω at any feed this machine uses).
    #[inline]
    pub fn evaluate_phi(&self, c: &Coefficients, phi: SpindleAngle) -> Command {
        if c.null {
            return Command::default();
        }
        let n = usize::from(c.terms).min(COLS);
        let (v, d) = (&c.value[..n], &c.delta[..n]);
        let (z, d1, d2) = match self.repr {
            Representation::Harmonic => {
                let (z, d1, d2, _) = harmonic::<false>(v, d, phi);
                (fx30(z), fx30(d1), fx30(d2))
            }
            Representation::SinPower => {
                // The sin-power series is formed in i32 already: no
                // saturation back from a wider type.
                let [z, d1, d2, _] = if self.small {
                    sin_power::<false, true>(v, d, sin_cos(phi))
                } else {
                    sin_power::<false, false>(v, d, sin_cos(phi))
                };
                let q30 = I2F30::from_bits;
                (q30(z), q30(d1), q30(d2))
            }
        };
        Command {
            z: ZInches(z),
            dz_dphi: d1,
            d2z_dphi2: d2,
            dz_dx: I2F30::ZERO,
        }
    }

    /// Z only, the cheap path (no derivatives).
    pub fn z(&self, x: XInches, phi: SpindleAngle) -> Result<ZInches, Fault> {
        let c = self.coefficients(x)?;
        Ok(self.evaluate(&c, phi).z)
    }

    /// The full command at (X, φ).
    pub fn command(&self, x: XInches, phi: SpindleAngle) -> Result<Command, Fault> {
        let c = self.coefficients(x)?;
        Ok(self.evaluate(&c, phi))
    }

    /// One eq 2-19 coefficient at `at`, Q30 inches. Sin-power tables give
    /// their first four columns; harmonic tables are converted by eq 2-20..23
    /// (C00 = C0 + C2, C01 = S1 + 3 S3, C02 = −2 C2, C03 = −4 S3), which is
    /// exact when the table has no other harmonics than 1..3 (cos φ and
    /// sin 2φ terms cannot be carried by powers of sin φ; the default
    /// geometry's are zero by symmetry).
    pub fn legacy_coefficient(&self, at: Locus, which: Legacy) -> i32 {
        let all = self.legacy_coefficients(at);
        all.get(which as usize).copied().unwrap_or(0)
    }

    /// Table columns the four legacy coefficients are made of: sin-power
    /// C00..C03 directly; harmonic C0, C2, S1, S3 (eq 2-20..2-23).
    pub(crate) fn legacy_columns(&self) -> [u8; 4] {
        match self.repr {
            Representation::SinPower => [0, 1, 2, 3],
            // Harmonic columns: 0 C0, 1 C1, 2 S1, 3 C2, 4 S2, 5 C3, 6 S3.
            Representation::Harmonic => [0, 3, 2, 6],
        }
    }

    /// C00..C03 at `at` (see [`CommandGen::legacy_coefficient`]), Q30
    /// inches, reading the table rows once.
    pub fn legacy_coefficients(&self, at: Locus) -> [i32; 4] {
        let mut v = [0i32; 4];
        self.interp.select(at, &self.legacy_columns(), &mut v);
        match self.repr {
            Representation::SinPower => v,
            Representation::Harmonic => {
                let [c0, c2, s1, s3] = v.map(i64::from);
                [c0 + c2, s1 + 3 * s3, -2 * c2, -4 * s3].map(sat_i32)
            }
        }
    }
}

/// Z = C0 + Σ C_k cos kφ + S_k sin kφ (eq 2-17); columns C0, C1, S1, C2, S2, …
///
/// sin kφ and cos kφ come from one [`sin_cos`] and the angle-addition
/// recurrence (a rotation by φ per harmonic, four products): each step adds
/// at most one LSB of rounding and carries the first step's < 3 LSB, so
/// harmonic k is within 4k LSB (2⁻³⁰) of exact, 6e-8 relative at k = 15
/// (and 1e-11 in on the default geometry's C₂).
///
/// Coefficients are within ±[`COEFF_LIMIT`] (2²⁷) and sines within
/// ±(2³⁰ + 60), so each product is below 2⁵⁸ and the sum of ≤ 16 of them
/// below 2⁶² in Q60: plain (multiply-accumulate) arithmetic cannot overflow.
fn harmonic<const DX: bool>(v: &[i32], d: &[i32], phi: SpindleAngle) -> (i64, i64, i64, i64) {
    let c0 = i64::from(v.first().copied().unwrap_or(0));
    let mut z = c0 << 30; // Q60, exact sums
    let mut zn = i64::from(d.first().copied().unwrap_or(0)) << 30;
    let mut d1 = 0i64; // Q30
    let mut d2 = 0i64; // Q30
    let pairs = v
        .get(1..)
        .unwrap_or(&[])
        .chunks_exact(2)
        .zip(d.get(1..).unwrap_or(&[]).chunks_exact(2));
    let first = sin_cos(phi);
    let (s1, c1) = (i64::from(first.sin), i64::from(first.cos));
    // i32 state: every product below is a single 32×32→64 multiply.
    let (mut si, mut ci) = (first.sin, first.cos);
    for (k, (pv, pd)) in (1i64..).zip(pairs) {
        let (s, c) = (i64::from(si), i64::from(ci));
        let (ck, sk) = (i64::from(pv[0]), i64::from(pv[1]));
        let zk = ck * c + sk * s;
        z += zk;
        if DX {
            let (dck, dsk) = (i64::from(pd[0]), i64::from(pd[1]));
            zn += dck * c + dsk * s;
        }
        d1 += q60_to_q30(sk * c - ck * s) * k;
        d2 -= q60_to_q30(zk) * k * k;
        // (k+1)φ = kφ + φ; |result| ≤ 2³⁰ + 4k: fits an i32.
        si = ((s * c1 + c * s1 + (1 << 29)) >> 30) as i32;
        ci = ((c * c1 - s * s1 + (1 << 29)) >> 30) as i32;
    }
    (q60_to_q30(z), d1, d2, q60_to_q30(zn))
}

/// Q30 × Q30 → Q30 rounded, `b` a sine or cosine (|b| ≤ 2³⁰). Then
/// |a·b/2³⁰| ≤ |a|, and with `a` kept off `i32::MIN` (see [`sat`]) the
/// rounded result always fits an i32: no clamp needed.
#[inline(always)]
fn mul_q30(a: i32, b: i32) -> i32 {
    ((i64::from(a) * i64::from(b) + (1 << 29)) >> 30) as i32
}

/// Saturating add kept within ±(2³¹ − 1), the range [`mul_q30`] needs.
#[inline(always)]
fn sat(a: i32, b: i32) -> i32 {
    a.saturating_add(b).max(-i32::MAX)
}

/// Z = Σ c_j sin^j φ (eq 2-19) by Horner, with P'(s) and P''(s) alongside:
/// ∂Z/∂φ = P'(s) cos φ, ∂²Z/∂φ² = P''(s) cos²φ − P'(s) sin φ. All in i32
/// Q30 with saturating adds (one instruction each on the M4's DSP unit).
fn sin_power<const DX: bool, const SMALL: bool>(v: &[i32], d: &[i32], sc: SinCos) -> [i32; 4] {
    let (s, c) = (sc.sin, sc.cos);
    let mul = |a: i32, b: i32| {
        if SMALL {
            mul_small(a, b)
        } else {
            mul_q30(a, b)
        }
    };
    let add = |a: i32, b: i32| if SMALL { a.wrapping_add(b) } else { sat(a, b) };
    let (mut p, mut dp, mut ddp, mut pn) = (0i32, 0i32, 0i32, 0i32);
    for (cj, dj) in v.iter().rev().zip(d.iter().rev()) {
        ddp = add(mul(ddp, s), add(dp, dp));
        dp = add(mul(dp, s), p);
        p = add(mul(p, s), *cj);
        if DX {
            pn = add(mul(pn, s), *dj);
        }
    }
    let d1 = mul(dp, c);
    let d2 = add(mul(mul(ddp, c), c), -mul(dp, s));
    [p, d1, d2, pn]
}

/// [`mul_q30`] for |a| < 2²⁹: `(4a·b + 2³¹) >> 32` is the same rounded
/// quotient, and is one `SMMULR` on the Cortex-M4.
#[inline(always)]
fn mul_small(a: i32, b: i32) -> i32 {
    ((i64::from(a << 2) * i64::from(b) + (1 << 31)) >> 32) as i32
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    extern crate std;
    use super::*;
    use crate::table::{Geometry, TableHeader};
    use std::vec;
    use std::vec::Vec;

    fn table(repr: Representation, terms: u8, payload: &[i32], nodes: u32) -> Vec<u8> {
        let h = TableHeader {
            representation: repr,
            terms,
            coeff_frac_bits: 30,
            x_frac_bits: 24,
            node_count: nodes,
            x0_raw: 0,
            dx_raw: 1 << 22, // 0.25 in
            x_null_raw: (nodes as i32 - 2) << 22,
            geometry: Geometry {
                c_nin: 316_700_000_000,
                s_y_nin: 28_000_000_000,
                tool_radius_nin: 125_000_000,
            },
        };
        let mut out = vec![0u8; h.image_len()];
        h.encode(payload, &mut out).unwrap();
        out
    }

    fn q30(v: f64) -> i32 {
        (v * 2f64.powi(30)).round() as i32
    }

    /// Both representations of the same trigonometric polynomial give the
    /// same Z and derivatives, against closed forms evaluated in f64.
    #[test]
    fn harmonic_and_sin_power_agree_with_closed_forms() {
        // Node n: C0 = -1e-4 n, S1 = 2e-4 n, C2 = 1e-3 n, S3 = -3e-5 n.
        let nodes = 6u32;
        let coef = |n: f64| (-1e-4 * n, 2e-4 * n, 1e-3 * n, -3e-5 * n);
        let mut harm = Vec::new();
        let mut pow = Vec::new();
        for n in 0..nodes {
            let (c0, s1, c2, s3) = coef(f64::from(n));
            harm.extend([q30(c0), 0, q30(s1), q30(c2), 0, 0, q30(s3)]);
            pow.extend([
                q30(c0 + c2),
                q30(s1 + 3.0 * s3),
                q30(-2.0 * c2),
                q30(-4.0 * s3),
            ]);
        }
        let ih = table(Representation::Harmonic, 7, &harm, nodes);
        let ip = table(Representation::SinPower, 4, &pow, nodes);
        let gh = CommandGen::new(CoeffTable::parse(&ih).unwrap());
        let gp = CommandGen::new(CoeffTable::parse(&ip).unwrap());
        let lsb = 2f64.powi(-30);
        for xi in 0..40 {
            let x = XInches::from_f64(f64::from(xi) * 0.0249);
            let u = x.to_f64() / 0.25;
            let (c0, s1, c2, s3) = coef(u);
            for deg in (0..360).step_by(7) {
                let phi = SpindleAngle::from_degrees(f64::from(deg) + 0.3);
                let p = phi.to_radians();
                let z = c0 + s1 * p.sin() + c2 * (2.0 * p).cos() + s3 * (3.0 * p).sin();
                let dz = s1 * p.cos() - 2.0 * c2 * (2.0 * p).sin() + 3.0 * s3 * (3.0 * p).cos();
                let ddz = -s1 * p.sin() - 4.0 * c2 * (2.0 * p).cos() - 9.0 * s3 * (3.0 * p).sin();
                let (a0, a1, a2, a3) = coef(1.0);
                let dzdx = (a0 + a1 * p.sin() + a2 * (2.0 * p).cos() + a3 * (3.0 * p).sin()) / 0.25;
                for g in [&gh, &gp] {
                    let cmd = g.command(x, phi).unwrap();
                    let fast = g.evaluate_phi(&g.coefficients(x).unwrap(), phi);
                    assert_eq!(
                        (fast.z, fast.dz_dphi, fast.d2z_dphi2),
                        (cmd.z, cmd.dz_dphi, cmd.d2z_dphi2)
                    );
                    assert!(
                        (cmd.z.to_f64() - z).abs() < 12.0 * lsb,
                        "z at {deg} x={x:?} {} {z}",
                        cmd.z.to_f64()
                    );
                    assert!((cmd.dz_dphi.to_num::<f64>() - dz).abs() < 40.0 * lsb);
                    assert!((cmd.d2z_dphi2.to_num::<f64>() - ddz).abs() < 80.0 * lsb);
                    assert!((cmd.dz_dx.to_num::<f64>() - dzdx).abs() < 1e-6);
                }
            }
        }
    }

    /// The derivatives are those of the command itself: a central difference
    /// of Z over a small angle matches ∂Z/∂φ.
    #[test]
    fn dz_dphi_is_the_slope_of_z() {
        let nodes = 4u32;
        let mut harm = Vec::new();
        for n in 0..nodes as i32 {
            harm.extend([
                q30(-3e-4) * n,
                q30(1e-4),
                q30(-5e-4) * n,
                q30(2e-3) * n,
                q30(1e-5),
                q30(4e-6),
                q30(-4e-5) * n,
            ]);
        }
        let img = table(Representation::Harmonic, 7, &harm, nodes);
        let g = CommandGen::new(CoeffTable::parse(&img).unwrap());
        let x = XInches::from_f64(0.4);
        let h = 1u32 << 20; // 1.5e-3 rad
        let hr = f64::from(h) * core::f64::consts::TAU / 2f64.powi(32);
        for k in 0..64u32 {
            let phi = SpindleAngle(k.wrapping_mul(67_108_864 + 12_345));
            let at = |h: u32| {
                let zp = g.z(x, phi.wrapping_add(SpindleAngle(h))).unwrap().to_f64();
                let zm = g
                    .z(x, SpindleAngle(phi.0.wrapping_sub(h)))
                    .unwrap()
                    .to_f64();
                (zp, zm)
            };
            let c = g.command(x, phi).unwrap();
            let (zp, zm) = at(h);
            let slope = (zp - zm) / (2.0 * hr);
            // Curvature needs a wider step: Z's LSB over h² would swamp it.
            let (zp, zm) = at(h << 4);
            let curv = (zp + zm - 2.0 * c.z.to_f64()) / (256.0 * hr * hr);
            assert!(
                (c.dz_dphi.to_num::<f64>() - slope).abs() < 6e-7,
                "k={k} {} {slope}",
                c.dz_dphi
            );
            assert!(
                (c.d2z_dphi2.to_num::<f64>() - curv).abs() < 2e-5,
                "k={k} {} {curv}",
                c.d2z_dphi2
            );
        }
    }

    /// A table holding one harmonic k at a time: Z is C_k cos kφ + S_k sin kφ
    /// within the recurrence's documented 4k LSB (plus rounding), for
    /// k = 1..=15, against libm.
    #[test]
    fn high_harmonics_within_the_recurrence_bound() {
        let one = 1 << 26; // 1/16 in
        for k in 1..=15usize {
            let mut row = [0i32; 31];
            row[2 * k - 1] = one;
            row[2 * k] = one / 2;
            let payload: Vec<i32> = [row, row, row].concat();
            let img = table(Representation::Harmonic, 31, &payload, 3);
            let g = CommandGen::new(CoeffTable::parse(&img).unwrap());
            let mut a: u32 = 7;
            for _ in 0..500 {
                a = a.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                let phi = SpindleAngle(a).to_radians() * k as f64;
                let want = (phi.cos() + 0.5 * phi.sin()) / 16.0;
                let got = g
                    .z(XInches::from_f64(0.1), SpindleAngle(a))
                    .unwrap()
                    .to_f64();
                // 4k LSB of the sines, scaled by the 1/16 in amplitude (×1.5), + 1 LSB.
                let bound = (4.0 * k as f64 * 1.5 / 16.0 + 1.5) * 2f64.powi(-30);
                assert!((got - want).abs() <= bound, "k={k}: {got} vs {want}");
            }
        }
    }

    /// The single-multiply path taken for tables of machine size gives the
    /// same bits as the saturating path.
    #[test]
    fn small_path_equals_saturating_path() {
        let g = CommandGen::new(CoeffTable::parse(crate::DEFAULT_TABLE).unwrap());
        assert!(g.small);
        let slow = CommandGen { small: false, ..g };
        let mut a: u32 = 99;
        for k in 0..3000u32 {
            a = a.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let x = XInches::from_bits((k * 40_427) as i32 % (121 << 20));
            let c = g.coefficients(x).unwrap();
            assert_eq!(
                g.evaluate(&c, SpindleAngle(a)),
                slow.evaluate(&c, SpindleAngle(a))
            );
        }
    }

    #[test]
    fn null_zone_and_outside_table() {
        let nodes = 5u32;
        let pow: Vec<i32> = (0..nodes as i32 * 4).map(|i| -1000 * i).collect();
        let img = table(Representation::SinPower, 4, &pow, nodes);
        let g = CommandGen::new(CoeffTable::parse(&img).unwrap());
        // x_null = 0.75 in: at the boundary the command is live, beyond it null.
        let phi = SpindleAngle::from_degrees(90.0);
        assert_ne!(g.z(XInches::from_f64(0.75), phi).unwrap(), ZInches::ZERO);
        assert_eq!(
            g.z(XInches::from_f64(0.7500001), phi).unwrap(),
            ZInches::ZERO
        );
        assert_eq!(
            g.command(XInches::from_f64(50.0), phi).unwrap(),
            Command::default()
        );
        assert_eq!(
            g.z(XInches::from_f64(-1e-6), phi),
            Err(Fault::XOutsideTable)
        );
    }

    /// The interval-cached legacy output gives exactly the frames of the
    /// stateless one, across interval changes in both directions.
    #[test]
    fn legacy_output_cache_is_exact() {
        use crate::xpos::legacy_output::LegacyOutput;
        use crate::xpos::{half_mils_to_x, XUpdate};
        let nodes = 6u32;
        let mut harm = Vec::new();
        let mut pow = Vec::new();
        for n in 0..nodes as i32 {
            harm.extend([
                q30(-1e-5) * n,
                7,
                q30(2e-4) * n,
                q30(-1.3e-3) * n,
                5,
                3,
                q30(4e-6) * n,
            ]);
            pow.extend([
                q30(-1e-5) * n,
                q30(2e-4) * n,
                q30(-1.3e-3) * n,
                q30(4e-6) * n,
            ]);
        }
        for (img, repr) in [
            (table(Representation::Harmonic, 7, &harm, nodes), "harmonic"),
            (table(Representation::SinPower, 4, &pow, nodes), "sin-power"),
        ] {
            let g = CommandGen::new(CoeffTable::parse(&img).unwrap());
            let mut out = LegacyOutput::new();
            let sweep = (0..2000u32).chain((0..2000u32).rev()).step_by(7);
            for (k, hm) in sweep.enumerate() {
                let u = XUpdate {
                    half_mils: hm,
                    x: half_mils_to_x(hm),
                    update: (k % 16) as u8,
                    null: hm > 1990,
                };
                assert_eq!(out.frame(&g, &u), g.legacy_frame(&u), "{repr} at {hm}");
            }
        }
    }

    #[test]
    fn legacy_codes_follow_table_3_1() {
        use crate::xpos::legacy_output::legacy_dac_code;
        assert_eq!(legacy_dac_code(0), 32768);
        // +0.010 in is full scale (one LSB past the top code), -0.010 in is code 0.
        assert_eq!(legacy_dac_code(q30(0.010)), 65535);
        assert_eq!(legacy_dac_code(q30(-0.010)), 0);
        // 1 µin = 3.2768 LSB; C02 at X = 7.2 in (Table 2-2) = -0.0048855 in.
        assert_eq!(legacy_dac_code(q30(1e-6)), 32771);
        assert_eq!(legacy_dac_code(q30(-0.0048855)), 32768 - 16009);
    }

    mod prop {
        use super::*;
        use proptest::prelude::*;

        fn default_gen() -> CommandGen<'static> {
            CommandGen::new(CoeffTable::parse(crate::DEFAULT_TABLE).unwrap())
        }

        proptest! {
            /// The default table over the whole X range (and beyond) and
            /// every φ: no fault above X = 0, a command that is never
            /// positive beyond the error budget (max over φ of Z is 0), of
            /// the size the machine needs (< 0.008 in), and continuous in X:
            /// one X LSB (6e-8 in) moves Z by at most slope·LSB + rounding.
            #[test]
            fn default_table_over_all_x_and_phi(xbits in 0i32..(9 << 24), phi in any::<u32>()) {
                let g = default_gen();
                let x = XInches::from_bits(xbits);
                let c = g.command(x, SpindleAngle(phi)).unwrap();
                let z = c.z.to_f64();
                prop_assert!(z <= 0.1e-6 && z > -0.008, "Z({x:?}) = {z}");
                let n = g.command(XInches::from_bits(xbits + 1), SpindleAngle(phi)).unwrap();
                if x < g.x_null() {
                    // |∂Z/∂X| < 0.002 in/in: 6e-8 in of X moves Z < 1.2e-10 in,
                    // plus a few LSB of rounding (9.3e-10 in each).
                    prop_assert!((n.z.to_f64() - z).abs() < 5e-9, "jump at {x:?}");
                    prop_assert!(c.dz_dx.to_num::<f64>().abs() < 0.002);
                }
            }

            /// Crossing a grid node of the default table exactly: no step.
            #[test]
            fn default_table_continuous_at_every_node(node in 1u32..230, phi in any::<u32>()) {
                let g = default_gen();
                let xn = g.interpolator().table().node_x(node);
                let a = g.z(XInches::from_bits(xn.to_bits() - 1), SpindleAngle(phi)).unwrap();
                let b = g.z(xn, SpindleAngle(phi)).unwrap();
                prop_assert!((a.to_f64() - b.to_f64()).abs() < 5e-9);
            }

            /// No overflow or panic anywhere in X and φ, for any coefficient
            /// values the format can hold, in both representations; and
            /// with coefficients of machine size (|c| ≤ 0.02 in) Z stays
            /// within Σ|c| (no wrap-around).
            #[test]
            fn no_overflow_over_x_and_phi(
                vals in proptest::collection::vec(any::<i32>(), 28),
                small in proptest::collection::vec(-21_474_836i32..21_474_836, 28),
                harmonic in any::<bool>(),
                xbits in any::<i32>(), phi in any::<u32>(),
            ) {
                let (repr, terms) = if harmonic { (Representation::Harmonic, 7u8) } else { (Representation::SinPower, 7u8) };
                for payload in [&vals, &small] {
                    let img = table(repr, terms, payload, 4);
                    let g = CommandGen::new(CoeffTable::parse(&img).unwrap());
                    let r = g.command(XInches::from_bits(xbits), SpindleAngle(phi));
                    if payload == &small {
                        if let Ok(c) = r {
                            let bound: f64 = small.iter().map(|v| f64::from(*v).abs()).sum::<f64>() * 2f64.powi(-30);
                            prop_assert!(c.z.to_f64().abs() <= bound + 1e-8);
                        }
                    }
                }
            }
        }
    }
}
