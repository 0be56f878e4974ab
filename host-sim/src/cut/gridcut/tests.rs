use super::*;
use std::f64::consts::TAU;

const R_T: f64 = 0.125;
const F: f64 = 100e-6;
/// Ticks a turn (not a divisor of any grid angle).
const TICKS: f64 = 3001.0;

/// A nominal that differs between a part angle and its command angle
/// (cos(π − θ) = −cos θ): an angle read in the wrong frame errs by up to
/// 2000 µin.
fn nominal(x: f64, part_turns: f64) -> f64 {
    1e-3 * x * (TAU * part_turns).cos()
}

/// The tool's error at part-frame (x, y), in: a tilt of 2 µin per in and a
/// dip of 30 µin, σ = 0.05 in, centred on (`dip_x`, `dip_y`).
fn error_at(x: f64, y: f64, dip: (f64, f64)) -> f64 {
    let d2 = (x - dip.0).powi(2) + (y - dip.1).powi(2);
    2e-6 * (x + 0.5 * y) - 30e-6 * (-d2 / (2.0 * 0.05f64.powi(2))).exp()
}

/// The pass over each of `grid`'s windows, fed inward at `F` a turn, the
/// slide at the nominal plus `error_at` of the point under the tool (its
/// part angle: `frame::part_turns` of the command angle).
fn logged(grid: &RectGrid, dip: (f64, f64)) -> AngleLog {
    let mut log = AngleLog::of_grid(grid);
    for (lo, hi) in windows(grid, 0.003) {
        let x_start = hi + 3.0 * F;
        let n = ((x_start - lo + 3.0 * F) / F * TICKS) as usize;
        let mut prev = None;
        for k in 0..n {
            let turns = 0.123 + k as f64 / TICKS;
            let x = x_start - F * (turns - 0.123);
            let psi = frame::part_turns(turns.rem_euclid(1.0));
            let (px, py) = (x * (TAU * psi).cos(), x * (TAU * psi).sin());
            let z = nominal(x, psi) + error_at(px, py, dip);
            if let Some(p) = prev {
                log.record(p, (turns, x, z), nominal);
            }
            prev = Some((turns, x, z));
        }
    }
    log
}

/// Every cut point of a 5 × 5 grid reads the error the tool left at that
/// (x, y) (closed form, within the feed cusp f²/8r_t = 0.01 µin and the
/// tick interpolation), so the dip put on one point shows there, 30 µin
/// deep, and nowhere else.
#[test]
fn a_grid_point_reads_the_error_left_at_its_own_x_y_and_a_dip_shows_only_there() {
    let grid = RectGrid::new(5, 5, 0.05, 2.0).unwrap();
    let dip_at = (2f64.sqrt() / 2.0, 2f64.sqrt() / 2.0);
    let m = RectMeasured::measure(&grid, &logged(&grid, dip_at), R_T, F, |_, _| false);
    assert_eq!((m.kind, m.nx, m.ny), ("rectangular", 5, 5));
    let mut cut = 0;
    for p in &m.points {
        let Some(e) = p.error_uin else {
            // Only the corners (on the null circle) and the centre (at
            // the axis, below x_min) are outside.
            assert_eq!(p.absent, Some(Absent::OutsideTheCut), "{p:?}");
            assert!(p.radius_in < 0.05 || p.radius_in > 1.99, "{p:?}");
            continue;
        };
        cut += 1;
        let expect = error_at(p.x_in, p.y_in, dip_at) * 1e6;
        assert!(
            (e - expect).abs() < 0.05,
            "({}, {}): read {e} µin, left {expect}",
            p.x_in,
            p.y_in
        );
        let on_dip = (p.x_in - dip_at.0).abs() < 1e-9 && (p.y_in - dip_at.1).abs() < 1e-9;
        assert_eq!(e < -25.0, on_dip, "({}, {}): {e}", p.x_in, p.y_in);
    }
    assert_eq!(cut, 25 - 5);
}

/// A point with no pass on both sides is reported as not cut, and one
/// over an open hole as in a hole; neither is given a value.
#[test]
fn uncovered_and_hole_points_are_reported_absent_with_the_reason() {
    let grid = RectGrid::new(5, 5, 0.05, 2.0).unwrap();
    let empty = AngleLog::of_grid(&grid);
    let m = RectMeasured::measure(&grid, &empty, R_T, F, |_, _| false);
    assert!(m.points.iter().all(|p| p.error_uin.is_none()));
    assert_eq!(
        m.points
            .iter()
            .filter(|p| p.absent == Some(Absent::NotCut))
            .count(),
        20
    );
    let log = logged(&grid, (9.0, 9.0));
    let m = RectMeasured::measure(&grid, &log, R_T, F, |x, phi| {
        (x - 1.0).abs() < 1e-9 && (phi - 45.0).abs() < 1e-9
    });
    let p = m
        .points
        .iter()
        .find(|p| (p.phi_deg - 45.0).abs() < 1e-9 && (p.radius_in - 1.0).abs() < 1e-9)
        .unwrap();
    assert_eq!((p.error_uin, p.absent), (None, Some(Absent::InAHole)));
    assert_eq!(m.band().map(|b| b.0 < -1.0), Some(true));
}

/// Overlapping windows are merged into one (one stretch per radius).
#[test]
fn windows_around_the_grid_radii_merge_where_they_overlap() {
    let grid = RectGrid::new(5, 5, 0.05, 2.0).unwrap();
    // Radii √2/2, 1, √2, √(5/2): 0.707, 1.0, 1.414, 1.581.
    let w = windows(&grid, 0.1);
    assert_eq!(w.len(), 3, "{w:?}");
    assert!((w[2].0 - (2f64.sqrt() - 0.1)).abs() < 1e-12);
    assert!((w[2].1 - (2.5f64.sqrt() + 0.1)).abs() < 1e-12);
    assert_eq!(windows(&grid, 0.001).len(), 4);
}
