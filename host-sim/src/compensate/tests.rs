//! The fit against surfaces known in closed form, every refusal of a
//! measurement file, the cancellation of a known error through the
//! firmware's command path, and the measure → compensate → cut iteration
//! on a machine whose error is known.

use super::compensated;
use super::fit::{fit, ErrorFit, Limits, Point};
use super::measured::parse;
use crate::part::config::LoadedPart;
use crate::part::split::{Compensation, Part, Tool};
use crate::part::table::PartTableSpec;
use crate::part::xypoly::XyPolynomial;
use crate::part::zernike::{Ordering, Zernike};
use crate::part::Sag;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use std::sync::Arc;

/// Chapter 5's grid: X = 1..7 in by φ = 0..350° in 10° steps (252 points).
fn chapter5_grid() -> Vec<(f64, f64)> {
    let mut v = Vec::new();
    for i in 0..36 {
        for j in 1..=7 {
            let (s, c) = (10.0 * f64::from(i)).to_radians().sin_cos();
            v.push((f64::from(j) * c, f64::from(j) * s));
        }
    }
    v
}

fn noisy(f: impl Fn(f64, f64) -> f64, sigma: f64, seed: u64) -> Vec<Point> {
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
    chapter5_grid()
        .into_iter()
        .map(|(x, y)| {
            let n: f64 = StandardNormal.sample(&mut rng);
            Point {
                x_in: x,
                y_in: y,
                error_uin: f(x, y) + sigma * n,
            }
        })
        .collect()
}

/// Tilt + radial bias (the wear's shape: deepest at the centre) in µin.
fn tilt_and_bias(x: f64, y: f64) -> f64 {
    12.0 * x - 7.0 * y + 300.0 - 6.0 * (x * x + y * y)
}

/// Least squares with p terms leaves the fitted values' error with an RMS
/// over the N points of σ√(p/N) (its square is σ²χ²_p/N); twice that is
/// the tolerance (χ²_p > 4p has probability below 1e-6 for p ≥ 6).
#[test]
fn a_tilt_and_radial_bias_under_noise_are_recovered_within_two_sigma_root_p_over_n() {
    let sigma = 20.0;
    for seed in 1..=5 {
        let pts = noisy(tilt_and_bias, sigma, seed);
        let r = fit(&pts, 7.2, sigma, &Limits::default()).unwrap();
        let z = r.fit.surface().unwrap();
        let p = r.fit.coefficients_uin.len();
        assert!(
            r.fit.order >= 2,
            "order {} cannot hold the bias",
            r.fit.order
        );
        let err = (pts
            .iter()
            .map(|q| (z.sag(q.x_in, q.y_in) * 1e6 - tilt_and_bias(q.x_in, q.y_in)).powi(2))
            .sum::<f64>()
            / pts.len() as f64)
            .sqrt();
        let tol = 2.0 * sigma * (p as f64 / pts.len() as f64).sqrt();
        assert!(
            err <= tol,
            "seed {seed}: {err:.2} µin RMS vs {tol:.2} ({p} terms)"
        );
        // What it calls noise is the noise: σ̂ within 20 % of σ.
        let s = r.fit.noise_estimate_uin;
        assert!((s / sigma - 1.0).abs() < 0.2, "seed {seed}: σ̂ {s:.2}");
    }
}

#[test]
fn too_few_points_are_refused() {
    let pts: Vec<Point> = noisy(tilt_and_bias, 1.0, 1).into_iter().take(9).collect();
    let e = fit(&pts, 7.2, 1.0, &Limits::default()).unwrap_err();
    assert!(e.contains("too few points"), "{e}");
}

#[test]
fn a_hole_in_the_coverage_is_refused_and_placed() {
    // No point in the first quadrant: its middle (X ≈ 4.5 in, φ ≈ 45°) is
    // 3.2 in from the nearest.
    let pts: Vec<Point> = noisy(tilt_and_bias, 1.0, 1)
        .into_iter()
        .filter(|p| !(p.x_in > 0.1 && p.y_in > 0.1))
        .collect();
    let e = fit(&pts, 7.2, 20.0, &Limits::default()).unwrap_err();
    assert!(e.contains("hole in the coverage"), "{e}");
    assert!(e.contains("φ = 4") || e.contains("φ = 5"), "{e}");
}

#[test]
fn a_residual_beyond_the_instruments_noise_is_refused() {
    // 20 µin of scatter from an instrument said to have 2 µin.
    let pts = noisy(tilt_and_bias, 20.0, 3);
    let e = fit(&pts, 7.2, 2.0, &Limits::default()).unwrap_err();
    assert!(e.contains("above 3 × the instrument's 2 µin"), "{e}");
}

fn refused(text: &str, words: &str) {
    match parse(text.as_bytes()) {
        Ok(m) => panic!("accepted ({} points): {text}", m.points.len()),
        Err(e) => assert!(e.contains(words), "{e:?} lacks {words:?}"),
    }
}

#[test]
fn every_malformed_measurement_is_refused_with_its_line() {
    let ok = "x_in,y_in,error_uin\n1,0,10\n0,1,-5\n";
    assert_eq!(parse(ok.as_bytes()).unwrap().points.len(), 2);
    refused("x_mm,y_mm,error_um\n1,0,10\n", "line 1: header");
    refused("", "empty");
    refused("x_in,y_in,error_uin\n1,0,10\n2,0\n", "line 3");
    refused("x_in,y_in,error_uin\n1,0,10\n2,0,\n", "line 3");
    refused("x_in,y_in,error_uin\n1,0,NaN\n", "line 2: error = NaN");
    refused("x_in,y_in,error_uin\n1,0,inf\n", "line 2: error = inf");
    refused(
        "x_in,y_in,error_uin\n1,0,ten\n",
        "line 2: error_uin = \"ten\"",
    );
    refused(
        "x_in,y_in,error_uin\n1,0,10\n# a comment\n2,0,3\n1,0,11\n",
        "line 2 and line 5 measure the same place",
    );
    refused(
        "x_in,y_in,error_uin\n25.4,0,10\n",
        "line 2: radius 25.4 in is beyond",
    );
    refused(
        "x_in,y_in,error_uin\n1,0,25400\n",
        "line 2: error 25400 µin",
    );
    // cut --out's error map.
    let map = "phi_deg,X_1_in,X_2_in\n0,1,2\n10,3,\n360,1,2\n";
    let m = parse(map.as_bytes()).unwrap();
    assert_eq!((m.points.len(), m.absent), (3, 1));
    refused("phi_deg,X_1_in,X_2_in\n0,1,2\n10,3\n", "line 3: 2 fields");
    refused(
        "phi_deg,X_1_in,X_2_in\n0,1,2\n360,1,3\n",
        "line 3: the 360° row differs",
    );
    refused(
        "phi_deg,X_1_in,X_2_in\n0,1,2\n370,1,3\n",
        "line 3, X = 1 in: φ = 370°",
    );
    refused("phi_deg,X_1_mm\n0,1\n", "line 1: column \"X_1_mm\"");
    // cut --grid --out's points.
    let h = "x_in,y_in,radius_in,phi_deg,error_uin,finish_uin,absent\n";
    let g = format!("{h}1,0,1,0,3.5,0.1,\n0,0,0,0,,,outside-the-cut\n");
    let m = parse(g.as_bytes()).unwrap();
    assert_eq!((m.points.len(), m.absent), (1, 1));
    refused(
        &format!("{h}1,0,1,0,,,\n"),
        "line 2: error_uin is empty with no `absent`",
    );
    refused(
        &format!("{h}1,0,1,0,2,,in-a-hole\n"),
        "line 2: an error value and absent",
    );
    refused(&format!("{h}1,0,1,0,2,\n"), "line 2: 6 fields");
    // cut --json.
    let json = |sign: &str, measure: &str, rows: &str| {
        format!(
            "{{\"command_sign\": \"{sign}\", \"measure\": \"{measure}\", \"phi_deg\": [0.0, 10.0], \
             \"x_in\": [1.0, 2.0], \"cmm_grid_uin\": {rows}}}"
        )
    };
    let m = parse(json("normal", "cmm", "[[1.0, null], [2.0, 3.0]]").as_bytes()).unwrap();
    assert_eq!((m.points.len(), m.absent), (3, 1));
    assert!((m.stated_noise_uin.unwrap() - super::measured::cmm_noise_uin()).abs() < 1e-12);
    // The mean of 16 readings states a quarter of one reading's noise.
    let mean_of = |n: &str| {
        json("normal", "cmm", "[[1.0, null], [2.0, 3.0]]").replacen(
            '{',
            &format!("{{\"cmm_readings\": {n}, "),
            1,
        )
    };
    let m = parse(mean_of("16").as_bytes()).unwrap();
    assert!((m.stated_noise_uin.unwrap() - super::measured::cmm_noise_uin() / 4.0).abs() < 1e-12);
    refused(&mean_of("0"), "cmm_readings = 0");
    refused(&mean_of("2.5"), "cmm_readings = 2.5");
    refused(
        &json("reversed", "cmm", "[[1.0, 2.0], [2.0, 3.0]]"),
        "command_sign",
    );
    refused(
        &json("normal", "guess", "[[1.0, 2.0], [2.0, 3.0]]"),
        "measure",
    );
    refused(
        &json("normal", "cmm", "[[1.0, 2.0]]"),
        "1 rows for 2 angles",
    );
    refused(
        &json("normal", "cmm", "[[1.0, 2.0], [2.0]]"),
        "cmm_grid_uin[1] (φ = 10°) has 1 values",
    );
    refused(
        &json("normal", "cmm", "[[1.0, 2.0], [2.0, \"x\"]]"),
        "cmm_grid_uin[1][1]",
    );
    refused(
        "{\"command_sign\": \"normal\",\n \"measure\": }",
        "line 2: not JSON",
    );
    refused("{\"measure\": \"cmm\"}", "field `command_sign` missing");
}

/// A sharp-tool part over X ≤ 2 in: z = 1e-3·x² + 4e-4·x·y (a mild saddle
/// with φ-content).
fn small_part() -> LoadedPart {
    let sag = XyPolynomial::new(vec![(2, 0, 1e-3), (1, 1, 4e-4)]).unwrap();
    LoadedPart {
        name: "small".into(),
        description: "test".into(),
        part: Part {
            sag: Arc::new(sag),
            tool: Tool {
                nose_radius: 0.0,
                clearance_deg: 7.0,
                compensation: Compensation::ProfileNormal,
            },
        },
        table: PartTableSpec {
            x_min: 0.0,
            x_max: 2.0,
            step: 2.0,
            x_null: 2.0,
            harmonics: 1,
            coeff_frac_bits: 30,
            x_frac_bits: 24,
        },
        bound_uin: 0.2,
        allowance_uin: 0.01,
        binary_grid: true,
        plan_error_bound_uin: 25.0,
    }
}

/// Tilt, defocus, astigmatism and coma, µin (Noll 2, 3, 4, 6, 8).
fn known_error() -> ErrorFit {
    ErrorFit {
        radius_in: 2.0,
        order: 3,
        coefficients_uin: vec![0.0, 30.0, -20.0, 15.0, 0.0, 10.0, 0.0, 8.0],
        points: 0,
        residual_rms_uin: 0.0,
        noise_estimate_uin: 0.0,
        loo_rms_uin: 0.0,
        noise_share: 0.0,
        excluded: vec![],
    }
}

/// A fit with its tilt excluded (the measurement's set-up term) corrects
/// everything else it fitted and no tilt: its surface is the known error
/// less exactly the Noll 2 and 3 terms, and its reported tilt is the
/// known one (2 × |(30, −20)| µin at the edge).
#[test]
fn an_excluded_tilt_is_fitted_and_reported_but_not_corrected() {
    let mut f = known_error();
    f.excluded = crate::compensate::fit::TILT.to_vec();
    let with = known_error().surface().unwrap();
    let without = f.surface().unwrap();
    let tilt = Zernike::new(Ordering::Standard, 2.0, None, &[0.0, 30e-6, -20e-6]).unwrap();
    for (x, y) in [(0.3, -1.1), (1.9, 0.2), (-1.2, 1.4), (0.0, 0.0)] {
        let d = with.sag(x, y) - without.sag(x, y) - tilt.sag(x, y);
        assert!(d.abs() < 1e-12, "at ({x}, {y}): {d:e} in");
    }
    assert!((f.tilt_edge_uin() - 2.0 * 30f64.hypot(20.0)).abs() < 1e-9);
}

/// With gain 1 the firmware's command (its fixed-point path on the
/// compensated table) plus the axial slide's `Y'` is the nominal surface
/// less the known error, within the table's bound.
#[test]
fn a_known_error_with_gain_one_cancels_in_the_command_within_the_tables_bound() {
    let lp = small_part();
    let e = known_error().surface().unwrap();
    let cp = compensated(&lp, vec![(1.0, e.clone())]);
    let (_, image, r) = crate::cmd::parttable::make(&cp).unwrap();
    assert!(r.errors.total_uin + lp.allowance_uin <= lp.bound_uin);
    let gen = zslide::command::CommandGen::new(zslide::table::CoeffTable::parse(&image).unwrap());
    let mut worst = 0.0f64;
    for i in 0..40 {
        let x = 0.05 + 1.9 * f64::from(i) / 39.0;
        let y_axial = cp.part.section(x).unwrap().y;
        for k in 0..51 {
            let phi_cmd = 7.0 * f64::from(k);
            let z = crate::cmd::zcmd::z_at(&gen, x, phi_cmd).unwrap();
            let phi_p = crate::part::part_angle(phi_cmd.to_radians());
            let (px, py) = (x * phi_p.cos(), x * phi_p.sin());
            let want = lp.part.sag.sag(px, py) - e.sag(px, py);
            worst = worst.max((y_axial + z - want).abs());
        }
    }
    assert!(
        worst * 1e6 <= lp.bound_uin,
        "{:.4} µin vs {}",
        worst * 1e6,
        lp.bound_uin
    );
}

/// The iteration on a machine whose error repeats: each pass leaves the
/// machine's own error `m(x, y)` (tilt, wear-shaped bias, coma) plus the
/// program's departure from the nominal (the compensated tool path `T'`
/// less the nominal `T`, what the slides add), read with 20 µin of new
/// noise; two compensations at gain 1 bring the true band to within the
/// fit's noise (4σ√(p/N) ≈ 20 µin from 800 µin). With the correction's
/// sign reversed (`Compensated::sag` adding g·ê) the band grows instead.
#[test]
fn measure_compensate_cut_twice_brings_a_repeatable_error_to_the_fits_noise() {
    let lp = small_part();
    let machine = |x: f64, y: f64| {
        150.0 * x - 80.0 * y + 400.0 - 90.0 * (x * x + y * y) + 20.0 * x * (x * x + y * y)
    };
    let pts: Vec<(f64, f64)> = chapter5_grid()
        .into_iter()
        .map(|(x, y)| (x * 2.0 / 7.0, y * 2.0 / 7.0))
        .collect();
    let band = |prog: &LoadedPart| -> Vec<f64> {
        pts.iter()
            .map(|&(x, y)| {
                let (r, phi) = (x.hypot(y), y.atan2(x));
                let t_prog = prog.part.section(r).unwrap();
                let t_nom = lp.part.section(r).unwrap();
                let dz = t_prog.t(&prog.part, phi).unwrap() - t_nom.t(&lp.part, phi).unwrap();
                machine(x, y) + dz * 1e6
            })
            .collect()
    };
    let width = |v: &[f64]| v.iter().fold(0.0f64, |a, &e| a.max(e.abs()));
    let mut corrections = vec![];
    let mut prog = compensated(&lp, vec![]);
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(9);
    let first = width(&band(&prog));
    let (mut last, mut p) = (first, 0usize);
    for _ in 0..2 {
        let measured: Vec<Point> = pts
            .iter()
            .zip(band(&prog))
            .map(|(&(x, y), e)| {
                let n: f64 = StandardNormal.sample(&mut rng);
                Point {
                    x_in: x,
                    y_in: y,
                    error_uin: e + 20.0 * n,
                }
            })
            .collect();
        let r = fit(&measured, 2.0, 20.0, &Limits::default()).unwrap();
        p = p.max(r.fit.coefficients_uin.len());
        corrections.push((1.0, r.fit.surface().unwrap()));
        prog = compensated(&lp, corrections.clone());
        last = width(&band(&prog));
    }
    let tol = 4.0 * 20.0 * (p as f64 / pts.len() as f64).sqrt();
    assert!(first > 500.0, "{first}");
    assert!(
        last <= tol,
        "after two compensations the band is ±{last:.1} µin (tolerance {tol:.1}, from ±{first:.0})"
    );
}
