//! Issue 30, item 2: the process stiffness measured on the machine.
//! `zslide identify --in-cut` on a served legacy-hw machine whose tool is
//! in a light test cut (`host-sim serve --cut-depth 300`, 100 µin/rev),
//! with the force model's edge constant k_e × 0.5, × 1 and × 3, against
//! the in-air plant (the data sheet: the served machine is the nominal
//! one, so the in-air fit's own error, 0.2 % in gain, is not in this
//! test: `tests/identify.rs` bounds it).
//!
//! The reference is the force model's slope at the cut's depth d and
//! feed f, written out here from its closed form (plant/cutting.rs:
//! F = k_t·d·f + k_e·(√(2 r_t d) + f/2), so dF/dd = k_t·f + k_e·√(r_t/(2d))):
//! 1102, 2185 and 6514 lbf/in.
//!
//! Tolerance, from a Monte Carlo over the rig's seeds (the gauge's noise
//! and the chip's force noise; the served machine runs in lockstep, so a
//! seed gives one result, bit for bit, whatever the host's timing):
//! [`monte_carlo_of_the_identified_stiffness_over_seeds`] identifies each
//! k_e on [`MC_SEEDS`] seeds and gives the mean m of k/slope − 1 (the
//! estimator's bias: the force model's curvature over the tool's motion,
//! at most +0.6 % by the first harmonic of √(d + a sin ωt), and whatever
//! else the estimator has), the spread s of the runs about it and the
//! identifier's own one-sigma σ̄ on average; [`MC`] records them. A run
//! must then lie within 3 r σ + 2 s/√n of slope × (1 + m): its own sigma
//! σ, scaled by r = max(1, s/σ̄) where the runs spread wider than the
//! identifier says, three times, plus twice the bias's standard error.
//! The one-sigma itself must be under 3 % of the stiffness, or the test
//! proves nothing.

use std::time::Duration;

use host_sim::serve::Setup;
use zslide_host::cli::run_line;
use zslide_host::client::Link;

/// Seeds of the Monte Carlo per k_e.
const MC_SEEDS: u64 = 12;

/// What [`monte_carlo_of_the_identified_stiffness_over_seeds`] measured
/// (seeds 1..=12 each): k_e scale, mean of k/slope − 1, its spread, and
/// the identifier's sigma/slope on average. At k_e × 3 the bias, +0.91 %
/// ± 0.05 %, is beyond the curvature's 0.6 %: a systematic of the
/// estimator not run down (candidates: the in-air model against the served
/// machine at 156-195 Hz, where the spring is 14 % of 1/H).
const MC: [(f64, f64, f64, f64); 3] = [
    (0.5, -0.0036, 0.0235, 0.0188),
    (1.0, 0.0001, 0.0103, 0.0090),
    (3.0, 0.0091, 0.0016, 0.0025),
];

/// The Monte Carlo's row for `ke_scale`.
fn mc(ke_scale: f64) -> (f64, f64, f64) {
    let &(_, mean, spread, sigma) = MC.iter().find(|r| r.0 == ke_scale).unwrap();
    (mean, spread, sigma)
}

mod in_cut;
mod machine;
mod phase;
use in_cut::{air_plant, identify, test_dir, Identified, Run, DEPTH_IN, FEED_IN};
use machine::Machine;

/// The force model's slope at the cut's depth d and feed f with k_e ×
/// `ke_scale`, from its closed form (plant/cutting.rs:
/// F = k_t·d·f + k_e·(√(2 r_t d) + f/2), so dF/dd = k_t·f + k_e·√(r_t/(2d))),
/// lbf/in.
fn model_slope(ke_scale: f64) -> f64 {
    let c = host_sim::scenario::load("legacy-hw").unwrap().cutting;
    c.k_t_psi * FEED_IN + ke_scale * c.k_e_lbf_per_in * (c.tool_radius_in / (2.0 * DEPTH_IN)).sqrt()
}

/// Identifies the process of the test cut with k_e × `ke_scale` on the
/// rig seeded `seed` (None: the scenario's), in lockstep.
fn identify_at(ke_scale: f64, seed: Option<u64>) -> Identified {
    let name = format!("process-ke{ke_scale}-seed{seed:?}");
    identify(&Run {
        name: &name,
        ke_scale,
        seed,
        lockstep: true,
        repeats: None,
        route: &|addr| addr.to_owned(),
    })
}

fn check(ke_scale: f64) {
    let slope = model_slope(ke_scale);
    let got = identify_at(ke_scale, None);
    let (k, sigma) = (
        got.process.stiffness_lbf_per_in,
        got.process.stiffness_sigma,
    );
    eprintln!(
        "k_e x {ke_scale}:\n{}model slope {slope:.1} lbf/in",
        got.report
    );
    assert!(
        sigma <= 0.03 * slope,
        "k_e x {ke_scale}: one sigma {sigma:.1} lbf/in is over 3 % of {slope:.0}"
    );
    let (mean, spread, sigma_mc) = mc(ke_scale);
    let expected = slope * (1.0 + mean);
    let allowed = 3.0 * (spread / sigma_mc).max(1.0) * sigma
        + 2.0 * spread / (MC_SEEDS as f64).sqrt() * slope;
    assert!(
        (k - expected).abs() <= allowed,
        "k_e x {ke_scale}: identified {k:.1} ± {sigma:.1} lbf/in, the force model's slope \
         {slope:.1} with the estimator's bias {:+.2} %: {expected:.1} (allowed ±{allowed:.1})",
        100.0 * mean
    );
}

/// The Monte Carlo over the rig's seeds behind the tolerance: for each
/// k_e, `MC_SEEDS` identifications, each on its own seed (the gauge's
/// noise and the chip's force noise), in lockstep. Prints the mean and
/// the spread of k/slope − 1 and the mean of the identifier's own
/// sigma/slope. Not part of the suite (a minute of release-profile
/// simulation): `cargo test --release -p zslide-host --test process --
/// --ignored --nocapture`.
#[test]
#[ignore]
fn monte_carlo_of_the_identified_stiffness_over_seeds() {
    for ke_scale in [0.5, 1.0, 3.0] {
        let reference = model_slope(ke_scale);
        let (mut errs, mut sigmas) = (Vec::new(), Vec::new());
        for seed in 1..=MC_SEEDS {
            let p = identify_at(ke_scale, Some(seed)).process;
            errs.push(p.stiffness_lbf_per_in / reference - 1.0);
            sigmas.push(p.stiffness_sigma / reference);
            eprintln!(
                "k_e x {ke_scale} seed {seed}: {:.1} ± {:.1} lbf/in against {reference:.1}",
                p.stiffness_lbf_per_in, p.stiffness_sigma
            );
        }
        let n = errs.len() as f64;
        let mean = errs.iter().sum::<f64>() / n;
        let spread = (errs.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let sigma = sigmas.iter().sum::<f64>() / n;
        eprintln!(
            "k_e x {ke_scale}: over {MC_SEEDS} seeds k/slope - 1 = {:+.2} % mean, {:.2} % spread \
             (standard error of the mean {:.2} %), the identifier's sigma {:.2} % on average, \
             largest |error| {:.2} %",
            100.0 * mean,
            100.0 * spread,
            100.0 * spread / n.sqrt(),
            100.0 * sigma,
            100.0 * errs.iter().fold(0.0f64, |a, e| a.max(e.abs()))
        );
        let (m, sp, sg) = mc(ke_scale);
        assert!(
            (mean - m).abs() <= 5e-5 && (spread - sp).abs() <= 5e-5 && (sigma - sg).abs() <= 5e-5,
            "k_e x {ke_scale}: MC records ({m}, {sp}, {sg}); this run gives \
             ({mean:.4}, {spread:.4}, {sigma:.4}): update MC"
        );
    }
}

#[test]
fn the_process_stiffness_of_a_half_sharp_edge_is_the_force_models_slope() {
    check(0.5);
}

#[test]
fn the_process_stiffness_of_the_nominal_edge_is_the_force_models_slope() {
    check(1.0);
}

#[test]
fn the_process_stiffness_of_a_thrice_blunt_edge_is_the_force_models_slope() {
    check(3.0);
}

/// `tune --process`: the nominal design on the nominal plant passes in
/// air; a part of 50 000 lbf/in (k_e × 23 of the test cut: a nearly rigid
/// contact) leaves it less than the minimum margins, by the sampled-data
/// model of the design (`host_sim::loopmodel`, which the code under test
/// does not use), so `tune` refuses and sets nothing; a part of the
/// nominal cut's stiffness passes.
#[test]
fn tune_refuses_a_design_whose_margins_at_the_measured_stiffness_are_below_the_minimums() {
    use zslide_host::predict::{MIN_GAIN_MARGIN_DB, MIN_PHASE_MARGIN_DEG};
    use zslide_host::process::{process_text, Process};
    let sc = host_sim::scenario::load("legacy-hw").unwrap();
    let stiff = 50_000.0;
    // The least gain margin of the model's loop at that stiffness (−|L|
    // in dB wherever ∠L crosses −180°) and the least phase margin
    // (180° + ∠L wherever |L| crosses 1), between 2 Hz and 2 kHz.
    let model = host_sim::loopmodel::LoopModel::new(
        &sc.servo_design,
        sc.file.motor.l_over_r_ms * 1e-3,
        sc.rig.dac_latency_ns as f64 * 1e-9,
        stiff,
    );
    let fs: Vec<f64> = (0..4000)
        .map(|i| 2.0 * 1000f64.powf(f64::from(i) / 3999.0))
        .collect();
    let least_gm = fs
        .windows(2)
        .filter_map(|w| {
            let (a, b) = (model.loop_gain(w[0]), model.loop_gain(w[1]));
            (a.re < 0.0 && b.re < 0.0 && (a.im > 0.0) != (b.im > 0.0))
                .then(|| -20.0 * b.norm().log10())
        })
        .fold(f64::INFINITY, f64::min);
    let least_pm = fs
        .windows(2)
        .filter_map(|w| {
            let (a, b) = (model.loop_gain(w[0]), model.loop_gain(w[1]));
            ((a.norm() >= 1.0) != (b.norm() >= 1.0)).then(|| 180.0 - b.arg().to_degrees().abs())
        })
        .fold(f64::INFINITY, f64::min);
    assert!(
        least_gm < MIN_GAIN_MARGIN_DB || least_pm < MIN_PHASE_MARGIN_DEG,
        "the model's margins at {stiff} lbf/in: {least_pm:.1} deg, {least_gm:.1} dB"
    );

    let dir = test_dir();
    let plant = air_plant(&dir);
    let file = |name: &str, k: f64| {
        let path = dir.join(name);
        let p = Process {
            stiffness_lbf_per_in: k,
            stiffness_sigma: 0.01 * k,
            damping_lbf_s_per_in: 0.0,
            damping_sigma: 0.02,
            chi2: 1.0,
        };
        std::fs::write(&path, process_text(&p, &plant)).unwrap();
        path
    };
    let rigid = file("process-rigid.process", stiff);
    let nominal = file("process-nominal.process", 2185.0);
    let m = Machine::start("process-tune", Setup::new(sc));
    let mut link = Link::new(&m.addr, Duration::from_secs(10));
    let before = zslide_host::identify::design_on(link.client().unwrap()).unwrap();
    let e = run_line(
        &mut link,
        &format!("tune {} --process {}", plant.display(), rigid.display()),
    )
    .unwrap_err();
    assert!(
        e.contains("in the cut") && e.contains("margin") && e.contains("nothing set"),
        "{e}"
    );
    let after = zslide_host::identify::design_on(link.client().unwrap()).unwrap();
    assert_eq!(format!("{before:?}"), format!("{after:?}"));
    let ok = run_line(
        &mut link,
        &format!(
            "tune {} --process {} --dry-run",
            plant.display(),
            nominal.display()
        ),
    )
    .unwrap();
    assert_eq!(ok.matches("lbf/in: crossover").count(), 3, "{ok}");
}
