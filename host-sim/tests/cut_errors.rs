//! The error sources beyond the loop against their closed forms, each on
//! the digital loop and the low-noise machine (`modern-hw`), holes filled,
//! as the part's grid minus the same seeded run without the source.

use host_sim::cut::errors::{ErrorLevels, Selection};
use host_sim::cut::part::{CmmGrid, CMM_PHI_COUNT, CMM_X_IN};
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
    g.err_uin.iter().map(|row| row[j].unwrap()).collect()
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

#[test]
fn a_constant_x_zero_error_gives_the_slope_times_the_offset() {
    let delta = 0.01;
    let x = 7.0;
    // The band wide enough that the shifted part still covers the point.
    let mut b = spec(None);
    b.band_half_in = 0.012;
    let base = column(&b, x);
    let mut s = spec(Some(ErrorLevels {
        x_zero_error_in: delta,
        ..ErrorLevels::default()
    }));
    s.band_half_in = 0.012;
    let with = column(&s, x);
    let (surf, _) = s.surface().unwrap();
    let sec = surf.section(x / surf.contact_gain()).unwrap();
    let mut worst = 0.0f64;
    let mut largest = 0.0f64;
    for i in 0..CMM_PHI_COUNT {
        let expect = sec.dz_dx(TAU * i as f64 / CMM_PHI_COUNT as f64) * delta * 1e6;
        largest = largest.max(expect.abs());
        worst = worst.max((with[i] - base[i] - expect).abs());
    }
    assert!(largest > 10.0, "the test sees the slope ({largest:.1} µin)");
    // slope × δ reaches ≈ 18 µin; the shifted run reaches the point after
    // 35 revolutions of settling instead of 135 (the loop's own change).
    assert!(
        worst < 2.0,
        "worst deviation from slope × δ: {worst:.2} µin"
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
