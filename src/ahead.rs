//! The command ahead of the loop tick: Z, ∂Z/∂φ and ∂²Z/∂φ² evaluated by
//! the handler below the tick (the learning's, `crate::learning`) at the
//! angle the next tick is predicted to read, and stepped in the tick to
//! the angle it does read by a second-order Taylor step (a few multiplies
//! instead of the sine and the Horner series: `docs/BOARD.md`, interrupt
//! cost).
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
//! with 10 % margin; tested). Per δ:
//!
//! | δ | Z error | velocity error at 1200 rpm |
//! |---|---|---|
//! | one tick at 300 rpm (2²⁰) | 0.0007 codes | 0.009 codes/tick |
//! | one tick at 1200 rpm (2²²) | 0.045 codes (0.0009 µin) | 0.14 codes/tick |
//! | two ticks at 1200 rpm | 0.38 codes (0.007 µin) | 0.58 codes/tick |
//! | the limit, 3·2²² (0.0184 rad) | 1.2 codes (0.023 µin) | 1.2 codes/tick |
//!
//! Where the handler runs after every tick (the NUCLEO, host-sim) δ is the
//! prediction's error (the spindle's speed change over a tick: a fraction
//! of a count); on QEMU (its timer 1 runs every 2.3 ticks) δ is zero, one
//! or two ticks of angle. The rounding adds half an LSB of each product:
//! < 0.01 Q8 codes. ∂²Z/∂φ² is taken at φ₀ (its error M₃·|δ_rad| enters
//! the acceleration times Δφ²: below 1e-5 codes per tick²). A third-order
//! term (∂³Z/∂φ³ from the handler) would bring the limit's error to the
//! fourth-order remainder; not done yet.
//!
//! # Freshness
//! The tick uses an expansion only if it was made for a tick at most
//! [`MAX_AGE`] ticks ago and |δ| ≤ [`DELTA_LIMIT`]; otherwise (the handler
//! starved by higher priorities) the tick evaluates the command itself
//! (`Expansion::direct`, the same arithmetic at δ = 0), so a late handler
//! costs instructions, never accuracy. While the command was null (no
//! angle yet, no coefficients), it stays null until the first expansion
//! arrives (one or two ticks): no jump, the slew profile joins it.

use crate::codes::{CODE_MAX, CODE_MIN};
use crate::command::{Coefficients, CommandGen};
use crate::handoff::{Shared, NULL_META};
use crate::servo::fixed::mul_hi;
use crate::units::{SpindleAngle, XInches};
use core::sync::atomic::{fence, Ordering};

/// Largest |φ − φ₀| an expansion is stepped over: 3·2²², 1/341 turn
/// (two ticks at 1800 rpm and 20 kHz).
pub const DELTA_LIMIT: i32 = 3 << 22;
/// Oldest expansion the tick uses, in ticks after the one it was made for.
pub const MAX_AGE: u32 = 4;
/// Q8 codes kept for Z: ±2²⁹ (4× the gauge's range, clamped to it later).
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

/// Z and its scaled φ-derivatives at one angle (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Expansion {
    /// φ₀, where the values hold.
    pub phi: SpindleAngle,
    /// Z, gauge codes Q8 (saturated to ±2²⁹).
    pub z_q8: i32,
    /// ∂Z/∂φ (clamped to ±2²⁷ Q30 in/rad) times `FF_K`/2³², rounded.
    pub p1: i32,
    /// ∂²Z/∂φ² (clamped to ±2²⁸ Q30 in/rad²) times `FF_K2`/2³², rounded.
    pub p2: i32,
}

impl Expansion {
    /// The command at `phi`, evaluated (non-null coefficients).
    #[inline]
    pub fn direct(gen: &CommandGen, c: &Coefficients, phi: SpindleAngle) -> Self {
        let cmd = gen.evaluate_phi(c, phi);
        // Bounds that keep every product of the rates a 32-bit multiply:
        // |∂Z/∂φ| ≤ 2²⁷ (1/8 in/rad), |∂²Z/∂φ²| ≤ 2²⁸: far beyond any cut.
        let d1 = cmd.dz_dphi.to_bits().clamp(-(1 << 27), 1 << 27);
        let d2 = cmd.d2z_dphi2.to_bits().clamp(-(1 << 28), 1 << 28);
        // Codes = Z·25·2²¹/2³⁰; Q8 truncated, so that rounding the Q8 value
        // to a code gives exactly `gauge_code_from_z` (tested).
        let z = (i64::from(cmd.z.to_bits()) * 25) >> 1;
        Self {
            phi,
            z_q8: z.clamp(-i64::from(Z_Q8_LIMIT), i64::from(Z_Q8_LIMIT)) as i32,
            p1: mul_hi(d1, FF_K),
            p2: mul_hi(d2, FF_K2),
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
            z_q8: self.z_q8.saturating_add(dz).clamp(-Z_Q8_LIMIT, Z_Q8_LIMIT),
            p1,
            p2: self.p2,
        })
    }

    /// Z in whole gauge codes (rounded), within the gauge's range.
    #[inline(always)]
    pub fn code(&self) -> i32 {
        ((self.z_q8 + (1 << 7)) >> 8).clamp(CODE_MIN, CODE_MAX)
    }
}

/// What the tick takes from the hand-off: the expansion, for which tick,
/// and the coefficient set it was evaluated from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ahead {
    /// The tick it was predicted for ([`crate::looptick::LoopState::ticks`]).
    pub tick: u32,
    /// `None`: the command is null (null zone, no table).
    pub expansion: Option<Expansion>,
    /// X of the coefficients.
    pub x: XInches,
    /// Their generation ([`Shared::coefficient_generation`]).
    pub coeff_gen: u32,
}

/// State of the evaluation ahead of the tick (runs in the learning
/// handler, below the tick and, on the NUCLEO, below the X handlers).
#[derive(Clone, Debug)]
pub struct AheadState {
    gen: Option<CommandGen<'static>>,
    /// An X source publishes coefficients.
    x_published: bool,
    coeffs: Coefficients,
    coeff_seen: u32,
    /// The tick's angle request last evaluated.
    request_seen: u32,
    /// Expansions published (the hand-off's generation).
    published: u32,
}

impl AheadState {
    pub(crate) fn new(gen: Option<CommandGen<'static>>, x_published: bool) -> Self {
        Self {
            gen,
            x_published,
            coeffs: Coefficients::NULL,
            coeff_seen: 0,
            request_seen: 0,
            published: 0,
        }
    }

    /// Takes a new coefficient set, evaluates the command at the angle the
    /// next tick is predicted to read (this tick's angle plus its step) and
    /// publishes it; nothing when the tick posted no new angle.
    #[inline(never)]
    pub fn run(&mut self, sh: &Shared) {
        if self.x_published {
            // A set overwritten while copied (an X handler preempting this
            // one, on the NUCLEO) is taken again: the next read finds the
            // newer set complete unless X events come microseconds apart.
            for _ in 0..3 {
                if sh
                    .take_coefficients(&mut self.coeff_seen, &mut self.coeffs)
                    .is_ok()
                {
                    break;
                }
            }
        }
        let Some((tick, phi, dphi)) = sh.ahead.request() else {
            return;
        };
        if tick == self.request_seen {
            return;
        }
        self.request_seen = tick;
        let at = SpindleAngle(phi.wrapping_add(dphi as u32));
        let expansion = match &self.gen {
            Some(g) if !self.coeffs.null => Some(Expansion::direct(g, &self.coeffs, at)),
            _ => None,
        };
        self.published = self.published.wrapping_add(1);
        sh.ahead.publish(
            self.published,
            &Ahead {
                tick: tick.wrapping_add(1),
                expansion,
                x: self.coeffs.x(),
                coeff_gen: self.coeff_seen,
            },
        );
    }

    /// The coefficients this handler evaluates (the last set taken).
    pub fn coefficients(&self) -> &Coefficients {
        &self.coeffs
    }
}

/// Words of one published expansion: sequence, tick, φ₀, Z, p1, p2, X,
/// coefficient generation, null flag.
const WORDS: usize = 9;

/// The hand-off of [`crate::handoff::Shared`] between the tick (angle
/// requests in, expansions out) and [`AheadState`]: the tick's request is
/// three words (a torn one only moves φ₀, which the tick checks), the
/// expansion two slots under the coefficients' seqlock rule.
pub(crate) struct AheadHandoff {
    /// [φ, Δφ, tick]: the tick's angle and step; tick 0 = none yet.
    request: [core::sync::atomic::AtomicU32; 3],
    gen: core::sync::atomic::AtomicU32,
    slots: [[core::sync::atomic::AtomicU32; WORDS]; 2],
}

impl AheadHandoff {
    pub(crate) const fn new() -> Self {
        use core::sync::atomic::AtomicU32;
        Self {
            request: [const { AtomicU32::new(0) }; 3],
            gen: AtomicU32::new(0),
            slots: [const { [const { AtomicU32::new(0) }; WORDS] }; 2],
        }
    }

    /// The tick's angle and step (the tick; `tick` ≠ 0).
    #[inline(always)]
    pub(crate) fn post(&self, tick: u32, phi: SpindleAngle, dphi: i32) {
        self.request[0].store(phi.0, Ordering::Relaxed);
        self.request[1].store(dphi as u32, Ordering::Relaxed);
        self.request[2].store(tick, Ordering::Release);
    }

    fn request(&self) -> Option<(u32, u32, i32)> {
        let tick = self.request[2].load(Ordering::Acquire);
        if tick == 0 {
            return None;
        }
        let phi = self.request[0].load(Ordering::Relaxed);
        let dphi = self.request[1].load(Ordering::Relaxed) as i32;
        Some((tick, phi, dphi))
    }

    fn publish(&self, g: u32, a: &Ahead) {
        let slot = &self.slots[(g & 1) as usize];
        slot[0].store(g, Ordering::Relaxed);
        fence(Ordering::Release);
        let e = a.expansion.unwrap_or_default();
        let words = [
            a.tick,
            e.phi.0,
            e.z_q8 as u32,
            e.p1 as u32,
            e.p2 as u32,
            a.x.to_bits() as u32,
            a.coeff_gen,
            if a.expansion.is_some() { 0 } else { NULL_META },
        ];
        for (w, v) in slot[1..].iter().zip(words) {
            w.store(v, Ordering::Relaxed);
        }
        self.gen.store(g, Ordering::Release);
    }

    /// The latest expansion (the tick; `None` before the first or when
    /// overwritten while read).
    #[inline(always)]
    pub(crate) fn latest(&self) -> Option<Ahead> {
        let g = self.gen.load(Ordering::Acquire);
        if g == 0 {
            return None;
        }
        let slot = &self.slots[(g & 1) as usize];
        let w: [u32; WORDS - 1] = core::array::from_fn(|k| slot[k + 1].load(Ordering::Relaxed));
        fence(Ordering::Acquire);
        if slot[0].load(Ordering::Relaxed) != g {
            return None;
        }
        Some(Ahead {
            tick: w[0],
            expansion: (w[7] & NULL_META == 0).then_some(Expansion {
                phi: SpindleAngle(w[1]),
                z_q8: w[2] as i32,
                p1: w[3] as i32,
                p2: w[4] as i32,
            }),
            x: XInches::from_bits(w[5] as i32),
            coeff_gen: w[6],
        })
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    extern crate std;
    use super::*;
    use crate::codes::gauge_code_from_z;
    use crate::table::CoeffTable;
    use crate::DEFAULT_TABLE;

    /// Gauge codes per inch, and radians per binary-angle unit.
    const CPI: f64 = 524_288.0 / 0.010;
    const RAD: f64 = core::f64::consts::TAU / 4_294_967_296.0;
    /// M₃ of the default table as the module docs state it, in/rad³.
    const M3_DOC: f64 = 0.0223;

    /// Z, ∂Z/∂φ, ∂²Z/∂φ² of Σ c_j sin^j φ in f64 (inches, radians): the
    /// closed form, independent of the fixed-point Horner.
    fn exact(c: &[f64], phi: f64) -> [f64; 3] {
        let (s, co) = (libm::sin(phi), libm::cos(phi));
        let (mut z, mut d1, mut d2) = (0.0, 0.0, 0.0);
        for (j, cj) in c.iter().enumerate() {
            let j = j as f64;
            z += cj * libm::pow(s, j);
            if j >= 1.0 {
                d1 += cj * j * libm::pow(s, j - 1.0) * co;
                d2 -= cj * j * libm::pow(s, j);
            }
            if j >= 2.0 {
                d2 += cj * j * (j - 1.0) * libm::pow(s, j - 2.0) * co * co;
            }
        }
        [z, d1, d2]
    }

    fn gen() -> CommandGen<'static> {
        CommandGen::new(CoeffTable::parse(DEFAULT_TABLE).unwrap())
    }

    /// ∂³Z/∂φ³ of Σ c_j sin^j φ in f64 (in/rad³).
    fn third(c: &[f64], phi: f64) -> f64 {
        let (s, co) = (libm::sin(phi), libm::cos(phi));
        let p = |k: f64| if k < 0.0 { 0.0 } else { libm::pow(s, k) };
        c.iter()
            .enumerate()
            .map(|(j, cj)| {
                let j = j as f64;
                cj * (j
                    * (j - 1.0)
                    * ((j - 2.0) * p(j - 3.0) * co * co * co - 2.0 * p(j - 1.0) * co)
                    - j * j * p(j - 1.0) * co)
            })
            .sum()
    }

    /// The coefficients at `x` in f64 inches (`None` outside the table or
    /// in the null zone).
    fn coeffs_f64(g: &CommandGen, x: XInches) -> Option<(Coefficients, std::vec::Vec<f64>)> {
        let c = g.coefficients(x).ok().filter(|c| !c.null)?;
        let f = c.value[..usize::from(c.terms())]
            .iter()
            .map(|&v| f64::from(v) / f64::from(1u32 << 30))
            .collect();
        Some((c, f))
    }

    /// M₃ = max |∂³Z/∂φ³| over the default table (X every 1/64 in to the
    /// null zone, φ every 1/1024 turn), in/rad³, with 10 % margin for what
    /// the sampling misses between its points.
    fn m3_default() -> f64 {
        let g = gen();
        let mut m = 0f64;
        for k in 0..=(7.2 * 64.0) as i32 {
            let Some((_, c)) = coeffs_f64(&g, XInches::from_bits(k * (1 << 18))) else {
                continue;
            };
            for i in 0..1024 {
                m = m.max(third(&c, f64::from(i) * core::f64::consts::TAU / 1024.0).abs());
            }
        }
        1.1 * m
    }

    /// The module docs' M₃ of the default table, and the third derivative
    /// against a finite difference of the closed form's second.
    #[test]
    fn default_table_third_derivative_bound_is_the_documented_one() {
        let g = gen();
        let (_, c) = coeffs_f64(&g, XInches::from_bits(3 << 24)).unwrap();
        let h = 1e-4;
        let fd = (exact(&c, 0.7 + h)[2] - exact(&c, 0.7 - h)[2]) / (2.0 * h);
        assert!(
            (fd - third(&c, 0.7)).abs() <= 1e-6 * fd.abs().max(1e-6),
            "{fd}"
        );
        let m3 = m3_default();
        std::println!("M3 {m3}");
        assert!(m3 > 0.0 && m3 <= M3_DOC, "M3 {m3}");
    }

    /// At δ = 0 the expansion is the old direct path bit for bit: the code
    /// is `gauge_code_from_z` of the evaluated Z, the rates' factors the
    /// rounded products of the clamped derivatives.
    #[test]
    fn direct_expansion_code_is_gauge_code_from_z() {
        let g = gen();
        for k in 0..230u32 {
            let x = XInches::from_bits((k as i32) * (1 << 19));
            let Some((c, _)) = coeffs_f64(&g, x) else {
                continue;
            };
            for m in 0..64u32 {
                let phi = SpindleAngle(m.wrapping_mul(67_108_864 + 12_345));
                let e = Expansion::direct(&g, &c, phi);
                let cmd = g.evaluate_phi(&c, phi);
                assert_eq!(e.code(), gauge_code_from_z(cmd.z), "x {k} phi {m}");
                let d1 = cmd.dz_dphi.to_bits().clamp(-(1 << 27), 1 << 27);
                assert_eq!(e.p1, mul_hi(d1, FF_K));
                assert_eq!(e.step(phi), Some(e));
            }
        }
    }

    /// The Taylor step against the closed form at the stepped angle, over
    /// the default table, |δ| up to the limit: Z within the direct
    /// evaluation's own error at φ₀ plus M₃|δ|³/12 plus 0.02 codes of
    /// rounding; ∂Z/∂φ (as codes per tick at 1200 rpm, 20 kHz) within
    /// M₃δ²/2 plus 0.002 codes per tick; beyond the limit, no step.
    #[test]
    fn taylor_step_is_within_its_remainder_of_the_closed_form() {
        let g = gen();
        let m3 = m3_default();
        let dphi_1200 = 4_294_967_296.0 / 1000.0;
        let mut worst = [0f64; 2];
        let mut seen_z = 0f64;
        for k in (0..230u32).step_by(7) {
            let x = XInches::from_bits((k as i32) * (1 << 19) + 12_345);
            let Some((c, cf)) = coeffs_f64(&g, x) else {
                continue;
            };
            for m in 0..40u32 {
                let phi0 = SpindleAngle(m.wrapping_mul(107_374_183));
                let e = Expansion::direct(&g, &c, phi0);
                let z0_err = (f64::from(e.z_q8) / 256.0
                    - exact(&cf, f64::from(phi0.0) * RAD)[0] * CPI)
                    .abs();
                for d in [
                    1,
                    -1_000,
                    70_000,
                    -4_294_967,
                    8_589_934,
                    -12_000_000,
                    DELTA_LIMIT,
                    -DELTA_LIMIT,
                ] {
                    let phi = SpindleAngle(phi0.0.wrapping_add(d as u32));
                    let s = e.step(phi).unwrap();
                    let [z, d1, _] = exact(&cf, f64::from(phi.0) * RAD);
                    let h = f64::from(d).abs() * RAD;
                    let z_err = (f64::from(s.z_q8) / 256.0 - z * CPI).abs();
                    let z_bound = z0_err + m3 * h.powi(3) / 6.0 * CPI + 0.02;
                    assert!(z_err <= z_bound, "x {k} phi {m} d {d}: {z_err} > {z_bound}");
                    let v = f64::from(s.p1) * dphi_1200 / 4_294_967_296.0;
                    let v_exact = d1 * dphi_1200 * RAD * CPI;
                    let v_err = (v - v_exact).abs();
                    let v_bound = m3 * h * h / 2.0 * dphi_1200 * RAD * CPI + 0.002;
                    assert!(v_err <= v_bound, "x {k} phi {m} d {d}: {v_err} > {v_bound}");
                    worst = [worst[0].max(z_err - z0_err), worst[1].max(v_err)];
                    seen_z = seen_z.max((z * CPI).abs());
                }
                let beyond = SpindleAngle(phi0.0.wrapping_add(DELTA_LIMIT as u32 + 1));
                assert_eq!(e.step(beyond), None);
            }
        }
        assert!(seen_z > 1000.0, "a real command: {seen_z} codes");
        std::println!(
            "worst step error: Z {} codes, velocity {} codes/tick",
            worst[0],
            worst[1]
        );
    }
}
