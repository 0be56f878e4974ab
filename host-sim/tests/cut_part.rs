//! `cut --part` end to end on an example part (tables/sinusoidal-grid:
//! not symmetric under the firmware's angle map, so a table in the wrong
//! frame cuts its mirror image): the real firmware running the committed
//! table on modern-hw, measured on the polar grid and on a rectangular
//! one, and `plan`'s predicted following error against the cut's.

use host_sim::cut::gridcut::{AngleLog, RectMeasured};
use host_sim::cut::part::CmmGrid;
use host_sim::cut::rectgrid::RectGrid;
use host_sim::cut::{plan, run_pass, run_stretch, Controller, CutSpec, Extras};
use std::path::Path;
use std::sync::Arc;

fn part_file() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tables/sinusoidal-grid.toml")
}

/// The chapter 5 pass of the example part on modern-hw, its committed table.
fn spec() -> CutSpec {
    let sc = host_sim::scenario::load("modern-hw").unwrap();
    let mut s = CutSpec::chapter5(sc, Controller::Digital, None, None, false).unwrap();
    let table = part_file().with_extension("zsct");
    s.part = Some(host_sim::cmd::parttable::part_cut(&part_file(), Some(&table)).unwrap());
    s
}

/// One cut of the band at the null circle's inscribed square's half side
/// (a 3 × 3 grid: its four cut points on the axes, at 0°, 90°, 180°, 270°,
/// which are also polar CMM angles). Both grids are read from the same
/// passes: the rectangular grid's at its points, the polar grid's at all
/// 36 angles of that radius.
#[test]
fn grid_points_on_polar_angles_read_what_the_polar_grid_reads_and_the_part_is_within_the_tools_path(
) {
    let mut s = spec();
    s.band_half_in = 0.0015;
    s.preroll_revs = 60.0;
    let p = s.part.clone().unwrap();
    let grid = Arc::new(RectGrid::new(3, 3, p.x_min, p.x_null).unwrap());
    s.grid = Some(grid.clone());
    // The plan's last stretch is the pass's rim (`Entry::Rim`): not a band.
    let stretches: Vec<_> = plan(&s, 1.0)
        .into_iter()
        .filter(|st| !matches!(st.entry, host_sim::cut::run::Entry::Rim(_)))
        .collect();
    assert_eq!(stretches.len(), 1, "four points on one radius: one band");
    let r = run_stretch(&s, &stretches[0], &Extras::default(), &|_| {}).unwrap();
    assert!(r.faults.is_empty(), "{:?}", r.faults);
    let (r_t, f) = (s.scenario.cutting.tool_radius_in, s.feed_per_rev_in);
    let radius = p.x_null / 2f64.sqrt();
    let polar = CmmGrid::measure_at(&r.log.passes, &[radius], 1.0, r_t, f, |_, _| false);
    let log: &AngleLog = r.log.grid.as_ref().unwrap();
    let rect = RectMeasured::measure(&grid, log, r_t, f, |_, _| false);
    let mut compared = 0;
    for pt in &rect.points {
        let Some(e) = pt.error_uin else { continue };
        let row = (pt.phi_deg / 10.0).round() as usize % 36;
        let q = polar.err_uin[row][0].unwrap();
        assert!(
            (e - q).abs() < 1e-6,
            "({}, {}) at {}°: grid {e} µin, polar {q} µin",
            pt.x_in,
            pt.y_in,
            pt.phi_deg
        );
        compared += 1;
    }
    assert_eq!(compared, 4);
    // The whole circle on the polar grid, held to what the tool's path
    // can leave (host_sim::cut::part, "The envelope"): err(x, φ) =
    // min_j [e_j + arc_j] with every pass's error |e_j| ≤ the stretch's
    // peak following error and the arcs ≥ 0, the nearest pass's (at most
    // half a feed away) ≤ the cusp r_t − √(r_t² − f²/4). So
    // −peak ≤ err ≤ peak + cusp. A mirrored table would leave up to twice
    // the surface's ±200 µin here.
    let (lo, hi) = polar.band().unwrap();
    let peak = r.log.fe_peak * 1e6;
    let cusp = (r_t - (r_t * r_t - f * f / 4.0).sqrt()) * 1e6;
    eprintln!("{lo:.3} .. {hi:.3} µin at X = {radius}: within −{peak:.3} .. {peak:.3} + {cusp:.3}");
    assert!(
        lo >= -peak && hi <= peak + cusp,
        "{lo:.3} .. {hi:.3} µin at X = {radius}: beyond −{peak:.3} .. {peak:.3} + the cusp {cusp:.3} µin"
    );
}

/// docs/PARTS.md: `plan` predicts the loop's following error from feedback
/// alone (no feedforward, no learning), so it is an upper estimate, at
/// most 20 times the cut's peak following error on the example parts.
/// Checked here on the sinusoidal grid: cut's peak ≤ plan's ≤ 20 × cut's
/// (2.7× in issue 33's review). Only the lower side is derived: the
/// cut's error is what the feedforward and the learning leave plus the
/// noise, which `plan` does not model, so no lower bound on it, and no
/// upper bound on the ratio, follows from plan's inputs; the 20 is
/// PARTS.md's stated claim, checked as stated.
#[test]
fn plan_predicted_following_error_bounds_the_cut_within_the_stated_factor() {
    let lp = host_sim::part::config::load_part(&part_file()).unwrap();
    let sc = host_sim::scenario::load("modern-hw").unwrap();
    let sections = host_sim::part::plan::sections(&lp, 33).unwrap();
    let sens = host_sim::cmd::plan::measure_sensitivity(&sc);
    let machine = host_sim::part::plan::Machine::of(&sc);
    let predicted =
        host_sim::part::plan::plan(&lp, &sections, &machine, sc.file.spindle.rpm, &|f| {
            sens.at(f)
        })
        .predicted_error_peak_uin;
    let mut s = spec();
    s.band_half_in = 0.0015;
    let o = run_pass(&s, |_| Extras::default(), &|_| {}).unwrap();
    assert!(o.faults.is_empty(), "{:?}", o.faults);
    let cut = o.following_error_peak_uin;
    eprintln!("plan {predicted:.3} µin, cut {cut:.3} µin peak");
    assert!(
        cut <= predicted && predicted <= 20.0 * cut,
        "plan predicts {predicted:.3} µin, the cut's peak is {cut:.3} µin"
    );
}
