//! The process stiffness (`zslide identify --in-cut`): the engaged part
//! is a spring and a damper between the slide's carriage and the frame,
//! so the slide's response in a light test cut is the in-air plant (the
//! fit of an earlier `identify`) with `k + c·s` added to its mechanical
//! impedance `m s² + B s`. Below about twice the spring's own frequency
//! (√(k/m)/2π: 58 Hz for legacy-hw's 0.0162 lbf s²/in on 2200 lbf/in) the
//! spring is most of that impedance; far above it the mass hides it.
//!
//! Each measured frequency gives (k, c) by solving `H(f; k, c) = H_meas`
//! (Newton on 1/H, which is nearly affine in k and c), with its 2×2
//! covariance from the point's measured spread through the model's
//! Jacobian. The frequencies combine by their information (inverse
//! covariance); when their scatter exceeds what their own spreads explain
//! (χ² per degree of freedom above 1), the uncertainty is widened by its
//! square root.

use std::path::Path;

use nalgebra::{Complex, Matrix2, Vector2};

use crate::fit::{Known, Plant};
use crate::measured::Measured;
use crate::Result;

/// The process as measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Process {
    pub stiffness_lbf_per_in: f64,
    /// One sigma, lbf/in.
    pub stiffness_sigma: f64,
    pub damping_lbf_s_per_in: f64,
    /// One sigma, lbf s/in.
    pub damping_sigma: f64,
    /// χ² per degree of freedom of the frequencies about the combined
    /// value (≈ 1: the scatter is the noise).
    pub chi2: f64,
}

/// One frequency's (k, c) and covariance.
#[derive(Clone, Copy, Debug)]
pub struct PointEstimate {
    pub f_hz: f64,
    pub k: f64,
    pub c: f64,
    pub cov: Matrix2<f64>,
}

/// The two real equations of a complex residual, scaled by `1/H`'s size.
fn re_im(z: Complex<f64>) -> Vector2<f64> {
    Vector2::new(z.re, z.im)
}

/// (k, c) at one measured point against the in-air plant `air`.
pub fn at_point(known: &Known, air: &Plant, m: &Measured) -> Result<PointEstimate> {
    let g_meas = 1.0 / m.h;
    let g = |k: f64, c: f64| 1.0 / known.response_engaged(air, k, c, m.f_hz);
    // Steps for the Jacobian: small against a part's (10³..10⁴ lbf/in,
    // a few lbf s/in), large against rounding.
    let (dk, dc) = (1.0, 1e-3);
    let jac = |k: f64, c: f64| {
        let g0 = g(k, c);
        let jk = re_im((g(k + dk, c) - g0) / dk);
        let jc = re_im((g(k, c + dc) - g0) / dc);
        Matrix2::from_columns(&[jk, jc])
    };
    let (mut k, mut c) = (0.0, 0.0);
    for _ in 0..8 {
        let r = re_im(g_meas - g(k, c));
        let step = jac(k, c)
            .lu()
            .solve(&r)
            .ok_or_else(|| format!("{:.1} Hz: the process is not observable there", m.f_hz))?;
        k += step[0];
        c += step[1];
        if step[0].abs() < 1e-6 * k.abs().max(1.0) && step[1].abs() < 1e-9 {
            break;
        }
    }
    let j = jac(k, c);
    // The point's relative spread is circular complex noise on 1/H: each
    // real component carries half its variance.
    let var = (g_meas.norm() * m.rel_sigma).powi(2) / 2.0;
    let cov = (j.transpose() * j)
        .try_inverse()
        .ok_or_else(|| format!("{:.1} Hz: the process is not observable there", m.f_hz))?
        * var;
    Ok(PointEstimate {
        f_hz: m.f_hz,
        k,
        c,
        cov,
    })
}

/// The frequencies combined by their information.
pub fn combine(pts: &[PointEstimate]) -> Result<Process> {
    if pts.len() < 2 {
        return Err("the process needs at least two measured frequencies".into());
    }
    let mut info = Matrix2::zeros();
    let mut v = Vector2::zeros();
    let inv: Vec<Matrix2<f64>> = pts
        .iter()
        .map(|p| {
            p.cov
                .try_inverse()
                .ok_or_else(|| format!("{:.1} Hz: a singular covariance", p.f_hz))
        })
        .collect::<Result<_>>()?;
    for (p, w) in pts.iter().zip(&inv) {
        info += w;
        v += w * Vector2::new(p.k, p.c);
    }
    let cov = info
        .try_inverse()
        .ok_or("the frequencies do not determine the process")?;
    let theta = cov * v;
    let chi2_sum: f64 = pts
        .iter()
        .zip(&inv)
        .map(|(p, w)| {
            let d = Vector2::new(p.k, p.c) - theta;
            (d.transpose() * w * d)[0]
        })
        .sum();
    let chi2 = chi2_sum / (2.0 * (pts.len() - 1) as f64);
    let widen = chi2.max(1.0).sqrt();
    Ok(Process {
        stiffness_lbf_per_in: theta[0],
        stiffness_sigma: cov[(0, 0)].sqrt() * widen,
        damping_lbf_s_per_in: theta[1],
        damping_sigma: cov[(1, 1)].sqrt() * widen,
        chi2,
    })
}

/// The process's file: `name = value` lines.
pub fn process_text(p: &Process, air: &Path) -> String {
    format!(
        "# zslide identify --in-cut: the process measured against {}\n\
         stiffness_lbf_per_in = {}\nstiffness_sigma = {}\ndamping_lbf_s_per_in = {}\n\
         damping_sigma = {}\nchi2 = {}\n",
        air.display(),
        p.stiffness_lbf_per_in,
        p.stiffness_sigma,
        p.damping_lbf_s_per_in,
        p.damping_sigma,
        p.chi2
    )
}

/// Reads [`process_text`]'s file; every field is required, nothing else
/// is accepted, and the stiffness must be a spring (finite, its sigma
/// positive).
pub fn read_process(path: &Path) -> Result<Process> {
    let mut v = crate::fields::read_fields(path)?;
    let mut take = |k: &str| {
        v.remove(k)
            .ok_or_else(|| format!("{}: no {k}", path.display()))
    };
    let p = Process {
        stiffness_lbf_per_in: take("stiffness_lbf_per_in")?,
        stiffness_sigma: take("stiffness_sigma")?,
        damping_lbf_s_per_in: take("damping_lbf_s_per_in")?,
        damping_sigma: take("damping_sigma")?,
        chi2: take("chi2")?,
    };
    if let Some(k) = v.keys().next() {
        return Err(format!("{}: unknown field {k}", path.display()));
    }
    if !(p.stiffness_lbf_per_in.is_finite() && p.stiffness_sigma.is_finite())
        || p.stiffness_sigma < 0.0
    {
        return Err(format!(
            "{}: stiffness {} ± {} lbf/in is not a measured spring",
            path.display(),
            p.stiffness_lbf_per_in,
            p.stiffness_sigma
        ));
    }
    Ok(p)
}

/// The stiffnesses `tune` checks a design's margins at: the measured one
/// and its two-sigma bounds (not below 0: in air).
pub fn stiffnesses_checked(p: &Process) -> [f64; 3] {
    let k = p.stiffness_lbf_per_in;
    let s = 2.0 * p.stiffness_sigma;
    [(k - s).max(0.0), k.max(0.0), k + s]
}
