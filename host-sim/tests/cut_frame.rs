//! The frames of the cut pinned independently of the simulator: the
//! simulated 1983 second part (holes filled, 360 rpm) against the linear
//! prediction of eq 4-49, `(1 − T)·Z`, T evaluated in the command's angle
//! (increasing with time), counted positive as excess stock: chapter 5's
//! frame, where the dissertation's own simulation (`ERR = R2 − Z`,
//! Appendix C) "displays a similar character" to the measured part.

use host_sim::analog1983::eq4_49;
use host_sim::coeffgen::harmonics;
use host_sim::cut::part::{CmmGrid, CMM_PHI_COUNT, CMM_X_IN};
use host_sim::cut::{plan, run_stretch, Controller, CutSpec, Extras, Holes};
use nalgebra::Complex;
use std::f64::consts::TAU;

/// `(1 − T(jkΩ))·Z` at the tool-centre radius `xc`, by harmonic, sampled
/// at the 36 CMM angles read as the command's angle, in.
fn lag_prediction(spec: &CutSpec, xc: f64) -> Vec<f64> {
    let (surf, _) = spec.surface().unwrap();
    let h = harmonics(&surf.section(xc).unwrap(), 12);
    let omega = spec.rpm / 60.0 * TAU;
    (0..CMM_PHI_COUNT)
        .map(|i| {
            let phi = TAU * i as f64 / CMM_PHI_COUNT as f64;
            (1..=h.k_max())
                .map(|k| {
                    let g = Complex::new(1.0, 0.0) - eq4_49(k as f64 * omega);
                    let zk = Complex::new(h.c[k], -h.s[k]);
                    (g * zk * Complex::from_polar(1.0, k as f64 * phi)).re
                })
                .sum::<f64>()
        })
        .collect()
}

fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let cov: f64 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = a.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f64 = b.iter().map(|y| (y - mb).powi(2)).sum();
    cov / (va * vb).sqrt()
}

#[test]
fn the_1983_second_part_correlates_with_the_eq_4_49_lag_prediction_at_5_and_7_in() {
    let sc = host_sim::scenario::load("legacy-hw").unwrap();
    let mut spec = CutSpec::chapter5(
        sc,
        Controller::LegacyAnalog,
        Some(360.0),
        Some(Holes::Filled),
        false,
    )
    .unwrap();
    spec.band_half_in = 0.0015;
    spec.preroll_revs = 15.0;
    let (surf, _) = spec.surface().unwrap();
    let gain = surf.contact_gain();
    let stretches = plan(&spec, gain);
    for x in [5.0, 7.0] {
        let j = CMM_X_IN.iter().position(|&v| v == x).unwrap();
        let r = run_stretch(&spec, &stretches[j], &Extras::default(), &|_| {}).unwrap();
        assert!(r.faults.is_empty(), "{:?}", r.faults);
        let g = CmmGrid::measure(
            &r.log.passes,
            gain,
            spec.scenario.cutting.tool_radius_in,
            spec.feed_per_rev_in,
            |_, _| false,
        );
        let sim: Vec<f64> = g.err_uin.iter().map(|row| row[j].unwrap()).collect();
        let pred: Vec<f64> = lag_prediction(&spec, x / gain)
            .iter()
            .map(|v| v * 1e6)
            .collect();
        let rho = correlation(&sim, &pred);
        eprintln!("X = {x} in: correlation {rho:.3}");
        assert!(rho > 0.7, "X = {x} in: correlation {rho:.3}");
    }
}
