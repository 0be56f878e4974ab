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
pub(crate) mod tests;
