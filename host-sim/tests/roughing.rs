//! A roughing pass over the open bolt holes (issue 31 item 4, chapter 5's
//! 0.005 .. 0.010 in passes, where the 1983 amplifier tripped on the hole
//! edges): the digital firmware, told the depth (`depth_of_cut_uin`, its
//! edges' contact chord 0.050 in) and the holes (the interruption block),
//! cuts a narrow stretch across the bolt circle 0.010 in deep without a
//! fault, its coil current within the firmware's and the amplifier's
//! limits. The depths `cut` refuses before the pass are
//! `bad_input.rs`'s.
//!
//! Cost: one stretch of about 60 revolutions of machine time (12 s at
//! 300 rpm); docs/CUT.md's roughing rows are the full `cut --depth-in`.

use host_sim::cut::holezone::ZoneMeasured;
use host_sim::cut::{plan, run_stretch, Controller, CutSpec, Extras, Holes, Stretch};

#[test]
fn a_pass_0_010_in_deep_over_open_holes_completes_without_a_fault_within_the_current_limits() {
    let sc = host_sim::scenario::load("legacy-hw").unwrap();
    let mut s = CutSpec::chapter5(sc, Controller::Digital, None, Some(Holes::Open), false).unwrap();
    s.set_depth_in(0.010).unwrap();
    assert_eq!(s.scenario.servo.depth_of_cut_uin, 10_000);
    s.hole_zone = true;
    s.band_half_in = 0.002;
    s.preroll_revs = 20.0;
    let gain = s.surface().unwrap().0.contact_gain();
    let grid = s.zone_grid().unwrap().unwrap();
    let r_b = s.scenario.cutting.bolt_holes.circle_radius_in;
    let c = r_b / gain;
    let (lo, hi) = (c - s.band_half_in, c + s.band_half_in);
    let f = s.feed_per_rev_in;
    let index = plan(&s, gain)
        .into_iter()
        .find(|st| !st.zone.is_empty())
        .unwrap()
        .index;
    let st = Stretch {
        x_start_in: hi + s.preroll_revs * f,
        x_end_in: lo - 2.0 * f,
        windows: vec![],
        zone: vec![(lo, hi)],
        index,
        entry: host_sim::cut::run::Entry::AfterPreroll,
    };
    let r = run_stretch(&s, &st, &Extras::default(), &|_| {}).unwrap();
    let z = ZoneMeasured::measure(&grid, r.log.zone.as_ref().unwrap()).summary();
    let peak = r.log.current_peak_a;
    // The steady thrust's current, closed form: k_t d f + k_e (√(2 r_t d)
    // + f/2) over Kf = (0.2 + 150 · 0.05005) / 2.9 = 2.66 A.
    let cut = &s.scenario.cutting;
    let steady_a = (cut.k_t_psi * 0.010 * f
        + cut.k_e_lbf_per_in * ((2.0 * cut.tool_radius_in * 0.010).sqrt() + f / 2.0))
        / s.scenario.file.motor.kf_lbf_per_a;
    println!(
        "0.010 in, legacy-hw: faults {:?}, coil current peak {peak:.2} A (steady {steady_a:.2} A), \
         worst beyond 0.01 in {:?} µin, {} points",
        r.faults, z.worst_uin[1], z.points
    );
    assert!(r.faults.is_empty(), "{:?}", r.faults);
    assert!(z.points > 1000, "{} points cut", z.points);
    assert!(
        peak > steady_a,
        "the cut's current {peak} A vs steady {steady_a} A"
    );
    assert!(
        peak < s.scenario.servo_design.current_limit_a
            && peak < s.scenario.file.amplifier.current_limit_a,
        "{peak} A"
    );
}
