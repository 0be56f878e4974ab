//! The tool's engagement with the stock, and the cutting force it puts on
//! the slide, evaluated at every loop tick of a simulated pass.
//!
//! # Geometry (radial section at the tool's angle φ, feeding inward)
//!
//! Heights are along +Y_t (+Z of eq 2-8), relative to the nominal finished
//! surface; the part material lies on the −Y_t side (the concave face looks
//! toward +Y_t: `Y(X)` of eq 2-14 rises with X), so the stock pushes the
//! tool toward +Z (`CuttingParams::part_side = −1`, checked by
//! `cut::check_part_side`).
//!
//! * `e`: the tool bottom's error now (slide position minus the exact
//!   command at the true X and φ): positive = the tool is higher, it cuts
//!   less.
//! * **Stock ahead** (radii the tool has not reached yet): the surface the
//!   previous (clean-up) pass left plus the depth of cut `d`. That pass was
//!   cut on the same machine with the same controller, so it left the same
//!   spindle-synchronous error: the stock top is `d + ē(φ)`, `ē` the
//!   revolution-to-revolution average of `e` at that angle (an exponential
//!   average over ≈ 8 revolutions). Its non-repeatable part is not kept.
//!   Depth into the fresh stock: `d_f = d + ē − e`; contact chord ahead of
//!   the centre `sqrt(2 r_t d_f)`.
//! * **Behind** (radii cut one revolution ago, at `X + f`): the nose is
//!   below the previous revolution's surface for `u < f/2 − (r_t/f)(e −
//!   e_prev)` (`u` from the tool centre, outward). That rear contact is
//!   bounded to `[0, f]`: beyond it the nose only rubs the previous
//!   revolution's surface at an interference of a few µin, which the edge
//!   (ploughing) constant, calibrated on full cuts, does not describe.
//!   With `e = e_prev` it is `f/2`, the steady contact of `CuttingParams`.
//! * Force magnitude `engaged · (k_t d_f f + k_e l_c)`, `l_c` the sum of
//!   the two contacts (`CuttingParams::thrust_lbf` in the steady state),
//!   `engaged` the fraction of the chord over material: not over an open
//!   bolt hole, and inside the stock's rim (`set_rim`: the stock lies at
//!   X ≤ the rim, so a tool feeding in from outside meets it with the
//!   leading point of its nose and the chord over material grows by one
//!   feed a revolution, `sqrt(2 r_t d)/f + 1/2` revolutions to the whole
//!   chord).
//! * The memory records only where the tool cut: out of the stock (no
//!   material under the chord) the tool leaves no surface behind.
//!
//! Filled holes (the second part of chapter 5) are cut like the part
//! material: the cast filler's own cutting constants are not known, so the
//! model gives it the part's (stated in docs/CUT.md).

use crate::plant::cutting::{BoltHoles, CuttingParams};
use std::f64::consts::TAU;

/// Angle bins of the per-revolution memory.
pub const BINS: usize = 2048;

/// Exponential-average weight of one revolution in `ē` (≈ 8 revolutions).
const SYNC_WEIGHT: f64 = 1.0 / 8.0;

/// Samples across the contact chord for the hole test (as
/// `BoltHoles::engaged_fraction`).
const CHORD_SAMPLES: usize = 16;

/// Bolt holes as angular intervals: at radius r a hole of radius ρ on the
/// bolt circle R_b covers `|φ − φ_k| < Δ(r)`, `cos Δ = (r² + R_b² − ρ²) /
/// (2 r R_b)`. Same answer as `BoltHoles::over_hole` without trigonometry
/// per sample unless the tool is near a hole.
#[derive(Clone, Debug)]
pub struct HoleRing {
    open: bool,
    count: f64,
    circle_r: f64,
    rho: f64,
    phase_turns: f64,
    /// Largest angular half-width of a hole at any radius, turns.
    max_half_turns: f64,
}

impl HoleRing {
    pub fn new(h: &BoltHoles) -> Self {
        let open = !h.filled && h.count > 0 && h.diameter_in > 0.0;
        let rho = h.diameter_in / 2.0;
        let max_half = if rho < h.circle_radius_in {
            (rho / h.circle_radius_in).asin() / TAU
        } else {
            0.5
        };
        Self {
            open,
            count: f64::from(h.count),
            circle_r: h.circle_radius_in,
            rho,
            phase_turns: h.phase_deg / 360.0,
            max_half_turns: max_half,
        }
    }

    /// Angular distance (turns) from `phi_turns` to the nearest hole centre.
    fn to_nearest(&self, phi_turns: f64) -> f64 {
        let u = crate::fastmath::frac((phi_turns - self.phase_turns) * self.count);
        u.min(1.0 - u) / self.count
    }

    fn half_width_turns(&self, r: f64) -> f64 {
        if (r - self.circle_r).abs() >= self.rho || r <= 0.0 {
            return -1.0;
        }
        let c = (r * r + self.circle_r * self.circle_r - self.rho * self.rho)
            / (2.0 * r * self.circle_r);
        c.clamp(-1.0, 1.0).acos() / TAU
    }

    /// Whether the point at radius `r_in`, angle `phi_turns` is over an open
    /// hole.
    pub fn over_hole(&self, r_in: f64, phi_turns: f64) -> bool {
        self.open && self.to_nearest(phi_turns) < self.half_width_turns(r_in)
    }

    /// Fraction of the radial chord `[r_lo, r_hi]` over solid material (16
    /// samples, as the plant's reference model).
    pub fn engaged_fraction(&self, r_lo: f64, r_hi: f64, phi_turns: f64) -> f64 {
        if !self.open || r_hi < self.circle_r - self.rho || r_lo > self.circle_r + self.rho {
            return 1.0;
        }
        let d = self.to_nearest(phi_turns);
        if d >= self.max_half_turns {
            return 1.0;
        }
        // d ≥ acos(c)/2π ⟺ cos(2πd) ≤ c (cos falls on [0, π] and 2πd ≤
        // π/count): one cosine a tick instead of an arccosine a sample.
        let cos_d = libm::cos(TAU * d);
        let solid = (0..CHORD_SAMPLES)
            .filter(|&k| {
                let r = r_lo + (r_hi - r_lo) * (k as f64 + 0.5) / CHORD_SAMPLES as f64;
                match self.half_width_cos(r) {
                    Some(c) => cos_d <= c,
                    None => true,
                }
            })
            .count();
        solid as f64 / CHORD_SAMPLES as f64
    }

    /// cos of the angular half-width (radians) of a hole at radius `r`
    /// (`None` off the holes' annulus).
    fn half_width_cos(&self, r: f64) -> Option<f64> {
        if (r - self.circle_r).abs() >= self.rho || r <= 0.0 {
            return None;
        }
        let c = (r * r + self.circle_r * self.circle_r - self.rho * self.rho)
            / (2.0 * r * self.circle_r);
        Some(c.clamp(-1.0, 1.0))
    }
}

/// What the engagement gives at one instant.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Contact {
    /// Depth into the fresh stock, in (≥ 0).
    pub depth_in: f64,
    /// Engaged edge length, in.
    pub chord_in: f64,
    /// Fraction of the chord over material.
    pub engaged: f64,
    /// Force on the slide along +Z, lbf.
    pub force_lbf: f64,
}

/// Stock memory and force law of one pass.
pub struct Engagement {
    cut: CuttingParams,
    holes: HoleRing,
    depth_in: f64,
    feed_in: f64,
    /// `e` of the previous revolution, per angle bin.
    prev: Vec<f64>,
    /// Spindle-synchronous average `ē`, per angle bin (NaN: not seen yet).
    sync: Vec<f64>,
    last_bin: Option<usize>,
    last_e: f64,
    /// Whether the tool was in the stock at the last call.
    last_cut: bool,
    /// Tool-centre X of the stock's outer edge, in (material at X ≤ it;
    /// +∞: the tool is in the stock everywhere, −∞: nowhere).
    rim_in: f64,
}

impl Engagement {
    /// `depth_in`: depth of cut of the pass; `feed_in`: feed per revolution.
    pub fn new(cut: &CuttingParams, depth_in: f64, feed_in: f64) -> Self {
        Self {
            holes: HoleRing::new(&cut.bolt_holes),
            cut: cut.clone(),
            depth_in,
            feed_in,
            prev: vec![0.0; BINS],
            sync: vec![f64::NAN; BINS],
            last_bin: None,
            last_e: 0.0,
            last_cut: false,
            rim_in: f64::INFINITY,
        }
    }

    /// Places the stock's outer edge at tool-centre X `rim_in` (material
    /// at X ≤ `rim_in`; `-∞`: the tool is clear of the stock).
    pub fn set_rim(&mut self, rim_in: f64) {
        self.rim_in = rim_in;
    }

    /// Forgets the stock memory: the next revolution defines `ē` and
    /// `e_prev` afresh (after the start-up transient of a stretch, which
    /// the previous pass did not have).
    /// Scales the edge force `k_e` from now on (a fault campaign's blunt
    /// edge or harder material mid-cut).
    pub fn scale_edge_force(&mut self, factor: f64) {
        self.cut.k_e_lbf_per_in *= factor;
    }

    pub fn reset_memory(&mut self) {
        self.prev.iter_mut().for_each(|v| *v = 0.0);
        self.sync.iter_mut().for_each(|v| *v = f64::NAN);
        self.last_bin = None;
    }

    pub fn holes(&self) -> &HoleRing {
        &self.holes
    }

    /// The contact at tool-centre radius `x_in`, angle `phi_turns`, with the
    /// tool bottom `e_in` above its nominal height; updates the memory of
    /// the angle bins passed since the last call.
    pub fn step(&mut self, x_in: f64, phi_turns: f64, e_in: f64) -> Contact {
        let b = ((crate::fastmath::frac(phi_turns) * BINS as f64) as usize).min(BINS - 1);
        let sync = self.sync[b];
        let e_bar = if sync.is_nan() { e_in } else { sync };
        let e_prev = if sync.is_nan() { e_in } else { self.prev[b] };
        let depth = (self.depth_in + e_bar - e_in).max(0.0);
        let r = self.cut.tool_radius_in;
        let f = self.feed_in;
        let front = (2.0 * r * depth).sqrt();
        let rear = if depth > 0.0 {
            (f / 2.0 - r / f * (e_in - e_prev)).clamp(0.0, f)
        } else {
            0.0
        };
        let chord = front + rear;
        // The chord [X − front, X + rear] over the stock (X ≤ rim).
        let inside = if chord > 0.0 {
            ((self.rim_in - (x_in - front)) / chord).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let engaged = if inside > 0.0 {
            inside
                * self
                    .holes
                    .engaged_fraction(x_in - front, x_in + rear, phi_turns)
        } else {
            0.0
        };
        let thrust = engaged * (self.cut.k_t_psi * depth * f + self.cut.k_e_lbf_per_in * chord);
        // Memory: the bins the tool has just left keep the `e` it had
        // there, so every visit of a bin during one revolution reads the
        // previous revolution's values.
        if let Some(l) = self.last_bin.filter(|_| self.last_cut) {
            let mut k = l;
            while k != b {
                self.prev[k] = self.last_e;
                let s = self.sync[k];
                self.sync[k] = if s.is_nan() {
                    self.last_e
                } else {
                    s + SYNC_WEIGHT * (self.last_e - s)
                };
                k = (k + 1) % BINS;
            }
        }
        self.last_bin = Some(b);
        self.last_e = e_in;
        self.last_cut = inside > 0.0;
        Contact {
            depth_in: depth,
            chord_in: chord,
            engaged,
            force_lbf: -self.cut.part_side * thrust,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(filled: bool) -> CuttingParams {
        let mut c = CuttingParams {
            part_side: -1.0,
            ..CuttingParams::default()
        };
        c.bolt_holes.filled = filled;
        c
    }

    #[test]
    fn hole_ring_agrees_with_the_plant_reference_model() {
        let c = params(false);
        let ring = HoleRing::new(&c.bolt_holes);
        let mut n_hole = 0;
        for i in 0..400 {
            let r = 2.7 + 1.1 * i as f64 / 400.0;
            for j in 0..720 {
                let turns = j as f64 / 720.0 + 1e-7;
                let a = ring.over_hole(r, turns);
                let b = c.bolt_holes.over_hole(r, turns * TAU);
                assert_eq!(a, b, "r {r} phi {turns}");
                n_hole += usize::from(a);
            }
        }
        assert!(n_hole > 1000, "the sweep crosses the holes ({n_hole})");
        for i in 0..200 {
            let x = 2.8 + 0.9 * i as f64 / 200.0;
            for j in 0..360 {
                let t = j as f64 / 360.0 + 1e-7;
                let l = 0.0087;
                let reference = c.bolt_holes.engaged_fraction(x, t * TAU, l);
                let fast = ring.engaged_fraction(x - l / 2.0, x + l / 2.0, t);
                assert_eq!(fast, reference, "x {x} phi {t}");
            }
        }
    }

    #[test]
    fn steady_engagement_gives_the_plant_thrust_along_plus_z() {
        let c = params(true);
        let (d, f) = (300e-6, 100e-6);
        let mut g = Engagement::new(&c, d, f);
        let mut last = Contact::default();
        for k in 0..3 * BINS {
            last = g.step(5.0, k as f64 / BINS as f64, 12e-6);
        }
        assert!((last.depth_in - d).abs() < 1e-12);
        let expect = c.thrust_lbf(d, f);
        assert!(
            (last.force_lbf - expect).abs() < 1e-9,
            "{last:?} vs {expect}"
        );
        assert!(
            last.force_lbf > 0.0,
            "stock on −Z pushes the tool toward +Z"
        );
    }

    #[test]
    fn lifting_the_tool_reduces_the_depth_and_the_force() {
        let c = params(true);
        let (d, f) = (300e-6, 100e-6);
        let mut g = Engagement::new(&c, d, f);
        for k in 0..4 * BINS {
            g.step(5.0, k as f64 / BINS as f64, 0.0);
        }
        // 100 µin above the previous revolutions: 200 µin into the stock,
        // no rear contact (the nose is above the last revolution's cut).
        let up = g.step(5.0, 0.0, 100e-6);
        assert!((up.depth_in - 200e-6).abs() < 1e-12);
        let expect = c.k_t_psi * 200e-6 * f + c.k_e_lbf_per_in * (2.0 * 0.125 * 200e-6f64).sqrt();
        assert!((up.force_lbf - expect).abs() < 1e-9);
        // Out of the stock: no force.
        let out = g.step(5.0, 1.0 / BINS as f64, 400e-6);
        assert_eq!(out.force_lbf, 0.0);
    }

    #[test]
    fn open_holes_remove_the_force_over_them_and_filled_ones_do_not() {
        let (d, f) = (300e-6, 100e-6);
        let hole_centre_turns = 22.5 / 360.0;
        for filled in [false, true] {
            let c = params(filled);
            let mut g = Engagement::new(&c, d, f);
            let mut over = Vec::new();
            let (mut min, mut max) = (f64::MAX, 0.0f64);
            for k in 0..2 * BINS {
                let t = k as f64 / BINS as f64;
                let ct = g.step(3.25, t, 0.0);
                min = min.min(ct.force_lbf);
                max = max.max(ct.force_lbf);
                // The sample nearest the hole centre (within half a step).
                if k >= BINS && (t.fract() - hole_centre_turns).abs() < 0.5 / BINS as f64 {
                    over.push(ct.force_lbf);
                }
            }
            // The sweep must reach the hole centre, or the check is empty.
            assert_eq!(over.len(), 1, "samples at the hole centre: {over:?}");
            if filled {
                assert!(min > 1.0, "filled: cut everywhere ({min})");
                assert!(over[0] > 1.0, "filled: cut over the hole ({over:?})");
            } else {
                assert_eq!(over[0], 0.0, "open: no force over the hole centre");
                assert!(max > 1.0, "open: cut between the holes ({max})");
            }
        }
    }
}
