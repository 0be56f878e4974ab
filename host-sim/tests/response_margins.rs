//! `response --loop digital` margins must not depend on how many points
//! the sweep has (issue 25: PM 45° at 30 points, 40° at 200). Checked on a
//! loop whose margins are known in closed form:
//! L(s) = K e^{−sτ} / (s (1 + s/a)).
//!
//! Crossover: |L| = 1 ⇔ ω⁴/a² + ω² − K² = 0, ω_c² = a²(√(1 + 4K²/a²) − 1)/2;
//! PM = 90° − atan(ω_c/a) − ω_c τ (degrees). Phase crossover:
//! 90° + atan(ω/a) + ωτ = 180°, solved here by bisection on that
//! scalar equation (independent of the code under test); GM = −20 log|L|.

use host_sim::cmd::response::{margins, margins_refined, LoopPoint};
use nalgebra::Complex;
use std::f64::consts::{PI, TAU};

const K: f64 = 600.0;
const A: f64 = 900.0;
const TAU_S: f64 = 0.0004;

fn l_of(f_hz: f64) -> Complex<f64> {
    let s = Complex::new(0.0, TAU * f_hz);
    K * (-s * TAU_S).exp() / (s * (1.0 + s / A))
}

fn point(f_hz: f64) -> LoopPoint {
    let l = l_of(f_hz);
    LoopPoint {
        f_hz,
        s: 1.0 / (1.0 + l),
        t: l / (1.0 + l),
    }
}

fn sweep(n: usize) -> Vec<LoopPoint> {
    (0..n)
        .map(|k| point(10f64.powf(k as f64 / (n - 1) as f64 * 3.0)))
        .collect()
}

fn exact() -> (f64, f64, f64, f64) {
    let wc = (A * A * ((1.0 + 4.0 * K * K / (A * A)).sqrt() - 1.0) / 2.0).sqrt();
    let pm = 90.0 - (wc / A).atan().to_degrees() - (wc * TAU_S).to_degrees();
    let g = |w: f64| PI / 2.0 + (w / A).atan() + w * TAU_S - PI;
    let (mut lo, mut hi) = (wc, 1e6);
    for _ in 0..200 {
        let m = 0.5 * (lo + hi);
        if g(m) < 0.0 {
            lo = m;
        } else {
            hi = m;
        }
    }
    let w180 = 0.5 * (lo + hi);
    let gm = -20.0 * l_of(w180 / TAU).norm().log10();
    (wc / TAU, pm, w180 / TAU, gm)
}

#[test]
fn refined_margins_match_the_closed_form_at_any_sweep_resolution() {
    let (fc, pm, f180, gm) = exact();
    for n in [12, 30, 200] {
        let m = margins_refined(&sweep(n), &point);
        let (mfc, mpm) = (m.crossover_hz.unwrap(), m.phase_margin_deg.unwrap());
        let (mf180, mgm) = (m.phase_crossover_hz.unwrap(), m.gain_margin_db.unwrap());
        assert!((mfc / fc - 1.0).abs() < 1e-3, "{n} points: {mfc} vs {fc}");
        assert!((mpm - pm).abs() < 0.02, "{n} points: PM {mpm} vs {pm}");
        assert!((mf180 / f180 - 1.0).abs() < 1e-3, "{n}: {mf180} vs {f180}");
        assert!((mgm - gm).abs() < 0.01, "{n} points: GM {mgm} vs {gm}");
    }
}

fn exact_peak_s_db() -> f64 {
    // A dense scan in log f (10⁵ points over the decade around the
    // crossover) and the best point: independent of the code under test.
    (0..100_000)
        .map(|k| 30.0 * 10f64.powf(k as f64 / 1e5))
        .map(|f| -20.0 * (1.0 + l_of(f)).norm().log10())
        .fold(f64::NEG_INFINITY, f64::max)
}

#[test]
fn refined_peak_sensitivity_matches_a_dense_scan_at_any_resolution() {
    let exact = exact_peak_s_db();
    for n in [12, 30, 200] {
        let m = margins_refined(&sweep(n), &point);
        assert!(
            (m.peak_sensitivity_db - exact).abs() < 0.005,
            "{n} points: {} vs {exact}",
            m.peak_sensitivity_db
        );
    }
}

/// The defect the refinement removes: read off a coarse sweep, the peak
/// of |S| is the largest sweep point's, well below the true peak.
#[test]
fn the_peak_sensitivity_of_a_coarse_sweep_alone_depends_on_its_resolution() {
    let exact = exact_peak_s_db();
    let coarse = margins(&sweep(12)).peak_sensitivity_db;
    assert!(exact - coarse > 0.3, "coarse {coarse} vs {exact}");
}
