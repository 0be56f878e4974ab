//! `cut --measure exact|cmm`: the part's grid as the true surface, or as
//! chapter 5's Renault coordinate measuring machine would read it.
//!
//! Chapter 5: the part was aligned from probe points on its periphery and
//! three on the face, "the alignment error ... could be used to correct the
//! measured errors", and the probe then visited the grid (1 in by 10°). A
//! correction leaves residuals; the machine reads in 1 µm steps. The
//! reading at each point is
//!
//! ```text
//! read = q( err + b·X·cos(φ − α) + δφ·∂Z/∂φ + n ),   q(v) = 1 µm · round(v / 1 µm)
//! ```
//!
//! `b·X·cos(φ − α)`: the tilt left after the alignment (a plane through
//! the axis, direction α drawn once a measurement); `δφ`: the residual of
//! the angle datum (the probe visits φ + δφ and compares with the nominal
//! at φ); `n`: the probe's repeatability. Levels: [`CmmLevels`].

use super::part::{CmmGrid, CMM_X_IN};
use crate::surface::Surface;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};

/// How the grid is measured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Measure {
    /// The true surface at the grid points.
    #[default]
    Exact,
    /// As the CMM reads it ([`CmmLevels::renault`]).
    Cmm,
}

impl Measure {
    pub fn name(self) -> &'static str {
        match self {
            Measure::Exact => "exact",
            Measure::Cmm => "cmm",
        }
    }
}

/// The measuring machine's levels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CmmLevels {
    /// Display resolution, in (1 µm).
    pub resolution_in: f64,
    /// Repeatability of one probing, 1σ, in.
    pub repeatability_in: f64,
    /// Tilt left by the alignment correction, in per in of radius.
    pub tilt_in_per_in: f64,
    /// Residual of the angle datum, 1σ, degrees.
    pub angle_datum_deg: f64,
}

impl CmmLevels {
    /// Chapter 5's machine: 1 µm resolution (the seed: "Renault"; the
    /// grid was reported in mils to four places). Assumed: repeatability
    /// 0.5 µm (20 µin) 1σ; alignment residual of the probe's repeatability
    /// over the part's 7 in lever arm, 3 µin per in; angle datum to 0.05°.
    pub fn renault() -> Self {
        Self {
            resolution_in: 1e-6 / 0.0254,
            repeatability_in: 20e-6,
            tilt_in_per_in: 3e-6,
            angle_datum_deg: 0.05,
        }
    }
}

/// Rounds `v` (in) to the display's step.
pub fn quantise(v_in: f64, step_in: f64) -> f64 {
    if step_in > 0.0 {
        (v_in / step_in).round() * step_in
    } else {
        v_in
    }
}

/// The CMM's reading of `grid` (µin) on the part `surf` (contact gain
/// `gain`: tool-centre X = x / gain), seeded.
pub fn read(grid: &CmmGrid, surf: &Surface, gain: f64, lv: &CmmLevels, seed: u64) -> CmmGrid {
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed ^ 0xC33_0001);
    let alpha = rng.random::<f64>() * std::f64::consts::TAU;
    let w: f64 = StandardNormal.sample(&mut rng);
    let dphi_rad = lv.angle_datum_deg.to_radians() * w;
    let mut out = grid.clone();
    for (i, row) in out.err_uin.iter_mut().enumerate() {
        let phi = (10.0 * i as f64).to_radians();
        for (j, v) in row.iter_mut().enumerate() {
            let Some(e) = *v else { continue };
            let x = CMM_X_IN[j];
            let slope = surf
                .section(x / gain)
                .map(|s| s.dz_dphi(phi))
                .unwrap_or(0.0);
            let n: f64 = StandardNormal.sample(&mut rng);
            let r = e * 1e-6
                + lv.tilt_in_per_in * x * (phi - alpha).cos()
                + dphi_rad * slope
                + lv.repeatability_in * n;
            *v = Some(quantise(r, lv.resolution_in) * 1e6);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cmm_reads_in_whole_micrometres_within_half_a_step() {
        let step = 1e-6 / 0.0254;
        for k in -2000..2000 {
            let v = f64::from(k) * 0.37e-6;
            let q = quantise(v, step);
            let n = q / step;
            assert!((n - n.round()).abs() < 1e-9, "{v} -> {q}");
            assert!((q - v).abs() <= step / 2.0 + 1e-15, "{v} -> {q}");
        }
        // 50 µin is 1.27 µm: reads 1 µm = 39.37 µin; 60 µin reads 2 µm.
        assert!((quantise(50e-6, step) * 1e6 - 39.370_078_7).abs() < 1e-6);
        assert!((quantise(60e-6, step) * 1e6 - 78.740_157_5).abs() < 1e-6);
    }

    #[test]
    fn a_perfect_cmm_reads_the_grid_to_its_resolution_only() {
        let t = zslide::table::CoeffTable::parse(zslide::DEFAULT_TABLE).unwrap();
        let surf = Surface::from_table_geometry(&t.header().geometry).unwrap();
        let grid = CmmGrid {
            err_uin: (0..36)
                .map(|i| {
                    (0..7)
                        .map(|j| Some(f64::from(i * 7 + j) * 3.1 - 300.0))
                        .collect()
                })
                .collect(),
            in_hole: vec![vec![false; 7]; 36],
            finish_by_x_uin: vec![None; 7],
        };
        let lv = CmmLevels {
            repeatability_in: 0.0,
            tilt_in_per_in: 0.0,
            angle_datum_deg: 0.0,
            ..CmmLevels::renault()
        };
        let r = read(&grid, &surf, surf.contact_gain(), &lv, 7);
        for (a, b) in grid
            .err_uin
            .iter()
            .flatten()
            .zip(r.err_uin.iter().flatten())
        {
            let (a, b) = (a.unwrap(), b.unwrap());
            assert!((a - b).abs() <= 39.37 / 2.0 + 1e-9, "{a} read {b}");
        }
    }
}
