//! The hole edges' anticipation (`zslide::servo::edges`) on the simulated
//! cut: a narrow stretch of the hole zone across the bolt circle, measured
//! as `cut --json`'s `hole_zone` measures it. With the part program's holes
//! where they are, the finishing pass beyond 0.01 in from the edges is
//! within `legacy-hw`'s ±30 µin goal; with the holes turned a few degrees
//! in the block the firmware gets, the same figure fails the goal.
//!
//! The step the anticipation learns settles on the force model's.
//!
//! Release profile (`cargo test --release -p host-sim --test hole_edges`):
//! two stretches of 25 revolutions of machine time each, and one of 140.

use host_sim::cut::holezone::ZoneMeasured;
use host_sim::cut::{plan, run_stretch, Controller, CutSpec, Extras, Holes, Stretch};

/// The goal of the brief on `legacy-hw`, µin.
const GOAL_UIN: f64 = 30.0;

/// The share of the learned step's error (a fraction of the step the loop
/// is left to meet unanticipated) allowed: a fifth of the goal over what
/// the whole step unanticipated leaves beyond 0.01 in, −95 µin on
/// `legacy-hw` (`host-sim cut --anticipate off --json`,
/// `.hole_zone.worst_uin[1]`, docs/CUT.md): 6/95 ≈ 6.3 %.
const STEP_TOLERANCE: f64 = GOAL_UIN / 5.0 / 95.0;

fn spec() -> CutSpec {
    let sc = host_sim::scenario::load("legacy-hw").unwrap();
    let mut s = CutSpec::chapter5(sc, Controller::Digital, None, Some(Holes::Open), false).unwrap();
    s.hole_zone = true;
    s.band_half_in = 0.002;
    s.preroll_revs = 20.0;
    s
}

/// The stretch across the bolt circle the zone's grid radius nearest it
/// is cut in (the pre-roll the spec asks), and its grid.
fn bolt_circle_stretch(s: &CutSpec) -> (host_sim::cut::StretchResult, ZoneMeasured) {
    let gain = s.surface().unwrap().0.contact_gain();
    let grid = s.zone_grid().unwrap().unwrap();
    let r_b = s.scenario.cutting.bolt_holes.circle_radius_in;
    // The grid radius nearest the bolt circle, its tool-centre window.
    let r = *grid
        .radii
        .iter()
        .min_by(|a, b| (*a - r_b).abs().total_cmp(&(*b - r_b).abs()))
        .unwrap();
    let c = r / gain;
    let (lo, hi) = (c - s.band_half_in, c + s.band_half_in);
    let f = s.feed_per_rev_in;
    let st = plan(s, gain)
        .into_iter()
        .find(|st| !st.zone.is_empty())
        .map(|z| Stretch {
            x_start_in: hi + s.preroll_revs * f,
            x_end_in: lo - 2.0 * f,
            windows: vec![],
            zone: vec![(lo, hi)],
            index: z.index,
            entry: z.entry,
        })
        .unwrap();
    let r = run_stretch(s, &st, &Extras::default(), &|_| {}).unwrap();
    assert!(r.faults.is_empty(), "{:?}", r.faults);
    let m = ZoneMeasured::measure(&grid, r.log.zone.as_ref().unwrap());
    (r, m)
}

/// The worst error (µin) at 0.01 in or more from an edge, over the zone's
/// radii within a few thousandths of the bolt circle.
fn worst_beyond_10_mils(s: &CutSpec) -> (f64, usize) {
    let (_, m) = bolt_circle_stretch(s);
    let z = m.summary();
    // `points` counts the surface points measured (the zone's hole and
    // uncut points are counted apart).
    (z.worst_uin[1].unwrap(), z.points)
}

#[test]
fn the_edges_anticipated_meet_the_goal_and_a_block_three_degrees_off_does_not() {
    let right = spec();
    let (w_right, n) = worst_beyond_10_mils(&right);
    assert!(n > 1000, "{n} points cut");
    let mut wrong = spec();
    wrong.block_angle_error_deg = 3.0;
    let (w_wrong, _) = worst_beyond_10_mils(&wrong);
    println!("worst beyond 0.01 in: holes right {w_right:.1} µin, 3° off {w_wrong:.1} µin");
    assert!(w_right.abs() <= GOAL_UIN, "anticipated: {w_right} µin");
    assert!(w_wrong.abs() > GOAL_UIN, "holes 3° off: {w_wrong} µin");
}

/// The force model's step where the whole contact chord enters a hole, in
/// the amplifier DAC's codes: the thrust of the finishing pass
/// (`CuttingParams::thrust_lbf`) through the motor's force constant and the
/// voltage amplifier's gain into the coil's resistance (at rest: no back
/// EMF), negative (the force on the slide vanishes).
fn model_step_codes(s: &CutSpec) -> f64 {
    let f = &s.scenario.file;
    let amps = s.scenario.cutting.thrust_lbf(s.depth_in, s.feed_per_rev_in) / f.motor.kf_lbf_per_a;
    -amps * f.motor.r_ohm / f.amplifier.gain * zslide::servo::design::DAC_CODES_PER_V
}

/// Over 140 revolutions the learned step comes within [`STEP_TOLERANCE`]
/// of the force model's by the 25th after the band's whole chord is in
/// the stock (its pre-roll runs in the air for a third, then the chord
/// comes in over `ENTRY_RAMP_REVS`) and stays there (it drifted 9 % away
/// when the observer's slow gains measured it).
#[test]
fn the_learned_step_settles_on_the_force_models_step() {
    let mut s = spec();
    s.preroll_revs = 100.0;
    let want = model_step_codes(&s);
    let (r, _) = bolt_circle_stretch(&s);
    let rev_s = 60.0 / s.scenario.file.spindle.rpm;
    let settled: Vec<(f64, f64)> = r
        .edge_steps_q8
        .iter()
        .map(|&(t, a)| (t / rev_s, f64::from(a) / 256.0))
        .filter(|&(rev, _)| {
            rev >= s.preroll_revs / 3.0 + host_sim::cut::run::ENTRY_RAMP_REVS + 25.0
        })
        .collect();
    assert!(
        settled.last().is_some_and(|&(rev, _)| rev > 130.0),
        "{settled:?}"
    );
    for &(rev, a) in &settled {
        println!("rev {rev:5.0}: step {a:7.0} codes, model {want:7.0}");
        assert!(
            (a / want - 1.0).abs() <= STEP_TOLERANCE,
            "rev {rev:.0}: learned {a:.0} codes, the force model's {want:.0} (tolerance {:.1} %)",
            STEP_TOLERANCE * 100.0
        );
    }
}
