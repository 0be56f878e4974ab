//! The hole zone: the surface around the bolt circle on a dense grid,
//! measured like the CMM grid (the envelope of the nose arcs, `part`), and
//! the error by distance from the nearest hole edge.
//!
//! * **The grid** (part frame, like the CMM's): surface radii across the
//!   ring from `MARGIN_IN` inside the holes to `MARGIN_IN` outside them, at
//!   most `MAX_DR_IN` apart; `PHI_COUNT` angles (0.25°). A point over an
//!   open hole is "hole" (no surface).
//! * **Distance from an edge**: the distance in the plane from the point to
//!   the nearest hole's rim (`|p − c_k| − ρ`; inside a filled hole its
//!   magnitude).
//! * **Leading / trailing**: the part turns in +φ, so the tool runs over
//!   it toward −φ (`frame`). A point at a larger angle than its nearest
//!   hole's centre is passed before the hole: the **leading** side, where
//!   the nose runs into the hole and the cut stops. A point at a smaller
//!   angle is passed after it: the **trailing** side, where the nose comes
//!   out of the hole and the force returns.
//! * **The runs**: band stretches at every grid radius (`cut --band-in`
//!   either side, with `--preroll-revs` before each, as the CMM radii have);
//!   with the default band the windows merge into a few continuous
//!   stretches that cover the whole ring.

use super::frame;
use super::part::Envelope;
use crate::plant::cutting::BoltHoles;
use std::f64::consts::TAU;

/// Angles around the circle (0.25°).
pub const PHI_COUNT: usize = 1440;
/// How far the grid reaches inside and outside the holes' radii, in.
pub const MARGIN_IN: f64 = 0.1;
/// Largest radial spacing of the grid, in.
pub const MAX_DR_IN: f64 = 0.01;
/// The distances from an edge the report gives the worst error beyond, in.
pub const BEYOND_IN: [f64; 4] = [0.005, 0.01, 0.02, 0.05];
/// Longest stretch of the zone's runs (tool-centre X, in): the ring is cut
/// in several stretches so that they run in parallel.
const CHUNK_IN: f64 = 0.2;

/// The zone's grid and where its points lie relative to the holes.
#[derive(Clone, Debug)]
pub struct ZoneGrid {
    /// Surface radii, in, ascending and evenly spaced.
    pub radii: Vec<f64>,
    /// Surface radius over tool-centre radius (`CutSpec::contact_gain`).
    pub contact_gain: f64,
    holes: BoltHoles,
}

/// Where a grid point lies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Place {
    /// Over an open hole (no surface).
    pub in_hole: bool,
    /// Distance from the nearest hole's rim, in (≥ 0).
    pub edge_in: f64,
    /// On the leading side of its nearest hole (see the module doc).
    pub leading: bool,
}

impl ZoneGrid {
    /// The zone of the part's bolt holes (part frame); `None` where the
    /// part has no holes or the ring does not fit on a part of radius
    /// `part_radius_in`.
    pub fn new(holes: &BoltHoles, contact_gain: f64, part_radius_in: f64) -> Option<Self> {
        if holes.count == 0 || holes.diameter_in <= 0.0 {
            return None;
        }
        let rho = holes.diameter_in / 2.0;
        let lo = (holes.circle_radius_in - rho - MARGIN_IN).max(MAX_DR_IN);
        let hi = (holes.circle_radius_in + rho + MARGIN_IN).min(part_radius_in);
        if hi <= lo {
            return None;
        }
        let n = ((hi - lo) / MAX_DR_IN).ceil() as usize + 1;
        let radii = (0..n)
            .map(|j| lo + (hi - lo) * j as f64 / (n - 1) as f64)
            .collect();
        Some(Self {
            radii,
            contact_gain,
            holes: holes.clone(),
        })
    }

    pub fn phi_deg(i: usize) -> f64 {
        360.0 * i as f64 / PHI_COUNT as f64
    }

    /// The holes' centres, degrees of the part frame.
    pub fn hole_deg(&self) -> Vec<f64> {
        (0..self.holes.count)
            .map(|k| self.holes.phase_deg + 360.0 * f64::from(k) / f64::from(self.holes.count))
            .collect()
    }

    pub fn holes(&self) -> &BoltHoles {
        &self.holes
    }

    /// Where the point at surface radius `r`, part angle `phi_deg` lies.
    pub fn place(&self, r: f64, phi_deg: f64) -> Place {
        let rho = self.holes.diameter_in / 2.0;
        let (x, y) = (
            r * phi_deg.to_radians().cos(),
            r * phi_deg.to_radians().sin(),
        );
        let mut best = (f64::INFINITY, 0.0);
        for a in self.hole_deg() {
            let (hx, hy) = (
                self.holes.circle_radius_in * a.to_radians().cos(),
                self.holes.circle_radius_in * a.to_radians().sin(),
            );
            let d = ((x - hx).powi(2) + (y - hy).powi(2)).sqrt();
            if d < best.0 {
                best = (d, (phi_deg - a + 180.0).rem_euclid(360.0) - 180.0);
            }
        }
        // `BoltHoles::over_hole`'s test (strictly inside the rim).
        let in_hole = !self.holes.filled && best.0 * best.0 < rho * rho;
        Place {
            in_hole,
            edge_in: (best.0 - rho).abs(),
            leading: best.1 > 0.0,
        }
    }

    /// Tool-centre windows of the zone's runs: `band_half_in` either side
    /// of every grid radius's contact, merged where they overlap and cut
    /// into stretches of at most `CHUNK_IN`, outermost first.
    pub fn windows(&self, band_half_in: f64) -> Vec<(f64, f64)> {
        let mut merged: Vec<(f64, f64)> = Vec::new();
        for &r in self.radii.iter().rev() {
            let c = r / self.contact_gain;
            let (lo, hi) = (c - band_half_in, c + band_half_in);
            match merged.last_mut() {
                Some(w) if hi >= w.0 => w.0 = w.0.min(lo),
                _ => merged.push((lo, hi)),
            }
        }
        let mut out = Vec::new();
        for (lo, hi) in merged {
            let n = ((hi - lo) / CHUNK_IN).ceil().max(1.0) as usize;
            for k in 0..n {
                let top = hi - (hi - lo) * k as f64 / n as f64;
                let bottom = hi - (hi - lo) * (k + 1) as f64 / n as f64;
                out.push((bottom, top));
            }
        }
        out
    }
}

/// The nose arcs' envelope at every grid point, accumulated pass by pass
/// while a stretch runs (the passes themselves are not kept: 1440 angles
/// over the ring would be millions).
#[derive(Clone, Debug)]
pub struct ZoneLog {
    /// Tool-centre radii of the grid's contacts, ascending.
    xc: Vec<f64>,
    r_t: f64,
    feed_in: f64,
    /// `[φ index × radii + radius index]`.
    env: Vec<Envelope>,
    /// Recording windows (tool-centre X), in.
    windows: Vec<(f64, f64)>,
    /// (turns, x, z) at the last recorded tick.
    pub prev: Option<(f64, f64, f64)>,
}

impl ZoneLog {
    pub fn new(grid: &ZoneGrid, r_t: f64, feed_in: f64, windows: Vec<(f64, f64)>) -> Self {
        Self {
            xc: grid.radii.iter().map(|r| r / grid.contact_gain).collect(),
            r_t,
            feed_in,
            env: vec![Envelope::default(); grid.radii.len() * PHI_COUNT],
            windows,
            prev: None,
        }
    }

    pub fn recording(&self, x: f64) -> bool {
        self.windows.iter().any(|&(lo, hi)| x >= lo && x <= hi)
    }

    /// The tool centre at `x_in` with error `e_in` passing part angle
    /// index `i`: its nose arc at every grid radius within the nose's
    /// reach.
    pub fn add(&mut self, i: usize, x_in: f64, e_in: f64) {
        let n = self.xc.len();
        let (lo, hi) = (x_in - self.r_t, x_in + self.r_t);
        let from = self.xc.partition_point(|&c| c <= lo);
        let row = &mut self.env[i * n..(i + 1) * n];
        for (j, &c) in self.xc.iter().enumerate().skip(from) {
            if c >= hi {
                break;
            }
            row[j].add(x_in - c, e_in, self.r_t, self.feed_in);
        }
    }

    /// Another stretch's arcs over the same grid.
    pub fn merge(&mut self, other: &ZoneLog) {
        for (a, b) in self.env.iter_mut().zip(&other.env) {
            a.merge(b);
        }
    }

    /// The command angles `k` (of `PHI_COUNT` a turn) crossed between two
    /// ticks, with their part-frame index (the CMM recording's rule).
    pub fn crossings(turns0: f64, turns1: f64) -> impl Iterator<Item = (i64, usize)> {
        let n = PHI_COUNT as f64;
        let k0 = crate::fastmath::floor_i64(turns0 * n);
        let k1 = crate::fastmath::floor_i64(turns1 * n);
        ((k0 + 1)..=k1).map(|k| (k, frame::part_index(k, PHI_COUNT)))
    }
}

/// The measured zone.
#[derive(Clone, Debug)]
pub struct ZoneMeasured {
    pub grid: ZoneGrid,
    /// `[φ index][radius index]`, µin (positive = excess stock); `None`
    /// over an open hole or where the point was not cut.
    pub err_uin: Vec<Vec<Option<f64>>>,
    pub place: Vec<Vec<Place>>,
}

/// The zone's figures (`cut --json`'s `hole_zone`).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct HoleZone {
    /// Distances from the nearest hole edge, in.
    pub beyond_in: Vec<f64>,
    /// For each distance: the error of largest magnitude at that distance
    /// or more from the nearest edge, signed, µin.
    pub worst_uin: Vec<Option<f64>>,
    /// The same over the leading sides (the nose runs into the hole).
    pub leading_worst_uin: Vec<Option<f64>>,
    /// The same over the trailing sides (the nose comes out of the hole).
    pub trailing_worst_uin: Vec<Option<f64>>,
    /// Surface points measured in the zone.
    pub points: usize,
    /// Points over an open hole, and points not cut by the runs.
    pub hole_points: usize,
    pub uncut_points: usize,
    /// The worst error nearer than the first distance, µin.
    pub closest_worst_uin: Option<f64>,
    /// The grid: radii (surface, in) and angular step (deg).
    pub radius_min_in: f64,
    pub radius_max_in: f64,
    pub radius_step_in: f64,
    pub phi_step_deg: f64,
    /// The holes as cut: count, bolt circle, diameter, first angle (part
    /// frame), filled.
    pub holes: BoltHoles,
}

impl ZoneMeasured {
    pub fn measure(grid: &ZoneGrid, log: &ZoneLog) -> Self {
        let n = grid.radii.len();
        let mut err_uin = Vec::with_capacity(PHI_COUNT);
        let mut place = Vec::with_capacity(PHI_COUNT);
        for i in 0..PHI_COUNT {
            let phi = ZoneGrid::phi_deg(i);
            let p: Vec<Place> = grid.radii.iter().map(|&r| grid.place(r, phi)).collect();
            err_uin.push(
                (0..n)
                    .map(|j| {
                        if p[j].in_hole {
                            None
                        } else {
                            log.env[i * n + j].value().map(|e| e * 1e6)
                        }
                    })
                    .collect(),
            );
            place.push(p);
        }
        Self {
            grid: grid.clone(),
            err_uin,
            place,
        }
    }

    pub fn summary(&self) -> HoleZone {
        let worst = |keep: &dyn Fn(&Place) -> bool, beyond: f64, nearer: bool| {
            let mut w: Option<f64> = None;
            for (row, prow) in self.err_uin.iter().zip(&self.place) {
                for (e, p) in row.iter().zip(prow) {
                    let at = if nearer {
                        p.edge_in < beyond
                    } else {
                        p.edge_in >= beyond
                    };
                    if let Some(e) = e {
                        if at && keep(p) && w.is_none_or(|v| e.abs() > v.abs()) {
                            w = Some(*e);
                        }
                    }
                }
            }
            w
        };
        let all = |_: &Place| true;
        let lead = |p: &Place| p.leading;
        let trail = |p: &Place| !p.leading;
        let cells = self
            .place
            .iter()
            .flatten()
            .zip(self.err_uin.iter().flatten());
        let hole_points = cells.clone().filter(|(p, _)| p.in_hole).count();
        let points = cells.clone().filter(|(_, e)| e.is_some()).count();
        let r = &self.grid.radii;
        HoleZone {
            beyond_in: BEYOND_IN.to_vec(),
            worst_uin: BEYOND_IN.iter().map(|&b| worst(&all, b, false)).collect(),
            leading_worst_uin: BEYOND_IN.iter().map(|&b| worst(&lead, b, false)).collect(),
            trailing_worst_uin: BEYOND_IN.iter().map(|&b| worst(&trail, b, false)).collect(),
            points,
            hole_points,
            uncut_points: cells.count() - points - hole_points,
            closest_worst_uin: worst(&all, BEYOND_IN[0], true),
            radius_min_in: r[0],
            radius_max_in: r[r.len() - 1],
            radius_step_in: (r[r.len() - 1] - r[0]) / (r.len() - 1) as f64,
            phi_step_deg: 360.0 / PHI_COUNT as f64,
            holes: self.grid.holes.clone(),
        }
    }
}

/// The hole zone's line of the summary.
pub fn summary_line(z: &HoleZone) -> String {
    let f = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:+.1}"));
    let by: Vec<String> = z
        .beyond_in
        .iter()
        .zip(&z.worst_uin)
        .zip(z.leading_worst_uin.iter().zip(&z.trailing_worst_uin))
        .map(|((b, w), (l, t))| format!("≥{b} in {} (lead {}, trail {})", f(*w), f(*l), f(*t)))
        .collect();
    format!(
        "worst error by distance from a hole edge, µin: {}; nearer {}; {} points, {} in holes{}",
        by.join(", "),
        f(z.closest_worst_uin),
        z.points,
        z.hole_points,
        if z.uncut_points > 0 {
            format!(", {} NOT CUT", z.uncut_points)
        } else {
            String::new()
        }
    )
}

/// The hole's outline at surface radius `r`: the angular half-width, deg
/// (`None` off the hole's annulus), for the plot.
pub fn half_width_deg(h: &BoltHoles, r: f64) -> Option<f64> {
    let rho = h.diameter_in / 2.0;
    let rb = h.circle_radius_in;
    if (r - rb).abs() >= rho || r <= 0.0 {
        return None;
    }
    let c = (r * r + rb * rb - rho * rho) / (2.0 * r * rb);
    Some(c.clamp(-1.0, 1.0).acos() * 360.0 / TAU)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn holes(filled: bool) -> BoltHoles {
        BoltHoles {
            filled,
            ..BoltHoles::default()
        }
    }

    #[test]
    fn the_grid_spans_the_ring_with_its_margins_at_the_stated_spacing() {
        let g = ZoneGrid::new(&holes(false), 1.0, 7.25).unwrap();
        let h = holes(false);
        let rho = h.diameter_in / 2.0;
        assert!((g.radii[0] - (h.circle_radius_in - rho - 0.1)).abs() < 1e-12);
        let last = *g.radii.last().unwrap();
        assert!((last - (h.circle_radius_in + rho + 0.1)).abs() < 1e-12);
        for w in g.radii.windows(2) {
            assert!(w[1] - w[0] <= MAX_DR_IN + 1e-12);
        }
        assert!(360.0 / PHI_COUNT as f64 <= 0.25);
    }

    #[test]
    fn distance_and_side_of_points_around_a_hole_on_its_circle() {
        let h = holes(false);
        let g = ZoneGrid::new(&h, 1.0, 7.25).unwrap();
        let rb = h.circle_radius_in;
        let rho = h.diameter_in / 2.0;
        // On the bolt circle, the angle a chord of length ρ + 0.02 from the
        // centre: 0.02 in outside the rim, either side.
        let da = (2.0 * ((rho + 0.02) / (2.0 * rb)).asin()).to_degrees();
        let after = g.place(rb, h.phase_deg + da);
        assert!(!after.in_hole && after.leading);
        assert!((after.edge_in - 0.02).abs() < 1e-9, "{after:?}");
        let before = g.place(rb, h.phase_deg - da);
        assert!(!before.leading && (before.edge_in - 0.02).abs() < 1e-9);
        let centre = g.place(rb, h.phase_deg);
        assert!(centre.in_hole && (centre.edge_in - rho).abs() < 1e-9);
        // A filled hole has a surface over it.
        let gf = ZoneGrid::new(&holes(true), 1.0, 7.25).unwrap();
        assert!(!gf.place(rb, h.phase_deg).in_hole);
    }

    #[test]
    fn the_zone_windows_cover_every_radius_and_merge_when_they_overlap() {
        let g = ZoneGrid::new(&holes(false), 1.001, 7.25).unwrap();
        let w = g.windows(0.01);
        let span: f64 = w.iter().map(|(a, b)| b - a).sum();
        let ring = (g.radii.last().unwrap() - g.radii[0]) / 1.001 + 0.02;
        assert!((span - ring).abs() < 1e-9, "{span} vs {ring}");
        assert!(w.len() >= 5, "{w:?}");
        for &r in &g.radii {
            assert!(w.iter().any(|&(a, b)| r / 1.001 >= a && r / 1.001 <= b));
        }
        // Narrow bands stay apart: one per radius.
        assert_eq!(g.windows(0.0005).len(), g.radii.len());
    }

    #[test]
    fn a_step_of_the_slide_over_one_hole_shows_on_its_side_only() {
        // Every pass 10 µin high except within 2° after (lower angle than)
        // hole 0's rim on the circle: 100 µin low there.
        let h = holes(false);
        let g = ZoneGrid::new(&h, 1.0, 7.25).unwrap();
        let f = 100e-6;
        let mut log = ZoneLog::new(&g, 0.125, f, vec![]);
        let rb = h.circle_radius_in;
        let half = half_width_deg(&h, rb).unwrap();
        for i in 0..PHI_COUNT {
            let phi = ZoneGrid::phi_deg(i);
            let off = (phi - h.phase_deg + 180.0).rem_euclid(360.0) - 180.0;
            let low = off < -half && off > -half - 2.0;
            let mut x = g.radii[0] - 0.02;
            while x < g.radii.last().unwrap() + 0.02 {
                let e = if low && (x - rb).abs() < 0.05 {
                    -100e-6
                } else {
                    10e-6
                };
                log.add(i, x, e);
                x += f;
            }
        }
        let z = ZoneMeasured::measure(&g, &log).summary();
        assert_eq!(z.uncut_points, 0);
        assert!(z.hole_points > 0);
        assert!(
            (z.leading_worst_uin[3].unwrap() - 10.0).abs() < 0.02,
            "{z:?}"
        );
        assert!(z.trailing_worst_uin[0].unwrap() < -99.0, "{z:?}");
        assert!(z.worst_uin[0].unwrap() < -99.0);
    }
}
