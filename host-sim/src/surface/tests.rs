use super::*;
use std::f64::consts::PI;

/// Independent route to Y_t, from eq 2-1..2-3 directly: the point
/// (x3, y3, z3) of the rotated frame lies on x1² + y1² = c z1; solve the
/// quadratic in z3 for the root near the sector (stable form).
fn yt_from_paraboloid(c: f64, s_y: f64, x: f64, phi: f64) -> f64 {
    let th = (2.0 * s_y / c).atan();
    let (st, ct) = th.sin_cos();
    let (x3, y3) = (x * phi.cos(), x * phi.sin());
    let s_z = s_y * s_y / c;
    // y1 = y3 cosθ − z3 sinθ + S_y, z1 = y3 sinθ + z3 cosθ + S_z.
    let p = y3 * ct + s_y;
    let qa = st * st;
    let qb = -(2.0 * st * p + c * ct);
    let qc = x3 * x3 + p * p - c * (y3 * st + s_z);
    // Small root: 2 qc / (−qb + √(qb² − 4 qa qc)).
    2.0 * qc / (-qb + (qb * qb - 4.0 * qa * qc).sqrt())
}

#[test]
fn yt_agrees_with_the_paraboloid_itself() {
    let s = Surface::dissertation();
    for &x in &[0.0, 0.3, 1.0, 4.0, 7.25, 8.0] {
        for i in 0..36 {
            let phi = i as f64 * PI / 18.0;
            let (sp, cp) = phi.sin_cos();
            let a = s.yt_sc(x, sp, cp * cp);
            let b = yt_from_paraboloid(316.7, 28.0, x, phi);
            // The quadratic route rounds at ~1e-14 of its ~30 in terms.
            assert!((a - b).abs() < 1e-12, "x={x} phi={phi}: {a} vs {b}");
        }
    }
}

#[test]
fn forex4_fun_form_agrees_away_from_its_rounding() {
    // FOREX4's FUN with its A, A1, A2, A3 literally (loses ~1e-12 in).
    let (c, sy) = (316.7f64, 28.0f64);
    let sth = 2.0 * sy / (c * c + 4.0 * sy * sy).sqrt();
    let cth = c / (c * c + 4.0 * sy * sy).sqrt();
    let a = c / (2.0 * cth * sth * sth);
    let a1 = 2.0 * cth / (a * sth);
    let a2 = 2.0 * cth / (a * c);
    let a3 = c / (2.0 * sy);
    let s = Surface::dissertation();
    for &x1 in &[0.5, 3.0, 8.0] {
        let y = (c / (2.0 * cth)) * (1.0 - (1.0 - (x1 * sth / sy).powi(2)).sqrt());
        for i in 0..24 {
            let phi = i as f64 * PI / 12.0;
            let sph = phi.sin();
            let fun = a
                * (1.0 - (1.0 + a1 * x1 * sph + a2 * x1 * x1 * sph * sph - a2 * x1 * x1).sqrt())
                + a3 * x1 * sph
                - y;
            assert!((fun - s.z_contact(x1, phi)).abs() < 1e-10);
        }
    }
}

#[test]
fn corrected_ridge_is_the_maximum_and_zero_at_the_axis() {
    let s = Surface::dissertation();
    assert_eq!(s.z(0.0, 1.0).unwrap(), 0.0);
    for &x in &[0.1, 1.0, 4.0, 8.0] {
        let sec = s.section(x).unwrap();
        // Max over φ by dense sampling, refined with golden section near
        // the best sample, must be 0 (the corrected eq 2-14), never > 0.
        let n = 4096;
        let (mut best, mut at) = (f64::MIN, 0.0);
        for i in 0..n {
            let phi = 2.0 * PI * i as f64 / n as f64;
            let z = sec.z(phi);
            assert!(z <= 1e-16, "Z > 0 at x={x} phi={phi}: {z}");
            if z > best {
                best = z;
                at = phi;
            }
        }
        let h = 2.0 * PI / n as f64;
        let (mut lo, mut hi) = (at - h, at + h);
        for _ in 0..100 {
            let m1 = lo + 0.381966 * (hi - lo);
            let m2 = hi - 0.381966 * (hi - lo);
            if sec.z(m1) < sec.z(m2) {
                lo = m1
            } else {
                hi = m2
            }
        }
        let zmax = sec.z(0.5 * (lo + hi));
        assert!(zmax.abs() < 1e-15, "max Z at x={x} is {zmax}");
        // ... and sits at the eq 2-11 angle.
        let sm = s.sin_phi_max(sec.x1);
        assert!(sec.z(sm.asin()).abs() < 1e-16);
    }
}

#[test]
fn iteration_converges_to_the_closed_form() {
    let s = Surface::dissertation();
    for &x in &[0.0, 0.1, 2.5, 7.2, 8.0, 20.0] {
        let (x1, passes) = s.contact_radius(x).unwrap();
        let closed = x * s.r0() / (s.r0() - 0.125);
        assert!((x1 - closed).abs() <= 4.0 * f64::EPSILON * closed.max(1.0));
        assert!(passes <= 8, "{passes} passes at x={x}");
        // Tool centre of the contact point is back at x.
        let alpha = (x1 / (s.r0() - s.ridge(x1))).atan();
        assert!((x1 - 0.125 * alpha.sin() - x).abs() < 1e-14);
    }
}

#[test]
fn small_x_closed_form() {
    // Leading order of eq 2-15: Z ≈ −x² sin²φ sin³θ/(2 S_y).
    let s = Surface::dissertation().with_tool_radius(0.0).unwrap();
    let k = s.sin_theta().powi(3) / (2.0 * 28.0);
    for &x in &[1e-3, 1e-2] {
        for i in 0..12 {
            let phi = i as f64 * PI / 6.0 + 0.1;
            let z = s.z(x, phi).unwrap();
            let lead = -x * x * phi.sin().powi(2) * k;
            assert!((z - lead).abs() < 1e-3 * x * x * k, "x={x}");
        }
    }
}

#[test]
fn derivatives_match_finite_differences() {
    // Both compensation models: FOREX4's ridge normal and the exact
    // profile normal.
    for s in [
        Surface::dissertation(),
        Surface::dissertation().with_compensation(Compensation::ProfileNormal),
    ] {
        for &x in &[0.5, 3.0, 7.2] {
            let sec = s.section(x).unwrap();
            for i in 0..16 {
                let phi = i as f64 * PI / 8.0 + 0.05;
                let h = 1e-4;
                let fd = (sec.z(phi + h) - sec.z(phi - h)) / (2.0 * h);
                assert!((fd - sec.dz_dphi(phi)).abs() < 1e-10);
                let fdx = (s.z(x + h, phi).unwrap() - s.z(x - h, phi).unwrap()) / (2.0 * h);
                assert!(
                    (fdx - sec.dz_dx(phi)).abs() < 1e-10,
                    "{fdx} vs {}",
                    sec.dz_dx(phi)
                );
            }
        }
    }
}

#[test]
fn profile_normal_compensation_differs_by_second_order() {
    // Profile-normal vs ridge-normal (FOREX4) compensation: the
    // difference must be the second-order r_t·ε²/2, ε = β − α the angle
    // between the normals (β of the profile at x1, α of the ridge).
    let f4 = Surface::dissertation();
    let pn = f4.with_compensation(Compensation::ProfileNormal);
    for &x in &[1.0, 4.0, 7.2, 8.0] {
        let (a, b) = (f4.section(x).unwrap(), pn.section(x).unwrap());
        let alpha = (a.x1 / f4.r0()).asin();
        let mut worst = 0.0f64;
        for i in 0..360 {
            let phi = (i as f64).to_radians();
            let (sp, cp) = phi.sin_cos();
            let d = b.z(phi) - a.z(phi);
            let eps = f4.slope_sc(a.x1, sp, cp * cp).atan() - alpha;
            let est = 0.125 * eps * eps / 2.0;
            assert!(
                (d - est).abs() < 0.05 * est + 1e-13,
                "x={x} phi={i}: {d} vs {est}"
            );
            worst = worst.max(d.abs());
            assert!(
                (b.z_of_sin(sp) - b.z(phi)).abs() < 1e-15,
                "{}",
                b.z_of_sin(sp) - b.z(phi)
            );
        }
        eprintln!(
            "X = {x} in: profile-normal vs FOREX4 compensation max {:.4} µin",
            worst * 1e6
        );
    }
    // r_t = 0: identical.
    let s0 = pn.with_tool_radius(0.0).unwrap().section(5.0).unwrap();
    let f0 = f4.with_tool_radius(0.0).unwrap().section(5.0).unwrap();
    assert_eq!(s0.z(1.0), f0.z(1.0));
}

#[test]
fn invalid_geometry_names_the_field() {
    for (c, sy, rt, field) in [
        (0.0, 28.0, 0.1, "surface.c_in"),
        (-1.0, 28.0, 0.1, "surface.c_in"),
        (f64::NAN, 28.0, 0.1, "surface.c_in"),
        (316.7, 0.0, 0.1, "surface.s_y_in"),
        (316.7, f64::INFINITY, 0.1, "surface.s_y_in"),
        (316.7, 28.0, -0.1, "surface.tool_radius_in"),
        (316.7, 28.0, f64::NAN, "surface.tool_radius_in"),
        (316.7, 28.0, 50.0, "surface.tool_radius_in"),
    ] {
        let e = Surface::new(c, sy, rt).unwrap_err();
        assert!(e.to_string().starts_with(field), "{e}");
    }
    let s = Surface::dissertation();
    assert!(s.x_limit() > 50.0 && s.x_limit() < 60.0, "{}", s.x_limit());
    let e = s.z(s.x_limit() + 0.01, 0.0).unwrap_err();
    assert!(matches!(e, SurfaceError::XOutOfDomain { .. }));
    assert!(s.z(-0.1, 0.0).is_err());
    assert!(s.z(f64::NAN, 0.0).is_err());
    // At the limit the maximum of eq 2-11 sits at φ = −90°.
    let x1 = s.contact_radius(s.x_limit()).unwrap().0;
    assert!((s.sin_phi_max(x1) + 1.0).abs() < 1e-9);
}
