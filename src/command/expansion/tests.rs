extern crate std;
use super::*;
use crate::codes::gauge_code_from_z;
use crate::table::CoeffTable;
use crate::units::XInches;
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
            cj * (j * (j - 1.0) * ((j - 2.0) * p(j - 3.0) * co * co * co - 2.0 * p(j - 1.0) * co)
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

/// M₁, M₂, M₃ = max |∂Z/∂φ|, |∂²Z/∂φ²|, |∂³Z/∂φ³| over the default
/// table (X every 1/64 in to the null zone, φ every 1/1024 turn), in/rad,
/// in/rad², in/rad³, each with 10 % margin for what the sampling misses
/// between its points.
fn bounds_default() -> [f64; 3] {
    let g = gen();
    let mut m = [0f64; 3];
    for k in 0..=(7.2 * 64.0) as i32 {
        let Some((_, c)) = coeffs_f64(&g, XInches::from_bits(k * (1 << 18))) else {
            continue;
        };
        for i in 0..1024 {
            let phi = f64::from(i) * core::f64::consts::TAU / 1024.0;
            let [_, d1, d2] = exact(&c, phi);
            for (m, d) in m.iter_mut().zip([d1, d2, third(&c, phi)]) {
                *m = m.max(d.abs());
            }
        }
    }
    m.map(|m| 1.1 * m)
}

/// The acceleration formed below the tick (at φ₀, for the predicted
/// step Δφ₀ and Δ²φ₀) against the closed form ∂²Z/∂φ²·Δφ² +
/// ∂Z/∂φ·Δ²φ at the angle, step and Δ²φ of the tick: within the
/// module docs' bound M₃|δ|Δφ₀² + M₂|Δφ² − Δφ₀²| + M₂|δ||Δ²φ₀| +
/// M₁|Δ²φ − Δ²φ₀| plus 0.002 codes per tick² of rounding, over the
/// default table, δ up to the limit, 300 to 1800 rpm, a spindle
/// slowing by 5 % in 0.1 s (Δ²φ) and a measured step off the predicted
/// one by a count of a 4096-line encoder.
#[test]
fn acceleration_from_below_is_within_its_bound_of_the_closed_form() {
    let g = gen();
    let [m1, m2, m3] = bounds_default();
    let mut worst = 0f64;
    let mut seen = 0f64;
    for k in (0..230u32).step_by(11) {
        let x = XInches::from_bits((k as i32) * (1 << 19) + 54_321);
        let Some((c, cf)) = coeffs_f64(&g, x) else {
            continue;
        };
        for m in 0..24u32 {
            let phi0 = SpindleAngle(m.wrapping_mul(178_956_971));
            for ticks_per_rev in [4000u32, 1000, 667] {
                let dphi0 = (4_294_967_296u64 / u64::from(ticks_per_rev)) as i32;
                // 5 % of the step in 2000 ticks, Q4.
                let alpha0 = -(dphi0 / 20 / 2000) * 16;
                let e = Expansion::direct(&g, &c, phi0, dphi0, alpha0);
                for (d, dd, da) in [
                    (0, 0, 0),
                    (dphi0, 0, 0),
                    (2 * dphi0, 1 << 20, 3),
                    (-dphi0 / 3, -(1 << 20), -40),
                    (DELTA_LIMIT, 1 << 20, 16),
                    (-DELTA_LIMIT, -(1 << 20), -16),
                ] {
                    let phi = SpindleAngle(phi0.0.wrapping_add(d as u32));
                    let Some(s) = e.step(phi) else { continue };
                    let (dphi, alpha) = (dphi0 + dd, alpha0 + da);
                    let [_, d1, d2] = exact(&cf, f64::from(phi.0) * RAD);
                    let (w, w0) = (f64::from(dphi) * RAD, f64::from(dphi0) * RAD);
                    let (al, al0) = (
                        f64::from(alpha) / 16.0 * RAD,
                        f64::from(alpha0) / 16.0 * RAD,
                    );
                    let a_exact = (d2 * w * w + d1 * al) * CPI;
                    let err = (f64::from(s.accel_q16) / 65_536.0 - a_exact).abs();
                    let h = f64::from(d).abs() * RAD;
                    let bound = (m3 * h * w0 * w0
                        + m2 * (w * w - w0 * w0).abs()
                        + m2 * h * al0.abs()
                        + m1 * (al - al0).abs())
                        * CPI
                        + 0.002;
                    assert!(err <= bound, "x {k} phi {m} d {d}: {err} > {bound}");
                    if dd == 0 && da == 0 {
                        worst = worst.max(err);
                    }
                    seen = seen.max(a_exact.abs());
                }
            }
        }
    }
    assert!(seen > 10.0, "a real acceleration: {seen} codes per tick²");
    std::println!("M1 {m1} M2 {m2}; worst at the predicted step: {worst} codes/tick² of {seen}");
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
    let [_, _, m3] = bounds_default();
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
            let e = Expansion::direct(&g, &c, phi, 1 << 22, 1000);
            let cmd = g.evaluate_phi(&c, phi);
            assert_eq!(e.code(), gauge_code_from_z(cmd.z), "x {k} phi {m}");
            let d1 = cmd.dz_dphi.to_bits().clamp(-(1 << 27), 1 << 27);
            assert_eq!(e.p1, mul_hi(d1, FF_K));
            let d2 = cmd.d2z_dphi2.to_bits().clamp(-(1 << 28), 1 << 28);
            assert_eq!(e.p2, mul_hi(d2, FF_K2));
            assert_eq!(e.accel_q16, acceleration(e.p1, e.p2, 1 << 22, 1000));
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
    let [_, _, m3] = bounds_default();
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
            let e = Expansion::direct(&g, &c, phi0, 0, 0);
            let z0_err =
                (f64::from(e.z_q8) / 256.0 - exact(&cf, f64::from(phi0.0) * RAD)[0] * CPI).abs();
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
