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
//! read = q( err + δ·X·sin(φ − φ0) + b·X·cos(φ − α) + δφ·∂Z/∂φ + n ),   q(v) = 1 µm · round(v / 1 µm)
//! ```
//!
//! `δ·X·sin(φ − φ0)`: the face the part is levelled on is not flat under
//! the three probe points ([`FaceLevelling`]; the scenario's face tilt,
//! fixed by the part's face, not by the draw); `b·X·cos(φ − α)`: the tilt
//! the probe's repeatability leaves after the alignment (a plane through
//! the axis, direction α drawn once a measurement); `δφ`: the residual of
//! the angle datum (the probe visits φ + δφ and compares with the nominal
//! at φ); `n`: the probe's repeatability. Levels: [`CmmLevels`].
//!
//! The face levelling belongs here, not in the cut: chapter 5 machined
//! the face "in the same pass as the full contour", so a part tilted on
//! the faceplate or a tilting spindle puts the same tilt into face and
//! contour, and levelling on the face takes it out; what is left is the
//! levelling itself, an error of the reading (docs/CUT.md, "The face
//! tilt").

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
    /// The levelling on the part's face.
    pub face: FaceLevelling,
}

/// The tilt the part's face gives the CMM's levelling (three probe points
/// on a face that is not flat under them): `δ·X·sin(φ − φ0)` added to
/// every reading, X the surface radius, φ the part frame's angle.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FaceLevelling {
    /// δ, in per in of radius.
    pub tilt_in_per_in: f64,
    /// φ0, where the tilt crosses zero rising, degrees.
    pub zero_phase_deg: f64,
}

impl FaceLevelling {
    /// The scenario's `[errors] face_tilt_*` levels.
    pub fn of(levels: &crate::error_levels::ErrorLevels) -> Self {
        Self {
            tilt_in_per_in: levels.face_tilt_uin_per_in * 1e-6,
            zero_phase_deg: levels.face_tilt_phase_deg,
        }
    }
    /// What the levelling adds to the reading at surface radius `x_in`,
    /// part angle `phi_rad`, in.
    pub fn at_in(&self, x_in: f64, phi_rad: f64) -> f64 {
        self.tilt_in_per_in * x_in * (phi_rad - self.zero_phase_deg.to_radians()).sin()
    }
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
            face: FaceLevelling::default(),
        }
    }
    /// A reading with no error but the face's levelling: what the face
    /// tilt alone adds (the budget's row, the tests).
    pub fn face_only(face: FaceLevelling) -> Self {
        Self {
            resolution_in: 0.0,
            repeatability_in: 0.0,
            tilt_in_per_in: 0.0,
            angle_datum_deg: 0.0,
            face,
        }
    }
    /// These levels levelled on `face`.
    pub fn levelled_on(self, face: FaceLevelling) -> Self {
        Self { face, ..self }
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
                + lv.face.at_in(x, phi)
                + lv.tilt_in_per_in * x * (phi - alpha).cos()
                + dphi_rad * slope
                + lv.repeatability_in * n;
            *v = Some(quantise(r, lv.resolution_in) * 1e6);
        }
    }
    out
}

/// The mean of `n` readings of the same part (`n` ≥ 1; reading 0 is
/// [`read`]'s with `seed`, so one reading is exactly `read`): each
/// reading draws its own probe noise, alignment residual and angle datum,
/// the face's levelling is the same in all of them (the same three probe
/// points on the same face). The probe's repeatability (20 µin) is about
/// half the 1 µm step, so it dithers the rounding and the readings'
/// rounding errors are nearly independent: the mean's noise is the one
/// reading's `√(σ² + step²/12)` over `√n` (tested). A shop does this to
/// measure a part finer than its CMM's repeatability.
pub fn read_averaged(
    grid: &CmmGrid,
    surf: &Surface,
    gain: f64,
    lv: &CmmLevels,
    seed: u64,
    n: u32,
) -> CmmGrid {
    let n = n.max(1);
    let mut sum = read(grid, surf, gain, lv, seed);
    for k in 1..n {
        let r = read(
            grid,
            surf,
            gain,
            lv,
            seed.wrapping_add(u64::from(k).wrapping_mul(0x9E37_79B9_7F4A_7C15)),
        );
        for (a, b) in sum
            .err_uin
            .iter_mut()
            .flatten()
            .zip(r.err_uin.iter().flatten())
        {
            if let (Some(a), Some(b)) = (a.as_mut(), b) {
                *a += b;
            }
        }
    }
    if n > 1 {
        for v in sum.err_uin.iter_mut().flatten().flatten() {
            *v /= f64::from(n);
        }
    }
    sum
}

/// Most readings `cut --cmm-readings` averages.
pub const MAX_READINGS: u32 = 400;

#[cfg(test)]
mod tests {
    use super::*;

    /// The default part's surface and a 36 × 7 grid of distinct values,
    /// `k·step − offset` µin at the k-th point.
    fn surface_and_grid(step: f64, offset: f64) -> (Surface, CmmGrid) {
        let t = zslide::table::CoeffTable::parse(zslide::DEFAULT_TABLE).unwrap();
        let surf = Surface::from_table_geometry(&t.header().geometry).unwrap();
        let grid = CmmGrid {
            err_uin: (0..36)
                .map(|i| {
                    (0..7)
                        .map(|j| Some(f64::from(i * 7 + j) * step - offset))
                        .collect()
                })
                .collect(),
            in_hole: vec![vec![false; 7]; 36],
            finish_by_x_uin: vec![None; 7],
        };
        (surf, grid)
    }

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
        let (surf, grid) = surface_and_grid(3.1, 300.0);
        let lv = CmmLevels {
            repeatability_in: 0.0,
            tilt_in_per_in: 0.0,
            angle_datum_deg: 0.0,
            face: FaceLevelling::default(),
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

    /// The face levelled on three points that are not flat: a perfect CMM
    /// otherwise reads the grid plus δ·X·sin(φ − φ0), φ the part frame's
    /// angle and X the surface radius (chapter 5's grid), whatever the
    /// grid holds and whatever the seed.
    #[test]
    fn a_face_tilt_delta_reads_delta_x_sin_phi_minus_phi0() {
        let (surf, grid) = surface_and_grid(2.3, 200.0);
        let (delta, phi0) = (100.0, 30.0f64);
        let face = FaceLevelling {
            tilt_in_per_in: delta * 1e-6,
            zero_phase_deg: phi0,
        };
        for seed in [1, 99] {
            let r = read(
                &grid,
                &surf,
                surf.contact_gain(),
                &CmmLevels::face_only(face),
                seed,
            );
            for (i, (a, b)) in grid.err_uin.iter().zip(&r.err_uin).enumerate() {
                let phi = (10.0 * i as f64).to_radians();
                for (j, (a, b)) in a.iter().zip(b).enumerate() {
                    let expect = delta * CMM_X_IN[j] * (phi - phi0.to_radians()).sin();
                    let got = b.unwrap() - a.unwrap();
                    assert!(
                        (got - expect).abs() < 1e-9,
                        "φ {i}0°, X {}: {got} vs {expect}",
                        CMM_X_IN[j]
                    );
                }
            }
        }
    }

    /// The mean of n readings by a CMM with only its repeatability and its
    /// step: the error's RMS over the 252 points is the one reading's
    /// `√(σ² + step²/12)` = 23.0 µin over √n, within 3.5 standard errors
    /// of an RMS of 252 samples (1/√(2·252) of it); one reading is
    /// `read` itself.
    #[test]
    fn the_mean_of_n_readings_has_the_noise_of_one_over_root_n() {
        let (surf, grid) = surface_and_grid(3.71, 400.0);
        let lv = CmmLevels {
            tilt_in_per_in: 0.0,
            angle_datum_deg: 0.0,
            ..CmmLevels::renault()
        };
        let one = (lv.repeatability_in.powi(2) + lv.resolution_in.powi(2) / 12.0).sqrt() * 1e6;
        let gain = surf.contact_gain();
        assert_eq!(
            read_averaged(&grid, &surf, gain, &lv, 5, 1).err_uin,
            read(&grid, &surf, gain, &lv, 5).err_uin
        );
        for n in [1u32, 4, 16, 64] {
            let r = read_averaged(&grid, &surf, gain, &lv, 5, n);
            let d: Vec<f64> = grid
                .err_uin
                .iter()
                .flatten()
                .zip(r.err_uin.iter().flatten())
                .map(|(a, b)| b.unwrap() - a.unwrap())
                .collect();
            let rms = (d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64).sqrt();
            let expect = one / f64::from(n).sqrt();
            let tol = 3.5 * expect / (2.0 * d.len() as f64).sqrt();
            eprintln!("{n} readings: RMS {rms:.2} µin, expected {expect:.2} ± {tol:.2}");
            assert!(
                (rms - expect).abs() <= tol,
                "{n} readings: RMS {rms:.2} vs {expect:.2} ± {tol:.2}"
            );
        }
    }
}
