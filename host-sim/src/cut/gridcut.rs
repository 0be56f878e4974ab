//! `cut --part P --grid NX,NY`: the part measured on a rectangular grid
//! (`rectgrid`) instead of the polar CMM grid.
//!
//! The same measurement as the polar grid's, at other points: the cutter
//! logs the tool centre (slide carriage plus every applied error source's
//! tool offset: the same `z` the polar log takes) each time the part angle
//! of a grid point passes under the tool, interpolated between the two
//! ticks that straddle it, and the error of a point is the envelope of the
//! nose arcs of those passes at the point's radius
//! (`part::envelope_error`, the polar grid's). The recording windows are
//! put around the grid's radii (`windows`), so every cut point is
//! surrounded by passes; a point no pass covers on both sides is reported
//! as not cut, never filled in.

use super::frame;
use super::part::{envelope_error, finish_rms, Pass};
use super::rectgrid::RectGrid;

/// Two part angles closer than this (turns) are one logged angle.
const SAME_ANGLE_TURNS: f64 = 1e-12;

/// The passes at the grid's part angles.
#[derive(Clone, Debug, Default)]
pub struct AngleLog {
    /// Command angle of each logged angle (turns, 0..1), ascending, and the
    /// index of the angle it logs.
    crossings: Vec<(f64, usize)>,
    /// Part angle (turns) of each logged angle.
    pub part_turns: Vec<f64>,
    /// Every revolution's pass at each logged angle.
    pub by_angle: Vec<Vec<Pass>>,
}

impl AngleLog {
    /// Logs at these part angles (turns, 0..1).
    pub fn new(part_angles: &[f64]) -> Self {
        let mut part_turns: Vec<f64> = Vec::new();
        for &a in part_angles {
            if !part_turns
                .iter()
                .any(|&b: &f64| (a - b).abs() < SAME_ANGLE_TURNS)
            {
                part_turns.push(a);
            }
        }
        let mut crossings: Vec<(f64, usize)> = part_turns
            .iter()
            .enumerate()
            .map(|(i, &p)| (frame::part_turns(p), i))
            .collect();
        crossings.sort_by(|a, b| a.0.total_cmp(&b.0));
        Self {
            crossings,
            by_angle: vec![Vec::new(); part_turns.len()],
            part_turns,
        }
    }

    /// The angles of `grid`'s cut points.
    pub fn of_grid(grid: &RectGrid) -> Self {
        let a: Vec<f64> = grid.cut_points().map(|p| p.phi_turns).collect();
        Self::new(&a)
    }

    /// Index of the logged angle of part angle `turns`.
    pub fn index_of(&self, turns: f64) -> Option<usize> {
        self.part_turns
            .iter()
            .position(|&b| (turns - b).abs() < SAME_ANGLE_TURNS)
    }

    /// The tool moved from `(turns0, x0, z0)` to `(turns, x, z)` (command
    /// angle unwrapped, turns; tool-centre X and Z, in) in one tick: logs
    /// every logged angle crossed in `(turns0, turns]`, its error against
    /// `nominal(x, part_turns)`.
    pub fn record(
        &mut self,
        (turns0, x0, z0): (f64, f64, f64),
        (turns, x, z): (f64, f64, f64),
        nominal: impl Fn(f64, f64) -> f64,
    ) {
        if turns <= turns0 {
            return;
        }
        let m0 = crate::fastmath::floor_i64(turns0);
        let m1 = crate::fastmath::floor_i64(turns);
        for m in m0..=m1 {
            let (lo, hi) = (turns0 - m as f64, turns - m as f64);
            let first = self.crossings.partition_point(|c| c.0 <= lo);
            for &(c, i) in &self.crossings[first..] {
                if c > hi {
                    break;
                }
                let tc = m as f64 + c;
                let w = (tc - turns0) / (turns - turns0);
                let xc = x0 + (x - x0) * w;
                let zc = z0 + (z - z0) * w;
                let e = zc - nominal(xc, self.part_turns[i]);
                self.by_angle[i].push(Pass { x_in: xc, e_in: e });
            }
        }
    }

    pub fn merge(&mut self, other: AngleLog) {
        for (a, b) in self.by_angle.iter_mut().zip(other.by_angle) {
            a.extend(b);
        }
    }
}

/// Why a grid point has no error.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Absent {
    /// Outside `x_min ≤ X < x_null` (the table nulls the slide there).
    OutsideTheCut,
    /// Over an open bolt hole (the probe cannot touch it).
    InAHole,
    /// No pass on both sides within the simulated windows.
    NotCut,
}

/// One point of the measured rectangular grid (a JSON row).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PointError {
    pub x_in: f64,
    pub y_in: f64,
    /// Tool-centre radius and part angle of the point.
    pub radius_in: f64,
    pub phi_deg: f64,
    /// µin, positive = excess stock (the polar grid's sign).
    pub error_uin: Option<f64>,
    /// Profilometer RMS of the radial trace through the point, µin (the
    /// polar grid's `finish_rms`).
    pub finish_uin: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub absent: Option<Absent>,
}

/// The measured rectangular grid.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RectMeasured {
    /// Always `"rectangular"` (the polar grid is `cmm_grid_uin`).
    pub kind: &'static str,
    pub nx: usize,
    pub ny: usize,
    /// Row-major, y the slow index (as `RectGrid::points`).
    pub points: Vec<PointError>,
}

impl RectMeasured {
    /// Measures `grid` from `log` (tool-centre radii: contact gain 1),
    /// with the polar grid's envelope and the same nose and feed.
    /// `in_open_hole(X, φ_deg)` as `CmmGrid::measure_at`'s.
    pub fn measure(
        grid: &RectGrid,
        log: &AngleLog,
        r_t: f64,
        feed_in: f64,
        in_open_hole: impl Fn(f64, f64) -> bool,
    ) -> Self {
        let points = grid
            .points
            .iter()
            .flatten()
            .map(|p| {
                let phi_deg = p.phi_turns * 360.0;
                let passes = log
                    .index_of(p.phi_turns)
                    .map_or(&[][..], |i| &log.by_angle[i][..]);
                let (error_uin, absent) = if !p.cut {
                    (None, Some(Absent::OutsideTheCut))
                } else if in_open_hole(p.radius_in, phi_deg) {
                    (None, Some(Absent::InAHole))
                } else {
                    match envelope_error(passes, p.radius_in, r_t, feed_in) {
                        Some(e) => (Some(e * 1e6), None),
                        None => (None, Some(Absent::NotCut)),
                    }
                };
                let finish_uin = error_uin
                    .and_then(|_| finish_rms(passes, p.radius_in, r_t, feed_in))
                    .map(|f| f * 1e6);
                PointError {
                    x_in: p.x_in,
                    y_in: p.y_in,
                    radius_in: p.radius_in,
                    phi_deg,
                    error_uin,
                    finish_uin,
                    absent,
                }
            })
            .collect();
        Self {
            kind: "rectangular",
            nx: grid.x_in.len(),
            ny: grid.y_in.len(),
            points,
        }
    }

    /// (min, max) over the measured points, µin.
    pub fn band(&self) -> Option<(f64, f64)> {
        self.points
            .iter()
            .filter_map(|p| p.error_uin)
            .fold(None, |b, e| match b {
                None => Some((e, e)),
                Some((lo, hi)) => Some((lo.min(e), hi.max(e))),
            })
    }
}

impl RectMeasured {
    /// RMS of the points' finish, µin.
    pub fn finish_rms_uin(&self) -> Option<f64> {
        let v: Vec<f64> = self.points.iter().filter_map(|p| p.finish_uin).collect();
        (!v.is_empty()).then(|| (v.iter().map(|f| f * f).sum::<f64>() / v.len() as f64).sqrt())
    }
}

/// The grid as text: y rows (top = +y), x columns, µin; `-` outside the
/// cut, `hole` over an open hole, `uncut` where no pass covers the point.
pub fn table(m: &RectMeasured) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "rectangular grid {} x {}: contour error, µin (positive = excess stock; y rows, x columns, in)",
        m.nx, m.ny
    );
    let _ = write!(out, "{:>9}", "y\\x");
    for p in &m.points[..m.nx] {
        let _ = write!(out, "{:>9.3}", p.x_in);
    }
    out.push('\n');
    for row in m.points.chunks(m.nx).rev() {
        let _ = write!(out, "{:>9.3}", row[0].y_in);
        for p in row {
            let cell = match (p.error_uin, p.absent) {
                (Some(e), _) => format!("{e:.2}"),
                (None, Some(Absent::InAHole)) => "hole".into(),
                (None, Some(Absent::NotCut)) => "uncut".into(),
                (None, _) => "-".into(),
            };
            let _ = write!(out, "{cell:>9}");
        }
        out.push('\n');
    }
    out
}

/// Writes `<dir>/grid_error.csv`: one row a point, empty where absent.
pub fn write_csv(dir: &std::path::Path, m: &RectMeasured) -> anyhow::Result<()> {
    let path = dir.join("grid_error.csv");
    let mut out = String::from("x_in,y_in,radius_in,phi_deg,error_uin,finish_uin,absent\n");
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v}"));
    for p in &m.points {
        let absent = match p.absent {
            None => "",
            Some(Absent::OutsideTheCut) => "outside-the-cut",
            Some(Absent::InAHole) => "in-a-hole",
            Some(Absent::NotCut) => "not-cut",
        };
        out += &format!(
            "{},{},{},{},{},{},{absent}\n",
            p.x_in,
            p.y_in,
            p.radius_in,
            p.phi_deg,
            opt(p.error_uin),
            opt(p.finish_uin)
        );
    }
    crate::outpath::replace(&path, out)
}

/// Recording windows (tool-centre X, in) around the grid's cut radii,
/// `half` either side, overlapping ones merged (one stretch cuts a radius
/// once: two simulations of the same X would be two different parts).
pub fn windows(grid: &RectGrid, half: f64) -> Vec<(f64, f64)> {
    let mut r: Vec<f64> = grid.cut_points().map(|p| p.radius_in).collect();
    r.sort_by(f64::total_cmp);
    let mut out: Vec<(f64, f64)> = Vec::new();
    for x in r {
        match out.last_mut() {
            Some(w) if x - half <= w.1 => w.1 = w.1.max(x + half),
            _ => out.push((x - half, x + half)),
        }
    }
    out
}

#[cfg(test)]
mod tests;
