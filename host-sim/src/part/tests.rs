//! Each surface kind against an independent closed form, the split's
//! compensation against exact offsets, and a part table through the
//! firmware's own command path.

use super::biconic::{Biconic, Toric};
use super::conic::OffAxisConic;
use super::saggrid::SagGrid;
use super::sinusoid::SinusoidalGrid;
use super::split::{Compensation, Part, Tool};
use super::table::{generate, PartTableSpec};
use super::xypoly::XyPolynomial;
use super::zernike::{fringe, noll, Ordering, Zernike};
use super::Sag;
use std::f64::consts::{PI, TAU};
use std::sync::Arc;

fn part(sag: impl Sag + 'static, r_t: f64, comp: Compensation) -> Part {
    Part {
        sag: Arc::new(sag),
        tool: Tool {
            nose_radius: r_t,
            clearance_deg: 7.0,
            compensation: comp,
        },
    }
}

/// The gradient of every kind against central differences of its sag.
fn check_gradient(s: &dyn Sag, pts: &[(f64, f64)], tol: f64) {
    let h = 1e-5;
    for &(x, y) in pts {
        let (gx, gy) = s.grad(x, y);
        let fx = (s.sag(x + h, y) - s.sag(x - h, y)) / (2.0 * h);
        let fy = (s.sag(x, y + h) - s.sag(x, y - h)) / (2.0 * h);
        assert!(
            (gx - fx).abs() < tol && (gy - fy).abs() < tol,
            "{}: at ({x}, {y}) grad ({gx}, {gy}) vs differences ({fx}, {fy})",
            s.describe()
        );
    }
}

const PTS: [(f64, f64); 6] = [
    (0.3, 0.2),
    (-1.1, 0.7),
    (1.9, -1.3),
    (0.0, 1.5),
    (2.2, 0.0),
    (-0.4, -2.0),
];

#[test]
fn sphere_on_the_turning_axis_is_exact_and_has_no_z_motion() {
    // An off-axis sector of a sphere (k = 0) tilted the dissertation's way
    // has the turning axis through the sphere's centre: the part is a
    // sphere of revolution, the tool centre a sphere of radius R − r_t.
    let (r, rt) = (50.0, 0.125);
    let s = OffAxisConic::new(r, 0.0, 10.0, None).unwrap();
    for &(x, y) in &PTS {
        let exact = r - (r * r - x * x - y * y).sqrt();
        assert!(
            (s.sag(x, y) - exact).abs() < 1e-13,
            "{} vs {exact}",
            s.sag(x, y)
        );
    }
    check_gradient(&s, &PTS, 1e-8);
    for comp in [Compensation::ProfileNormal, Compensation::Forex4] {
        let p = part(s, rt, comp);
        for &x in &[0.0, 0.5, 2.0, 4.0] {
            let sec = p.section(x).unwrap();
            // The tool centre is on the sphere of radius R − r_t about the
            // centre (0, 0, R); its lowest point is r_t above the vertex.
            let y = r - ((r - rt) * (r - rt) - x * x).sqrt();
            assert!(
                (sec.y - y).abs() < 1e-12,
                "{comp:?} X={x}: {} vs {y}",
                sec.y
            );
            for j in 0..16 {
                let z = sec.z(&p, j as f64 * 0.41).unwrap();
                assert!(z.abs() < 1e-12, "{comp:?} X={x}: Z = {z}");
            }
        }
    }
}

#[test]
fn off_centre_sphere_tool_centre_is_the_offset_circle_of_each_meridional_section() {
    // Tilt 0: the sphere's centre is off the turning axis. Each meridional
    // plane cuts the sphere in a circle; the nose offsets it to the
    // concentric circle of radius ρ − r_t: T(X, φ) in closed form.
    let (r, sy, rt) = (40.0, 6.0, 0.1);
    let s = OffAxisConic::new(r, 0.0, sy, Some(0.0)).unwrap();
    let sz = r - (r * r - sy * sy).sqrt();
    for &(x, y) in &PTS {
        let exact = r - (r * r - x * x - (y + sy).powi(2)).sqrt() - sz;
        assert!((s.sag(x, y) - exact).abs() < 1e-12);
    }
    let p = part(s, rt, Compensation::ProfileNormal);
    for &x in &[0.2, 1.0, 3.0] {
        let sec = p.section(x).unwrap();
        let mut zmax = f64::MIN;
        for j in 0..64 {
            let phi = TAU * j as f64 / 64.0 + 0.01;
            // Centre (0, −S_y, R − S_z): in the plane at φ its projection
            // is at radius a = −S_y sin φ, distance d = S_y cos φ from it.
            let a = -sy * phi.sin();
            let d = sy * phi.cos();
            let rho = (r * r - d * d).sqrt();
            let t = (r - sz) - ((rho - rt).powi(2) - (x - a).powi(2)).sqrt();
            let got = sec.t(&p, phi).unwrap();
            assert!((got - t).abs() < 1e-12, "X={x} φ={phi}: {got} vs {t}");
            zmax = zmax.max(sec.z(&p, phi).unwrap());
        }
        assert!(zmax <= 1e-15, "Z > 0: {zmax}");
    }
}

/// The dissertation's paraboloid as an off-axis conic: R = c/2, k = −1.
fn dissertation_conic(comp: Compensation) -> Part {
    let s = OffAxisConic::new(316.7 / 2.0, -1.0, 28.0, None).unwrap();
    part(s, 0.125, comp)
}

#[test]
fn paraboloid_off_axis_conic_is_eq_2_15_and_the_default_table() {
    let p = dissertation_conic(Compensation::Forex4);
    let reference = crate::surface::Surface::dissertation();
    let t = zslide::table::CoeffTable::parse(zslide::DEFAULT_TABLE).unwrap();
    let h = t.header();
    let scale = f64::from(h.coeff_frac_bits).exp2();
    let xs = f64::from(h.x_frac_bits).exp2();
    let (x0, dx) = (f64::from(h.x0_raw) / xs, f64::from(h.dx_raw) / xs);
    let mut worst_table = 0.0f64;
    for &x in &[0.0, 0.7, 2.3, 4.05, 5.5, 7.2] {
        let sec = p.section(x).unwrap();
        let u = (x - x0) / dx;
        let i = (u.floor() as u32).min(h.node_count - 2);
        let f = u - f64::from(i);
        for j in 0..72 {
            let phi = TAU * j as f64 / 72.0 + 0.003;
            let z = sec.z(&p, phi).unwrap();
            let e = reference.z(x, phi).unwrap();
            assert!((z - e).abs() < 1e-11, "X={x} φ={phi}: {z} vs eq 2-15 {e}");
            // The default table (sin-power, interpolated) in f64.
            let s = phi.sin();
            let tz = (0..h.terms).rev().fold(0.0, |acc, c| {
                let a = f64::from(t.coeff_raw(i, c)) / scale;
                let b = f64::from(t.coeff_raw(i + 1, c)) / scale;
                acc * s + a + (b - a) * f
            });
            worst_table = worst_table.max((z - tz).abs() * 1e6);
        }
    }
    // tables/default.toml: picked for 0.07 µin less 0.01 for the firmware.
    assert!(
        worst_table <= 0.06,
        "{worst_table} µin from the default table"
    );
    // The header names the paraboloid.
    let spec = PartTableSpec {
        x_min: 0.0,
        x_max: 8.0,
        step: 0.25,
        x_null: 7.2,
        harmonics: 6,
        coeff_frac_bits: 30,
        x_frac_bits: 24,
    };
    let g = generate(&p, &spec).unwrap().header.geometry;
    assert_eq!(
        (g.c_nin, g.s_y_nin, g.tool_radius_nin),
        (316_700_000_000, 28_000_000_000, 125_000_000)
    );
}

#[test]
fn profile_normal_paraboloid_matches_the_surface_modules_envelope() {
    let p = dissertation_conic(Compensation::ProfileNormal);
    let reference =
        crate::surface::Surface::dissertation().with_compensation(Compensation::ProfileNormal);
    for &x in &[1.0, 4.0, 7.2] {
        let sec = p.section(x).unwrap();
        for j in 0..36 {
            let phi = TAU * j as f64 / 36.0 + 0.01;
            let (z, e) = (sec.z(&p, phi).unwrap(), reference.z(x, phi).unwrap());
            // The surface module's Y is FOREX4's ridge; this split's is the
            // maximum of the offset profile: compare the φ-variation.
            let z0 = sec.z(&p, 0.01).unwrap() - reference.z(x, 0.01).unwrap();
            assert!(
                (z - e - z0).abs() < 1e-11,
                "X={x} φ={phi}: {z} vs {e} (+{z0})"
            );
        }
    }
}

/// Bessel J_n by its integral `J_n(x) = (1/π) ∫_0^π cos(nτ − x sin τ) dτ`
/// (trapezoid on a periodic integrand: exponentially convergent).
fn bessel_j(n: i32, x: f64) -> f64 {
    let m = 2000;
    let mut s = 0.0;
    for i in 0..m {
        let tau = TAU * i as f64 / m as f64;
        s += (f64::from(n) * tau - x * tau.sin()).cos();
    }
    s / m as f64
}

#[test]
fn sinusoidal_grid_harmonics_are_bessel_coefficients() {
    // z = A sin(aX cos φ) sin(bX sin φ) with Jacobi–Anger:
    // sin(u cos φ) = 2 Σ (−1)^m J_{2m+1}(u) cos (2m+1)φ,
    // sin(v sin φ) = 2 Σ J_{2m+1}(v) sin (2m+1)φ; cos pφ sin qφ =
    // ½ [sin (q+p)φ + sin (q−p)φ].
    let (amp, px, py) = (2e-4, 3.0, 5.0);
    let p = part(
        SinusoidalGrid::new(amp, px, py).unwrap(),
        0.0,
        Compensation::ProfileNormal,
    );
    // Independent check of the quadrature Bessel against libm's.
    assert!((bessel_j(3, 2.5) - libm::jn(3, 2.5)).abs() < 1e-14);
    for &x in &[0.5, 1.5, 2.5] {
        let (u, v) = (TAU * x / px, TAU * x / py);
        let mut s_k = vec![0.0; 60];
        for p_ in (1..30).step_by(2) {
            let alpha = 2.0 * if (p_ / 2) % 2 == 0 { 1.0 } else { -1.0 } * bessel_j(p_, u);
            for q in (1..30).step_by(2) {
                let w = 0.5 * amp * alpha * 2.0 * bessel_j(q, v);
                s_k[(q + p_) as usize] += w;
                match q.cmp(&p_) {
                    std::cmp::Ordering::Greater => s_k[(q - p_) as usize] += w,
                    std::cmp::Ordering::Less => s_k[(p_ - q) as usize] -= w,
                    std::cmp::Ordering::Equal => {}
                }
            }
        }
        let h = p.section(x).unwrap().harmonics(15);
        for (k, bessel) in s_k.iter().enumerate().take(16).skip(1) {
            assert!(h.c[k].abs() < 1e-15, "X={x} C{k} = {}", h.c[k]);
            assert!(
                (h.s[k] - bessel).abs() < 1e-15,
                "X={x} S{k}: {} vs Bessel {bessel}",
                h.s[k]
            );
        }
    }
}

#[test]
fn zernike_terms_at_known_points_in_both_orderings() {
    // Index maps (Noll 1976; Fringe): (n, m, cos).
    assert_eq!(noll(4), (2, 0, true));
    assert_eq!(noll(5), (2, 2, false));
    assert_eq!(noll(6), (2, 2, true));
    assert_eq!(noll(8), (3, 1, true));
    assert_eq!(noll(11), (4, 0, true));
    assert_eq!(noll(14), (4, 4, true));
    assert_eq!(fringe(4), (2, 0, true));
    assert_eq!(fringe(7), (3, 1, true));
    assert_eq!(fringe(9), (4, 0, true));
    assert_eq!(fringe(10), (3, 3, true));
    assert_eq!(fringe(16), (6, 0, true));
    assert_eq!(fringe(36), (10, 0, true));
    assert_eq!(fringe(37), (12, 0, true));
    let rn = 2.0;
    let one = |ord: Ordering, j: usize| {
        let mut c = vec![0.0; j];
        c[j - 1] = 1.0;
        Zernike::new(ord, rn, None, &c).unwrap()
    };
    for &(x, y) in &[(0.6, 0.8), (-1.2, 0.5), (0.3, -1.9), (1.0, 0.0)] {
        let rho = f64::hypot(x, y) / rn;
        let th = f64::atan2(y, x);
        let cases: [(Ordering, usize, f64); 7] = [
            (Ordering::Standard, 4, 3f64.sqrt() * (2.0 * rho * rho - 1.0)),
            (
                Ordering::Standard,
                6,
                6f64.sqrt() * rho * rho * (2.0 * th).cos(),
            ),
            (
                Ordering::Standard,
                8,
                8f64.sqrt() * (3.0 * rho.powi(3) - 2.0 * rho) * th.cos(),
            ),
            (
                Ordering::Standard,
                11,
                5f64.sqrt() * (6.0 * rho.powi(4) - 6.0 * rho * rho + 1.0),
            ),
            (Ordering::Fringe, 6, rho * rho * (2.0 * th).sin()),
            (
                Ordering::Fringe,
                9,
                6.0 * rho.powi(4) - 6.0 * rho * rho + 1.0,
            ),
            (Ordering::Fringe, 10, rho.powi(3) * (3.0 * th).cos()),
        ];
        for (ord, j, expect) in cases {
            let z = one(ord, j);
            assert!(
                (z.sag(x, y) - expect).abs() < 1e-13,
                "{ord:?} Z{j} at ({x}, {y}): {} vs {expect}",
                z.sag(x, y)
            );
            check_gradient(&z, &[(x, y)], 1e-7);
        }
    }
    // Unit RMS over the disc (Noll's normalisation): Z8 by quadrature.
    let z8 = one(Ordering::Standard, 8);
    let (mut s, mut a) = (0.0, 0.0);
    for i in 0..200 {
        let r = (i as f64 + 0.5) / 200.0;
        for j in 0..64 {
            let t = TAU * j as f64 / 64.0;
            let v = z8.sag(rn * r * t.cos(), rn * r * t.sin());
            s += v * v * r;
            a += r;
        }
    }
    assert!(((s / a).sqrt() - 1.0).abs() < 1e-4, "{}", (s / a).sqrt());
}

#[test]
fn sag_grid_of_a_known_function_interpolates_within_its_order() {
    // A quadratic is reproduced exactly by Catmull–Rom; a sinusoid to
    // O(h³): |err| ≤ (kh)³·A/8 at most (measured below it).
    let quad = |x: f64, y: f64| 1e-3 * (x * x + 0.5 * x * y - y * y) + 2e-4 * x;
    let (amp, k) = (1e-4, TAU / 3.0);
    let wave = |x: f64, y: f64| amp * (k * x).sin() * (k * y).cos();
    let h = 0.1;
    let grid = |f: &dyn Fn(f64, f64) -> f64| {
        let mut pts = Vec::new();
        for i in 0..=40 {
            for j in 0..=40 {
                let (x, y) = (-2.0 + h * i as f64, -2.0 + h * j as f64);
                pts.push((x, y, f(x, y)));
            }
        }
        SagGrid::from_points(&pts, "test").unwrap()
    };
    let gq = grid(&quad);
    let gw = grid(&wave);
    let mut worst = 0.0f64;
    for i in 0..97 {
        for j in 0..89 {
            let (x, y) = (
                -1.99 + 3.98 * i as f64 / 96.0,
                -1.99 + 3.98 * j as f64 / 88.0,
            );
            assert!(
                (gq.sag(x, y) - quad(x, y)).abs() < 1e-15,
                "quadratic at ({x}, {y})"
            );
            worst = worst.max((gw.sag(x, y) - wave(x, y)).abs());
        }
    }
    let bound = (k * h).powi(3) * amp / 8.0;
    assert!(worst < bound, "sinusoid: {worst:e} vs {bound:e}");
    check_gradient(&gw, &[(0.33, -0.71), (1.234, 1.5)], 1e-8);
    // Outside the grid: undefined, and the split names the point.
    assert!(gw.sag(2.05, 0.0).is_nan());
    let p = part(gw, 0.0, Compensation::ProfileNormal);
    let e = p.section(2.5).unwrap_err();
    assert!(e.contains("not defined at radius 2.5"), "{e}");
    // A file that is not a grid is refused by name.
    let e = SagGrid::from_points(&[(0.0, 0.0, 0.0); 16], "bad.csv").unwrap_err();
    assert!(e.starts_with("bad.csv: 1 × 1"), "{e}");
}

#[test]
fn toric_and_biconic_sections_are_their_circles() {
    let (rx, ry) = (50.0, 40.0);
    let t = Toric::new(rx, ry).unwrap();
    let b = Biconic::new(rx, ry, 0.0, 0.0).unwrap();
    for &v in &[0.0, 0.5, 1.7, -2.2] {
        let circ = |r: f64| r - (r * r - v * v).sqrt();
        // Along x at y = 0 and along y at x = 0: circles of Rx and Ry.
        assert!((t.sag(v, 0.0) - circ(rx)).abs() < 1e-14);
        assert!((t.sag(0.0, v) - circ(ry)).abs() < 1e-14);
        assert!((b.sag(v, 0.0) - circ(rx)).abs() < 1e-14);
        assert!((b.sag(0.0, v) - circ(ry)).abs() < 1e-14);
    }
    // The torus: the section along x at y is a circle of radius Rx − f(y)
    // about z = Rx.
    let (x, y) = (1.3, 0.9);
    let f = ry - (ry * ry - y * y).sqrt();
    let z = rx - ((rx - f).powi(2) - x * x).sqrt();
    assert!((t.sag(x, y) - z).abs() < 1e-14);
    check_gradient(&t, &PTS, 1e-8);
    check_gradient(&b, &PTS, 1e-8);
    let bk = Biconic::new(30.0, -45.0, -0.5, 2.0).unwrap();
    check_gradient(&bk, &PTS, 1e-8);
    // A toric on the axis moves the Z slide twice a revolution, amplitude
    // X²/4 (1/Rx − 1/Ry) to second order (the next order is X²/R² ≈ 6e-4
    // of it).
    let p = part(t, 0.0, Compensation::ProfileNormal);
    let h = p.section(1.0).unwrap().harmonics(4);
    let expect = 0.25 * (1.0 / rx - 1.0 / ry);
    assert!(
        (h.c[2] - expect).abs() < 2e-3 * expect.abs(),
        "{} vs {expect}",
        h.c[2]
    );
}

#[test]
fn xy_polynomial_at_known_points() {
    let p = XyPolynomial::new(vec![(2, 0, 1e-3), (1, 1, -2e-4), (0, 3, 5e-5)]).unwrap();
    for &(x, y) in &PTS {
        let e = 1e-3 * x * x - 2e-4 * x * y + 5e-5 * y.powi(3);
        assert!((p.sag(x, y) - e).abs() < 1e-17);
    }
    check_gradient(&p, &PTS, 1e-9);
    assert!(XyPolynomial::new(vec![(1, 1, 1.0), (1, 1, 2.0)])
        .unwrap_err()
        .contains("given twice"));
}

#[test]
fn every_kind_gives_its_gradient() {
    check_gradient(
        &OffAxisConic::new(100.0, -0.6, 12.0, None).unwrap(),
        &PTS,
        1e-8,
    );
    check_gradient(
        &OffAxisConic::new(80.0, 0.4, 9.0, Some(0.05)).unwrap(),
        &PTS,
        1e-8,
    );
    check_gradient(&SinusoidalGrid::new(3e-4, 2.0, 3.0).unwrap(), &PTS, 1e-8);
    check_gradient(
        &Zernike::new(
            Ordering::Fringe,
            2.5,
            Some(60.0),
            &[0.0, 1e-4, -2e-4, 3e-4, 0.0, 5e-5, 1e-5, 0.0, 2e-5],
        )
        .unwrap(),
        &PTS,
        1e-8,
    );
}

#[test]
fn a_sharp_tool_cuts_the_surface_itself() {
    let s = SinusoidalGrid::new(2e-4, 4.0, 4.0).unwrap();
    let p = part(s, 0.0, Compensation::ProfileNormal);
    let sec = p.section(1.3).unwrap();
    for j in 0..32 {
        let phi = PI * j as f64 / 16.0;
        let t = sec.t(&p, phi).unwrap();
        assert!((t - s.sag(1.3 * phi.cos(), 1.3 * phi.sin())).abs() < 1e-18);
    }
}

/// The committed example tables through the firmware's own command path
/// (`zcmd`'s `z_at`: `zslide::command`, fixed point, bit-exact with the
/// target) at seeded random points: within each part's stated bound of
/// the exact command.
#[test]
fn example_tables_command_within_their_stated_bound_at_random_points() {
    use rand::{Rng, SeedableRng};
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tables");
    for name in ["toric-lens", "zernike-freeform", "sinusoidal-grid"] {
        let lp = super::config::load_part(&dir.join(format!("{name}.toml"))).unwrap();
        let image = std::fs::read(dir.join(format!("{name}.zsct"))).unwrap();
        let t = zslide::table::CoeffTable::parse(&image).unwrap();
        assert!(super::header_is_not_a_paraboloid(&t.header().geometry));
        let gen = zslide::command::CommandGen::new(t);
        let x_hi = t.x_null().to_f64();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(23);
        let mut worst = 0.0f64;
        for _ in 0..300 {
            let x = rng.random_range(0.0..x_hi);
            let deg = rng.random_range(0.0..360.0);
            let z = crate::cmd::zcmd::z_at(&gen, x, deg).unwrap();
            // The firmware's angle is not the part's (`part_angle`).
            let exact = lp.part.z(x, super::part_angle(deg.to_radians())).unwrap();
            worst = worst.max((z - exact).abs() * 1e6);
        }
        assert!(
            worst <= lp.bound_uin,
            "{name}: {worst} µin from the exact command, stated bound {} µin",
            lp.bound_uin
        );
        eprintln!(
            "{name}: firmware command within {worst:.4} µin (bound {})",
            lp.bound_uin
        );
    }
}

#[test]
fn a_bound_no_table_can_meet_is_refused_with_the_reason() {
    // A sinusoidal grid of 0.5 in periods out to 2 in: 2πX/period = 25,
    // harmonics far beyond the format's 15.
    let lp = super::config::PartFile::from_toml(
        "[surface]\nkind = \"sinusoidal-grid\"\namplitude_in = 0.0001\nperiod_x_in = 0.5\nperiod_y_in = 0.5\n\
         [tool]\nnose_radius_in = 0.0\nclearance_deg = 7.0\n[table]\nx_max_in = 2.0\nbound_uin = 0.5\n",
    )
    .unwrap()
    .load("fine", std::path::Path::new("."))
    .unwrap();
    let spec = PartTableSpec {
        step: 0.25,
        ..lp.table.clone()
    };
    let why = super::table::pick(
        &lp.part,
        &spec,
        &[0.25],
        lp.bound_uin,
        lp.allowance_uin,
        0.0,
        2.0,
        crate::coeffgen::Sampling {
            per_interval: 2,
            phi: 180,
        },
    )
    .unwrap_err();
    assert!(
        why.contains("no table within the format") && why.contains("truncation alone is"),
        "{why}"
    );
}

#[test]
fn part_file_errors_name_the_field() {
    let load = |t: &str| {
        super::config::PartFile::from_toml(t)
            .and_then(|f| f.load("p", std::path::Path::new(".")).map(|_| ()))
            .unwrap_err()
    };
    let tool = "[tool]\nnose_radius_in = 0.1\nclearance_deg = 7.0\n[table]\nx_max_in = 2.0\nbound_uin = 0.5\n";
    for (surface, expect) in [
        ("kind = \"sinusoidal-grid\"\namplitude_in = 1e-4\nperiod_x_in = 0.0\nperiod_y_in = 1.0", "surface.period_x_in = 0"),
        ("kind = \"sinusoidal-grid\"\namplitude_in = 1e-4\nperiod_x = 1.0\nperiod_y_in = 1.0", "unknown field `period_x`"),
        ("kind = \"toric\"\nradius_x_in = -5.0\nradius_y_in = 40.0", "surface.radius_x_in = -5"),
        ("kind = \"zernike\"\nordering = \"fringe\"\nnormalization_radius_in = 0.0\ncoefficients_in = [0.0]", "surface.normalization_radius_in = 0"),
        ("kind = \"off-axis-conic\"\nconic_constant = -1.0\noff_axis_in = 5.0", "exactly one of vertex_radius_in"),
        ("kind = \"helix\"", "unknown variant `helix`"),
    ] {
        let e = load(&format!("[surface]\n{surface}\n{tool}"));
        assert!(e.contains(expect), "{surface:?}: {e}");
    }
    let e = load("[surface]\nkind = \"toric\"\nradius_x_in = 50.0\nradius_y_in = 40.0\n[tool]\nnose_radius_in = -0.1\nclearance_deg = 7.0\n[table]\nx_max_in = 2.0\nbound_uin = 0.5\n");
    assert!(e.starts_with("tool.nose_radius_in = -0.1"), "{e}");
}

mod plan_checks {
    use super::super::config::PartFile;
    use super::super::plan::{plan, sections, Machine};
    use nalgebra::Complex;

    fn plan_of(toml: &str) -> super::super::plan::Plan {
        let lp = PartFile::from_toml(toml)
            .unwrap()
            .load("p", std::path::Path::new("."))
            .unwrap();
        let sc = crate::scenario::load("modern-hw").unwrap();
        let s = sections(&lp, 9).unwrap();
        // A first-order sensitivity stands in for the measured one: these
        // checks do not depend on it.
        plan(&lp, &s, &Machine::of(&sc), 300.0, &|f| {
            Complex::new(0.0, f) / Complex::new(80.0, f)
        })
    }

    fn failed(p: &super::super::plan::Plan) -> Vec<String> {
        p.checks
            .iter()
            .filter(|c| !c.ok)
            .map(|c| c.name.clone())
            .collect()
    }

    #[test]
    fn plan_refuses_a_stroke_beyond_the_slide_range() {
        // Toric, Rx 20 in × Ry 40 in to 2 in: X²/2·(1/Rx − 1/Ry) = 0.05 in
        // of Z stroke, against the ±0.0095 in command range.
        let p = plan_of(
            "[surface]\nkind = \"toric\"\nradius_x_in = 20.0\nradius_y_in = 40.0\n\
             [tool]\nnose_radius_in = 0.125\nclearance_deg = 7.0\n[table]\nx_max_in = 2.0\nbound_uin = 0.5\n",
        );
        assert!(!p.feasible);
        assert!(
            failed(&p).contains(&"z_stroke".to_string()),
            "{:?}",
            failed(&p)
        );
        let c = p.checks.iter().find(|c| c.name == "z_stroke").unwrap();
        assert!((c.value - 0.05).abs() < 0.002, "{}", c.value);
        assert!(c
            .reason
            .as_ref()
            .unwrap()
            .contains("exceeds the slide's command range"));
        assert!(!failed(&p).contains(&"slope_along_cut".to_string()));
    }

    #[test]
    fn plan_refuses_a_slope_beyond_the_clearance_angle() {
        // z = 0.2·x·y: ∂Z/∂φ = 0.2 X² cos 2φ, so the slope along the cut is
        // atan(0.2 X) = 0.573° at X = 0.05 in, beyond a 0.5° clearance,
        // with a stroke of only 0.0005 in.
        let p = plan_of(
            "[surface]\nkind = \"xy-polynomial\"\nterms = [{ x_power = 1, y_power = 1, coefficient = 0.2 }]\n\
             [tool]\nnose_radius_in = 0.0\nclearance_deg = 0.5\n[table]\nx_max_in = 0.05\nbound_uin = 0.5\n[plan]\nerror_bound_uin = 1000.0\n",
        );
        assert_eq!(failed(&p), vec!["slope_along_cut".to_string()]);
        let c = p
            .checks
            .iter()
            .find(|c| c.name == "slope_along_cut")
            .unwrap();
        assert!(
            (c.value - (0.2f64 * 0.05).atan().to_degrees()).abs() < 1e-3,
            "{}",
            c.value
        );
        assert!(c.reason.as_ref().unwrap().contains("the flank would rub"));
        // The same part with a 7° clearance passes.
        let ok = plan_of(
            "[surface]\nkind = \"xy-polynomial\"\nterms = [{ x_power = 1, y_power = 1, coefficient = 0.2 }]\n\
             [tool]\nnose_radius_in = 0.0\nclearance_deg = 7.0\n[table]\nx_max_in = 0.05\nbound_uin = 0.5\n[plan]\nerror_bound_uin = 1000.0\n",
        );
        assert!(ok.feasible, "{:?}", failed(&ok));
    }
}

#[test]
fn a_wrong_unit_key_and_a_unit_in_a_value_are_reported_at_their_own_line() {
    let part = "[surface]\nkind = \"sinusoidal-grid\"\namplitude_mm = 0.01\nperiod_x_in = 1.0\n\
                period_y_in = 1.0\n[tool]\nnose_radius_in = 0.125\nclearance_deg = 7.0\n\
                [table]\nx_max_in = 2.0\nbound_uin = 0.1\n";
    let e = super::config::PartFile::from_toml(part).unwrap_err();
    assert!(e.starts_with("TOML parse error at line 3, column 1"), "{e}");
    assert!(e.contains("unknown field `amplitude_mm`"), "{e}");
    assert!(e.contains("inches"), "{e}");
    let part = part.replace("amplitude_mm = 0.01", "amplitude_in = \"0.8 mil\"");
    let e = super::config::PartFile::from_toml(&part).unwrap_err();
    assert!(e.starts_with("TOML parse error at line 3, column 1"), "{e}");
    assert!(
        e.contains("surface.amplitude_in: invalid type: string \"0.8 mil\""),
        "{e}"
    );
}

#[test]
fn a_range_no_grid_step_divides_is_refused_with_that_reason() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tables");
    let text = std::fs::read_to_string(dir.join("toric-lens.toml"))
        .unwrap()
        .replace("x_max_in = 1.5", "x_max_in = 0.6");
    let lp = super::config::PartFile::from_toml(&text)
        .unwrap()
        .load("x06", &dir)
        .unwrap();
    let why = lp.pick().unwrap_err();
    assert!(
        why.contains("no grid step gives a table the format accepts over X 0..0.6 in"),
        "{why}"
    );
    assert!(why.contains("must divide"), "{why}");
}
