//! The simulated finishing pass end to end: the real firmware on the
//! simulated machine with the cutting force applied, measured on the CMM
//! grid. Short bands keep these quick; the figures of the full commands are
//! in docs/CUT.md.

use host_sim::cut::part::{CmmGrid, CMM_X_IN};
use host_sim::cut::{
    check_part_side, plan, run_pass, run_stretch, Controller, CutSpec, Extras, Holes, Stretch,
    StretchResult,
};

fn spec(scenario: &str, holes: Holes) -> CutSpec {
    let sc = host_sim::scenario::load(scenario).unwrap();
    let mut s = CutSpec::chapter5(sc, Controller::Digital, None, Some(holes), false).unwrap();
    s.band_half_in = 0.0015;
    s.preroll_revs = 15.0;
    s
}

/// The band of CMM radius `x_in`.
fn band(s: &CutSpec, x_in: f64) -> Stretch {
    let gain = s.surface().unwrap().0.contact_gain();
    let k = CMM_X_IN.iter().position(|&x| x == x_in).unwrap();
    plan(s, gain).swap_remove(k)
}

fn run(s: &CutSpec, st: &Stretch) -> StretchResult {
    run_stretch(s, st, &Extras::default(), &|_| {}).unwrap()
}

fn grid(s: &CutSpec, r: &StretchResult) -> CmmGrid {
    let (surf, _) = s.surface().unwrap();
    CmmGrid::measure(
        &r.log.passes,
        surf.contact_gain(),
        s.scenario.cutting.tool_radius_in,
        s.feed_per_rev_in,
        |_, _| false,
    )
}

#[test]
fn a_seeded_band_is_bit_identical_when_run_again_and_differs_with_the_seed() {
    let s = spec("legacy-hw", Holes::Filled);
    let st = band(&s, 7.0);
    let a = run(&s, &st);
    let b = run(&s, &st);
    assert!(a.log.passes.by_phi.iter().all(|p| p.len() > 20));
    assert_eq!(a.log.passes.by_phi, b.log.passes.by_phi);
    assert_eq!(a.log.fe_sum_sq.to_bits(), b.log.fe_sum_sq.to_bits());
    let mut other = s.clone();
    other.scenario.rig.seed ^= 1;
    let c = run(&other, &st);
    assert_ne!(a.log.passes.by_phi, c.log.passes.by_phi);
}

#[test]
fn lifting_the_firmware_command_leaves_that_much_excess_stock_on_the_cmm() {
    let s0 = spec("modern-hw", Holes::Filled);
    let st = band(&s0, 5.0);
    let mut s1 = s0.clone();
    s1.z_offset_in = 200e-6;
    let g0 = grid(&s0, &run(&s0, &st));
    let g1 = grid(&s1, &run(&s1, &st));
    for (r0, r1) in g0.err_uin.iter().zip(&g1.err_uin) {
        let d = r1[4].unwrap() - r0[4].unwrap();
        assert!((d - 200.0).abs() < 3.0, "offset read back as {d} µin");
    }
}

#[test]
fn the_cutting_force_on_the_slide_is_the_steady_thrust_along_plus_z() {
    let s = spec("modern-hw", Holes::Filled);
    let r = run(&s, &band(&s, 5.0));
    let mean = r.log.force_sum / r.log.fe_n as f64;
    let steady = s.scenario.cutting.thrust_lbf(s.depth_in, s.feed_per_rev_in);
    assert!(mean > 0.0, "stock on −Z pushes the slide toward +Z");
    assert!(
        (mean - steady).abs() < 0.02 * steady,
        "{mean} vs {steady} lbf"
    );
}

#[test]
fn open_bolt_holes_interrupt_the_force_at_the_bolt_circle_only() {
    let s = spec("modern-hw", Holes::Open);
    // A band on the bolt circle (between the CMM radii 3 and 4 in).
    let r_b = s.scenario.cutting.bolt_holes.circle_radius_in;
    let on_circle = Stretch {
        x_start_in: r_b + s.band_half_in + s.preroll_revs * s.feed_per_rev_in,
        x_end_in: r_b - s.band_half_in - 2.0 * s.feed_per_rev_in,
        windows: vec![(r_b - s.band_half_in, r_b + s.band_half_in)],
        zone: vec![],
        index: 3,
        entry: host_sim::cut::run::Entry::AfterPreroll,
    };
    let at3 = run(&s, &on_circle);
    let at5 = run(&s, &band(&s, 5.0));
    let steady = s.scenario.cutting.thrust_lbf(s.depth_in, s.feed_per_rev_in);
    let m3 = at3.log.force_sum / at3.log.fe_n as f64;
    let m5 = at5.log.force_sum / at5.log.fe_n as f64;
    assert!(
        m3 < 0.9 * steady,
        "holes on the bolt circle remove part of the cut: {m3}"
    );
    assert!(
        (m5 - steady).abs() < 0.02 * steady,
        "no holes at 5 in: {m5}"
    );
}

#[test]
fn a_stock_on_the_plus_z_side_is_refused_naming_the_field() {
    let e = check_part_side(1.0).unwrap_err();
    assert!(format!("{e}").contains("cutting.part_side"), "{e}");
    assert!(check_part_side(-1.0).is_ok());
}

/// The whole default run (a band at every CMM radius) of a scenario and
/// controller, second part (holes filled), CMM band in µin.
fn contour_band(scenario: &str, controller: Controller) -> (f64, f64, Vec<String>) {
    let sc = host_sim::scenario::load(scenario).unwrap();
    let s = CutSpec::chapter5(sc, controller, None, Some(Holes::Filled), false).unwrap();
    let o = run_pass(&s, |_| Extras::default(), &|_| {}).unwrap();
    let all: Vec<f64> = o.grid.err_uin.iter().flatten().flatten().copied().collect();
    assert_eq!(all.len(), 36 * 7, "every grid point measured");
    let lo = all.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = all.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (lo, hi, o.faults)
}

/// Brief §6: the simulated second part within ±30 µin on the 1983 machine
/// (`cargo sim -- --holes filled`: −7.9 .. −0.6 µin) and ±5 µin with the
/// modern gauge (−0.7 .. −0.1, every encoder edge captured as on the
/// NUCLEO), cutting force and its process stiffness on.
#[test]
fn digital_loop_cuts_the_second_part_within_the_brief_goals() {
    let (lo, hi, faults) = contour_band("legacy-hw", Controller::Digital);
    assert!(faults.is_empty(), "{faults:?}");
    assert!(
        lo >= -30.0 && hi <= 30.0,
        "legacy-hw: {lo:.1} .. {hi:.1} µin"
    );
    let (lo, hi, faults) = contour_band("modern-hw", Controller::Digital);
    assert!(faults.is_empty(), "{faults:?}");
    assert!(lo >= -5.0 && hi <= 5.0, "modern-hw: {lo:.1} .. {hi:.1} µin");
}

/// Twice the force model's edge constant (the engaged part a spring of
/// 4350 lbf/in instead of 2185) leaves the second part inside the brief's
/// ±30 µin on `legacy-hw`, with no fault: the learning's low-pass
/// (`learning_lowpass_hz`) keeps it converging against the spring
/// (without it, `learning_lowpass_hz = 0`: a limit cycle, −560 .. −470
/// µin).
#[test]
fn digital_loop_holds_the_band_with_twice_the_edge_force() {
    let mut sc = host_sim::scenario::load("legacy-hw").unwrap();
    sc.cutting.k_e_lbf_per_in *= 2.0;
    let s = CutSpec::chapter5(sc, Controller::Digital, None, Some(Holes::Filled), false).unwrap();
    let o = run_pass(&s, |_| Extras::default(), &|_| {}).unwrap();
    assert!(o.faults.is_empty(), "{:?}", o.faults);
    let (lo, hi) = o.grid.band().unwrap();
    assert!(lo >= -30.0 && hi <= 30.0, "k_e × 2: {lo:.1} .. {hi:.1} µin");
}

/// Three times the edge constant (6515 lbf/in) leaves the second part
/// inside ±30 µin on `legacy-hw`, with no fault: the hum canceller's 45°
/// advance (`hum_notch_turn_deg`) keeps its closed-loop poles damped where
/// the spring moves the crossover onto 120 Hz (with the plain notch,
/// `hum_notch_turn_deg = 0`: a 118..120 Hz ring, −43.8 .. −14.2 µin).
#[test]
fn digital_loop_holds_the_band_with_three_times_the_edge_force() {
    let mut sc = host_sim::scenario::load("legacy-hw").unwrap();
    sc.cutting.k_e_lbf_per_in *= 3.0;
    let s = CutSpec::chapter5(sc, Controller::Digital, None, Some(Holes::Filled), false).unwrap();
    let o = run_pass(&s, |_| Extras::default(), &|_| {}).unwrap();
    assert!(o.faults.is_empty(), "{:?}", o.faults);
    let (lo, hi) = o.grid.band().unwrap();
    assert!(lo >= -30.0 && hi <= 30.0, "k_e × 3: {lo:.1} .. {hi:.1} µin");
}

/// The 1983 loop on the same machine and part leaves errors of the order
/// chapter 5 measured (−500 .. +900 µin on the second part): its following
/// error at the part's 2/rev through the lag-compensated loop (eq 4-47)
/// is hundreds of µin (`cargo sim -- --controller legacy-analog`:
/// −384 .. +403).
#[test]
fn the_1983_loop_leaves_hundreds_of_microinch_on_the_same_part() {
    let (lo, hi, faults) = contour_band("legacy-hw", Controller::LegacyAnalog);
    assert!(faults.is_empty(), "{faults:?}");
    assert!(
        hi - lo > 400.0 && hi - lo < 1400.0,
        "{lo:.0} .. {hi:.0} µin"
    );
}

/// Table 5-1 (the first part, holes open) has a value at every one of its
/// 252 points: the holes' assumed geometry puts no CMM point over a hole.
#[test]
fn no_cmm_grid_point_falls_in_an_open_bolt_hole() {
    for name in ["legacy-hw", "modern-hw"] {
        let sc = host_sim::scenario::load(name).unwrap();
        let mut holes = sc.cutting.bolt_holes.clone();
        holes.filled = false;
        let ring = host_sim::cut::engage::HoleRing::new(&holes);
        for &x in &CMM_X_IN {
            for k in 0..36 {
                let phi = f64::from(k) / 36.0;
                assert!(!ring.over_hole(x, phi), "{name}: X {x} in, φ {}°", 10 * k);
            }
        }
        // ... while the holes are there to be cut over.
        let r_b = sc.cutting.bolt_holes.circle_radius_in;
        let hole_phi = sc.cutting.bolt_holes.phase_deg / 360.0;
        assert!(ring.over_hole(r_b, hole_phi), "{name}");
    }
}
