//! The error sources beyond the loop against their closed forms, each on
//! the digital loop and the low-noise machine (`modern-hw`), holes filled,
//! as the part's grid minus the same seeded run without the source.

use host_sim::cut::errors::{ErrorLevels, Selection};
use host_sim::cut::part::{rms_about_line, CmmGrid, CMM_PHI_COUNT, CMM_X_IN};
use host_sim::cut::sign::CommandSign;
use host_sim::cut::{plan, run_stretch, Controller, CutSpec, Extras, Holes};
use std::f64::consts::TAU;

fn spec(levels: Option<ErrorLevels>) -> CutSpec {
    let sc = host_sim::scenario::load("modern-hw").unwrap();
    let mut s =
        CutSpec::chapter5(sc, Controller::Digital, None, Some(Holes::Filled), false).unwrap();
    s.band_half_in = 0.0015;
    s.preroll_revs = 15.0;
    if let Some(l) = levels {
        s.errors = Selection::All;
        s.error_levels = l;
    }
    s
}

/// The grid column at CMM radius `x` (µin).
fn column(s: &CutSpec, x: f64) -> Vec<f64> {
    column_and_finish(s, x).0
}

/// The grid column at CMM radius `x` and the passes' scatter there (µin
/// RMS about their line in X at each angle).
fn column_and_finish(s: &CutSpec, x: f64) -> (Vec<f64>, f64) {
    let (surf, _) = s.surface().unwrap();
    let gain = surf.contact_gain();
    let j = CMM_X_IN.iter().position(|&v| v == x).unwrap();
    let st = plan(s, gain).swap_remove(j);
    let r = run_stretch(s, &st, &Extras::default(), &|_| {}).unwrap();
    assert!(r.faults.is_empty(), "{:?}", r.faults);
    let g = CmmGrid::measure(
        &r.log.passes,
        gain,
        s.scenario.cutting.tool_radius_in,
        s.feed_per_rev_in,
        |_, _| false,
    );
    let col = g.err_uin.iter().map(|row| row[j].unwrap()).collect();
    // The revolution-to-revolution scatter: at each angle the passes'
    // RMS about their line in X (the learning still settles over the
    // band), pooled over the angles.
    let sq: f64 = r
        .log
        .passes
        .by_phi
        .iter()
        .map(|passes| {
            let x: Vec<f64> = passes.iter().map(|p| p.x_in).collect();
            let e: Vec<f64> = passes.iter().map(|p| p.e_in * 1e6).collect();
            rms_about_line(&x, &e).powi(2)
        })
        .sum();
    (col, (sq / CMM_PHI_COUNT as f64).sqrt())
}

#[test]
fn a_gauge_scale_error_eps_leaves_minus_eps_times_z() {
    let eps = 0.01;
    let x = 7.0;
    let base = column(&spec(None), x);
    let s = spec(Some(ErrorLevels {
        gauge_scale_error: eps,
        ..ErrorLevels::default()
    }));
    let with = column(&s, x);
    let (surf, _) = s.surface().unwrap();
    let sec = surf.section(x / surf.contact_gain()).unwrap();
    let mut worst = 0.0f64;
    for i in 0..CMM_PHI_COUNT {
        let z = sec.z(TAU * i as f64 / CMM_PHI_COUNT as f64) * 1e6;
        let expect = -eps * z;
        worst = worst.max((with[i] - base[i] - expect).abs());
    }
    // −εZ reaches +64 µin here; ε²Z and the loop's own change stay < 2.
    assert!(worst < 2.0, "worst deviation from −εZ: {worst:.2} µin");
}

/// The interferometer reads X + δ: the tool at part radius x follows
/// Z(x + δ). The band keeps its pre-roll on the part (`cut::build_stretch`
/// starts the machine δ further out), so both runs cut the same part
/// history and the grid moves by `Z(x + δ) − Z(x)`. Its difference from
/// `∂Z/∂X·δ` is bounded by the mechanisms, each from an independent
/// figure, not from this run:
/// - the Taylor remainder `½ max|∂²Z/∂X²| δ²` (the surface);
/// - what the loop leaves of the added command `∂Z/∂X·δ`: the loop is
///   linear in its command, so at most the fraction ρ it leaves of the
///   command itself, ρ = (p-v of the base column) / (p-v of Z) (the base
///   run's whole variation counted as tracking error: an upper bound);
/// - the firmware's command path at X and at X + δ: 2 × 0.052 µin
///   (interpolation, quantisation and arithmetic; docs/COEFFICIENTS.md);
/// - the scatter of a grid point: the machine reading other X values puts
///   the X events and handlers at other instants, so the gauge noise is
///   sampled at other times and the two runs do not share the noise
///   realisation at the point (even δ = 1 µin moves points by 0.16 µin).
///   A point scatters by σ, the passes' RMS about their line in X at each
///   angle, measured on the base run; the difference of two draws is within
///   4·√2·σ at all 36 angles but with probability ≈ 0.2 %.
#[test]
fn a_constant_x_zero_error_gives_the_slope_times_the_offset() {
    let delta = 0.01;
    let x = 7.0;
    let (base, finish) = column_and_finish(&spec(None), x);
    let s = spec(Some(ErrorLevels {
        x_zero_error_in: delta,
        ..ErrorLevels::default()
    }));
    let with = column(&s, x);
    let (surf, _) = s.surface().unwrap();
    let xc = x / surf.contact_gain();
    let sec = surf.section(xc).unwrap();
    let h = 1e-3;
    let (lo, hi) = (surf.section(xc - h).unwrap(), surf.section(xc + h).unwrap());
    let phis: Vec<f64> = (0..CMM_PHI_COUNT)
        .map(|i| TAU * i as f64 / CMM_PHI_COUNT as f64)
        .collect();
    let slope_delta: Vec<f64> = phis.iter().map(|&p| sec.dz_dx(p) * delta * 1e6).collect();
    let largest = slope_delta.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(largest > 10.0, "the test sees the slope ({largest:.1} µin)");
    let zxx = phis
        .iter()
        .map(|&p| ((hi.dz_dx(p) - lo.dz_dx(p)) / (2.0 * h)).abs())
        .fold(0.0f64, f64::max);
    let taylor = 0.5 * zxx * delta * delta * 1e6;
    let pv = |v: &[f64]| {
        v.iter().copied().fold(f64::MIN, f64::max) - v.iter().copied().fold(f64::MAX, f64::min)
    };
    let z: Vec<f64> = phis.iter().map(|&p| sec.z(p) * 1e6).collect();
    let rho = pv(&base) / pv(&z);
    let command_path = 2.0 * 0.052;
    let scatter = 4.0 * std::f64::consts::SQRT_2 * finish;
    let bound = taylor + rho * largest + command_path + scatter;
    let worst = (0..CMM_PHI_COUNT)
        .map(|i| (with[i] - base[i] - slope_delta[i]).abs())
        .fold(0.0f64, f64::max);
    eprintln!(
        "X zero δ = {delta} in at X = {x} in: slope × δ up to {largest:.2} µin; deviation {worst:.3} µin; \
         bound {bound:.3} = Taylor {taylor:.3} + ρ·max {:.3} (ρ = {rho:.2e}) + command path {command_path:.3} \
         + scatter {scatter:.3} (pass scatter σ = {finish:.3})",
        rho * largest
    );
    assert!(
        worst <= bound,
        "worst deviation from slope × δ: {worst:.3} µin, bound {bound:.3} µin"
    );
}

/// The digital firmware with the 1983 command generator's mistake (a
/// table whose command has the wrong sign) refuses the table: the slide
/// stays at null and the fault is reported.
#[test]
fn the_digital_firmware_refuses_the_reversed_command_by_its_table_sign_check() {
    let mut s = spec(None);
    s.command_sign = CommandSign::Reversed;
    let (surf, _) = s.surface().unwrap();
    let st = plan(&s, surf.contact_gain()).swap_remove(6);
    let r = run_stretch(&s, &st, &Extras::default(), &|_| {}).unwrap();
    assert!(
        r.faults.iter().any(|f| f.contains("SignCheck")),
        "{:?}",
        r.faults
    );
}
