//! The machined part: the surface the tool leaves (the envelope of the tool
//! nose along the simulated tool-centre path), measured on the CMM grid of
//! chapter 5, and the finish estimate.
//!
//! # Sign convention (chapter 5: "positive error in this measurement
//! indicates excess stock")
//!
//! Errors are along the axis, +Y_t (+Z of eq 2-8). The material lies on the
//! −Y_t side of the surface, so a surface point higher than nominal is
//! material left on the part: **error = machined − nominal, positive =
//! excess stock**. A slide that runs high by δ (tool centre at `Z + δ`)
//! leaves `+δ` everywhere.
//!
//! # The envelope
//!
//! At one angle φ the tool passes once per revolution, at tool-centre radii
//! `X_j` (one feed apart) with tool-centre errors `e_j` (slide position
//! minus the exact command `Z(X_j, φ)`). The nominal path's envelope is the
//! nominal surface; the contact of surface radius `x` is made by the tool
//! centre at `X_c = x (R0 − r_t)/R0` (FOREX4's compensation, `surface.rs`).
//! A nose arc at `X_j` lies `r_t − sqrt(r_t² − (X_j − X_c)²)` above the
//! nominal surface at `x` (exact for the nose circle over a surface whose
//! own curvature, 1/R0 ≈ 1/160 in⁻¹, is neglected against 1/r_t = 8 in⁻¹),
//! so the error at `x` is
//!
//! ```text
//! err(x, φ) = min_j [ e_j + r_t − sqrt(r_t² − (X_j − X_c)²) ]
//! ```
//!
//! the lowest of the arcs, i.e. the material no pass removed.
//!
//! # Finish
//!
//! A profilometer trace along the radius at each CMM angle: the envelope
//! sampled every `f/16` over `FINISH_SPAN_FEEDS` feeds around the point, its
//! least-squares line removed (form), RMS of the rest. For a still slide it
//! is the cusp train of the feed marks, peak-to-valley `f²/(8 r_t)` and
//! RMS `f²/(12√5 r_t)`; slide motion between revolutions adds to it.

/// CMM radii, in (chapter 5: 1 in radial spacing).
pub const CMM_X_IN: [f64; 7] = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0];
/// CMM angles, degrees (10° spacing).
pub const CMM_PHI_COUNT: usize = 36;

/// Profilometer span, feeds.
pub const FINISH_SPAN_FEEDS: usize = 40;
/// Profile samples per feed.
const FINISH_SAMPLES_PER_FEED: usize = 16;

pub fn cmm_phi_deg() -> Vec<f64> {
    (0..CMM_PHI_COUNT).map(|k| 10.0 * k as f64).collect()
}

/// One revolution's passage of the tool centre at one CMM angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pass {
    /// Tool-centre radius, in.
    pub x_in: f64,
    /// Tool-centre error along +Z (slide minus exact command), in.
    pub e_in: f64,
}

/// The lowest nose arc over one surface point, gathered pass by pass:
/// the material no pass removed (module doc), and whether passes cover
/// the point on both sides within one and a half feeds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Envelope {
    below: bool,
    above: bool,
    best: f64,
}

impl Default for Envelope {
    fn default() -> Self {
        Self {
            below: false,
            above: false,
            best: f64::INFINITY,
        }
    }
}

impl Envelope {
    /// A pass `u` in outward of the point's contact tool centre, with
    /// tool-centre error `e_in`.
    pub fn add(&mut self, u: f64, e_in: f64, r_t: f64, feed_in: f64) {
        if u.abs() >= r_t {
            return;
        }
        self.below |= u <= 0.0 && u > -1.5 * feed_in;
        self.above |= u >= 0.0 && u < 1.5 * feed_in;
        let h = e_in + (r_t - ((r_t - u) * (r_t + u)).sqrt());
        self.best = self.best.min(h);
    }

    /// The passes of another stretch over the same point.
    pub fn merge(&mut self, o: &Envelope) {
        self.below |= o.below;
        self.above |= o.above;
        self.best = self.best.min(o.best);
    }

    /// The error, in; `None` unless cut on both sides.
    pub fn value(&self) -> Option<f64> {
        (self.below && self.above).then_some(self.best)
    }
}

/// Error of the surface at the point whose contact tool centre is `xc`,
/// in (positive = excess stock); `None` if no pass covers it on both
/// sides within one feed (the point was not cut in the simulated span).
pub fn envelope_error(passes: &[Pass], xc: f64, r_t: f64, feed_in: f64) -> Option<f64> {
    let mut env = Envelope::default();
    for p in passes {
        env.add(p.x_in - xc, p.e_in, r_t, feed_in);
    }
    env.value()
}

/// Profilometer RMS (in) of the radial profile around `xc`: envelope
/// sampled over `FINISH_SPAN_FEEDS` feeds, least-squares line removed.
/// `None` if the span is not fully cut.
pub fn finish_rms(passes: &[Pass], xc: f64, r_t: f64, feed_in: f64) -> Option<f64> {
    let n = FINISH_SPAN_FEEDS * FINISH_SAMPLES_PER_FEED;
    let span = FINISH_SPAN_FEEDS as f64 * feed_in;
    // Only the passes that can reach the span matter: bound the reach by
    // the spread of the errors (an arc further away lies above them all).
    let (lo, hi) = passes.iter().fold((f64::MAX, f64::MIN), |(a, b), p| {
        (a.min(p.e_in), b.max(p.e_in))
    });
    let reach = (2.0 * r_t * (hi - lo).max(0.0)).sqrt() + 2.0 * feed_in;
    let near: Vec<Pass> = passes
        .iter()
        .copied()
        .filter(|p| (p.x_in - xc).abs() <= span / 2.0 + reach)
        .collect();
    let mut xs = Vec::with_capacity(n);
    let mut ys = Vec::with_capacity(n);
    for k in 0..n {
        let x = xc - span / 2.0 + span * (k as f64 + 0.5) / n as f64;
        ys.push(envelope_error(&near, x, r_t, feed_in)?);
        xs.push(x - xc);
    }
    Some(rms_about_line(&xs, &ys))
}

/// RMS of `y` about its least-squares line in `x`.
pub fn rms_about_line(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let mx = x.iter().sum::<f64>() / n;
    let my = y.iter().sum::<f64>() / n;
    let sxx: f64 = x.iter().map(|v| (v - mx) * (v - mx)).sum();
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let ss: f64 = x
        .iter()
        .zip(y)
        .map(|(a, b)| {
            let r = b - my - slope * (a - mx);
            r * r
        })
        .sum();
    (ss / n).sqrt()
}

/// The passes of one band of the pass: per CMM angle, every revolution.
#[derive(Clone, Debug, Default)]
pub struct PassLog {
    pub by_phi: Vec<Vec<Pass>>,
}

impl PassLog {
    pub fn new() -> Self {
        Self {
            by_phi: vec![Vec::new(); CMM_PHI_COUNT],
        }
    }
    pub fn merge(&mut self, other: PassLog) {
        for (a, b) in self.by_phi.iter_mut().zip(other.by_phi) {
            a.extend(b);
        }
    }
}

/// The CMM measurement of the part.
#[derive(Clone, Debug, PartialEq)]
pub struct CmmGrid {
    /// `[φ row][X column]`, µin, positive = excess stock; `None` where the
    /// probe cannot measure (inside an open bolt hole) or the point was not
    /// cut.
    pub err_uin: Vec<Vec<Option<f64>>>,
    /// Why a point is `None`: true = inside an open hole.
    pub in_hole: Vec<Vec<bool>>,
    /// Finish RMS by CMM radius, µin (RMS over the 36 radial traces).
    pub finish_by_x_uin: Vec<Option<f64>>,
}

impl CmmGrid {
    /// Measures the surface the passes leave. `contact_gain` is
    /// `R0/(R0 − r_t)` (tool centre `X_c = x / contact_gain`);
    /// `in_open_hole(x, φ_deg)` tells which grid points the probe cannot
    /// touch.
    pub fn measure(
        log: &PassLog,
        contact_gain: f64,
        r_t: f64,
        feed_in: f64,
        in_open_hole: impl Fn(f64, f64) -> bool,
    ) -> Self {
        Self::measure_at(log, &CMM_X_IN, contact_gain, r_t, feed_in, in_open_hole)
    }

    /// [`Self::measure`] at the radii `radii` (a part's: `partcut`).
    pub fn measure_at(
        log: &PassLog,
        radii: &[f64],
        contact_gain: f64,
        r_t: f64,
        feed_in: f64,
        in_open_hole: impl Fn(f64, f64) -> bool,
    ) -> Self {
        let phis = cmm_phi_deg();
        let mut err = vec![vec![None; radii.len()]; CMM_PHI_COUNT];
        let mut hole = vec![vec![false; radii.len()]; CMM_PHI_COUNT];
        let mut fin_sum = vec![(0.0f64, 0usize); radii.len()];
        for (i, passes) in log.by_phi.iter().enumerate() {
            for (j, &x) in radii.iter().enumerate() {
                let xc = x / contact_gain;
                if in_open_hole(x, phis[i]) {
                    hole[i][j] = true;
                } else {
                    err[i][j] = envelope_error(passes, xc, r_t, feed_in).map(|e| e * 1e6);
                }
                if let Some(f) = finish_rms(passes, xc, r_t, feed_in) {
                    // A trace through an open hole measures the hole, not
                    // the finish: skip it.
                    if !hole[i][j] {
                        fin_sum[j].0 += f * f;
                        fin_sum[j].1 += 1;
                    }
                }
            }
        }
        let finish_by_x_uin = fin_sum
            .iter()
            .map(|&(s, n)| (n > 0).then(|| (s / n as f64).sqrt() * 1e6))
            .collect();
        Self {
            err_uin: err,
            in_hole: hole,
            finish_by_x_uin,
        }
    }

    /// (min, max) over the measured points, µin.
    pub fn band(&self) -> Option<(f64, f64)> {
        let v: Vec<f64> = self.err_uin.iter().flatten().flatten().copied().collect();
        if v.is_empty() {
            return None;
        }
        Some(
            v.iter()
                .fold((f64::MAX, f64::MIN), |(a, b), &e| (a.min(e), b.max(e))),
        )
    }

    /// RMS of the finish over all radii, µin.
    pub fn finish_rms_uin(&self) -> Option<f64> {
        let v: Vec<f64> = self.finish_by_x_uin.iter().flatten().copied().collect();
        (!v.is_empty()).then(|| (v.iter().map(|f| f * f).sum::<f64>() / v.len() as f64).sqrt())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    const R_T: f64 = 0.125;
    const F: f64 = 100e-6;

    /// Passes of a still or moving slide: revolution j at X = x0 − j f
    /// (plus the fraction of a turn the angle adds), error `e(X, φ)`.
    fn log_of(e: impl Fn(f64, f64) -> f64, x_hi: f64, x_lo: f64) -> PassLog {
        let mut log = PassLog::new();
        let revs = ((x_hi - x_lo) / F) as usize;
        for (i, passes) in log.by_phi.iter_mut().enumerate() {
            let phi = TAU * i as f64 / CMM_PHI_COUNT as f64;
            for j in 0..revs {
                let x = x_hi - F * (j as f64 + i as f64 / CMM_PHI_COUNT as f64);
                passes.push(Pass {
                    x_in: x,
                    e_in: e(x, phi),
                });
            }
        }
        log
    }

    fn full_log(e: impl Fn(f64, f64) -> f64 + Copy) -> PassLog {
        let mut log = PassLog::new();
        for &x in &CMM_X_IN {
            log.merge(log_of(e, x + 0.01, x - 0.01));
        }
        log
    }

    #[test]
    fn a_constant_offset_of_the_slide_reads_as_that_offset_everywhere() {
        let log = full_log(|_, _| 250e-6);
        let g = CmmGrid::measure(&log, 1.0 + 1e-3, R_T, F, |_, _| false);
        for row in &g.err_uin {
            for e in row {
                let e = e.expect("every point cut");
                // The envelope adds at most the cusp, f²/(8 r_t) = 0.01 µin.
                assert!((e - 250.0).abs() <= 0.011, "{e}");
            }
        }
    }

    #[test]
    fn a_pure_twice_per_rev_error_reads_as_the_same_cosine_on_the_grid() {
        let a = 400e-6;
        let log = full_log(|_, phi| a * (2.0 * phi).cos());
        let g = CmmGrid::measure(&log, 1.0, R_T, F, |_, _| false);
        for (i, row) in g.err_uin.iter().enumerate() {
            let expect = a * 1e6 * (2.0 * (10.0 * i as f64).to_radians()).cos();
            for e in row {
                assert!((e.unwrap() - expect).abs() <= 0.011, "{e:?} vs {expect}");
            }
        }
    }

    #[test]
    fn a_slide_running_high_leaves_excess_stock_positive_and_low_removes_it_negative() {
        let high = CmmGrid::measure(&full_log(|_, _| 1e-4), 1.0, R_T, F, |_, _| false);
        let low = CmmGrid::measure(&full_log(|_, _| -1e-4), 1.0, R_T, F, |_, _| false);
        let (hl, hh) = high.band().unwrap();
        let (ll, lh) = low.band().unwrap();
        assert!(hl > 99.0 && hh < 101.0);
        assert!(ll > -101.0 && lh < -99.0);
    }

    #[test]
    fn a_single_deep_revolution_cuts_its_neighbourhood_with_the_nose_arc() {
        // One revolution 50 µin low at X = 4 in: the nose arc sets the
        // surface within sqrt(2 r_t · 50 µin) = 3.5 mil of it, nothing beyond.
        let dip = |x: f64, _| {
            if (x - 4.0).abs() < F / 2.0 {
                -50e-6
            } else {
                0.0
            }
        };
        let log = log_of(dip, 4.01, 3.99);
        for (u, expect) in [
            (0.0, -50.0),
            (0.002, -50.0 + 0.002f64.powi(2) / (2.0 * R_T) * 1e6),
        ] {
            let e = envelope_error(&log.by_phi[0], 4.0 + u, R_T, F).unwrap() * 1e6;
            assert!((e - expect).abs() < 0.05, "u {u}: {e} vs {expect}");
        }
        let far = envelope_error(&log.by_phi[0], 4.004, R_T, F).unwrap() * 1e6;
        assert!(far.abs() < 0.02, "{far}");
    }

    #[test]
    fn finish_of_a_still_slide_is_the_feed_cusp_f2_over_8r() {
        let log = log_of(|_, _| 0.0, 3.01, 2.99);
        let passes = &log.by_phi[0];
        // Peak-to-valley of the envelope over two feeds.
        let n = 400;
        let vals: Vec<f64> = (0..n)
            .map(|k| envelope_error(passes, 3.0 + 2.0 * F * k as f64 / n as f64, R_T, F).unwrap())
            .collect();
        let pv = vals.iter().cloned().fold(f64::MIN, f64::max)
            - vals.iter().cloned().fold(f64::MAX, f64::min);
        let cusp = F * F / (8.0 * R_T);
        assert!((pv - cusp).abs() < 0.01 * cusp, "{pv} vs {cusp}");
        let rms = finish_rms(passes, 3.0, R_T, F).unwrap();
        let expect = F * F / (12.0 * 5f64.sqrt() * R_T);
        assert!((rms - expect).abs() < 0.02 * expect, "{rms} vs {expect}");
    }

    #[test]
    fn grid_points_in_open_holes_are_not_measured_and_stay_out_of_the_band() {
        let log = full_log(|_, _| 0.0);
        let g = CmmGrid::measure(&log, 1.0, R_T, F, |x, phi| x == 3.0 && phi == 20.0);
        assert_eq!(g.err_uin[2][2], None);
        assert!(g.in_hole[2][2]);
        assert!(g.err_uin[3][2].is_some());
    }
}
