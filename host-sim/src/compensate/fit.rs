//! The smooth error surface a measurement supports: Zernike terms
//! (Noll's standard set, `part::zernike`) fitted by least squares, the
//! radial order chosen by leave-one-out cross-validation.
//!
//! A shop's measurement is sparse (chapter 5's grid: 252 points) and noisy
//! (the CMM's 1 µm step and repeatability). Terms up to radial order n
//! (`(n+1)(n+2)/2` of them) are fitted for every n the data can carry
//! (at most a third as many terms as points, n ≤ [`MAX_ORDER`]); the order
//! kept is the one whose leave-one-out prediction error is least (PRESS:
//! `Σ (r_i / (1 − h_ii))²`, h the hat matrix's diagonal, exact for least
//! squares). What the kept fit leaves is what it treats as noise: the
//! residual RMS, and `σ̂ = √(Σ r² / (N − p))`, the noise it implies.
//!
//! Refused, with the reason ([`Limits`]): fewer than `min_points`
//! points; a point of the part farther than `max_hole_in` from every
//! measured point (a hole in the coverage, named by its place); a `σ̂`
//! above `noise_factor` × the instrument's stated noise (the surface has
//! structure the terms cannot follow, or the file is not what it says).

use crate::part::zernike::{Ordering, Zernike};
use crate::part::Sag;
use nalgebra::{DMatrix, DVector};

/// Highest radial order tried (the Noll set `part::zernike` carries:
/// 120 terms to order 14).
pub const MAX_ORDER: u32 = 14;

/// Terms of radial orders 0..=n.
pub fn terms_to_order(n: u32) -> usize {
    ((n + 1) * (n + 2) / 2) as usize
}

/// What a fit refuses.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Limits {
    /// Fewest points a fit accepts.
    pub min_points: usize,
    /// Largest distance, in, from a point of the part to the nearest
    /// measured point (chapter 5's grid leaves 1.0 in at the centre).
    pub max_hole_in: f64,
    /// The fit's σ̂ may exceed the instrument's noise by this factor.
    pub noise_factor: f64,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            min_points: 10,
            max_hole_in: 1.25,
            noise_factor: 3.0,
        }
    }
}

/// One measured point in the part frame: `x = X cos φ`, `y = X sin φ`,
/// error along the axis, µin, positive = excess stock.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    pub x_in: f64,
    pub y_in: f64,
    pub error_uin: f64,
}

/// Cross-validation of one order.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct OrderScore {
    pub order: u32,
    pub terms: usize,
    /// Leave-one-out prediction error, RMS µin.
    pub loo_rms_uin: f64,
    /// Residual of the fit to all points, RMS µin.
    pub residual_rms_uin: f64,
}

/// A kept fit.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ErrorFit {
    /// Zernike normalisation radius, in (the part's outer table radius).
    pub radius_in: f64,
    /// Radial order kept.
    pub order: u32,
    /// Noll-standard coefficients, µin (j = 1..).
    pub coefficients_uin: Vec<f64>,
    pub points: usize,
    /// Residual RMS over the points, µin.
    pub residual_rms_uin: f64,
    /// The noise the residual implies, `√(Σ r² / (N − p))`, µin.
    pub noise_estimate_uin: f64,
    /// Leave-one-out prediction error of the kept order, RMS µin.
    pub loo_rms_uin: f64,
    /// Share of the measurement's variance about its mean the fit leaves
    /// (treats as noise).
    pub noise_share: f64,
    /// Noll indices fitted but left out of the correction: the
    /// measurement's set-up terms ([`TILT`]), which one measurement cannot
    /// tell from the instrument's own alignment. Fitted all the same, so
    /// that the other terms are estimated free of them.
    #[serde(default)]
    pub excluded: Vec<usize>,
}

/// Noll's tilt terms (`j` = 2, 3: `2ρ cos θ`, `2ρ sin θ`): a plane through
/// the axis, what a CMM's alignment to the part's face leaves in a
/// direction of its own each measurement (`cut::cmm`).
pub const TILT: [usize; 2] = [2, 3];

impl ErrorFit {
    /// The fitted error as a surface, in (`part::zernike`).
    pub fn surface(&self) -> Result<Zernike, String> {
        let c: Vec<f64> = self
            .coefficients_uin
            .iter()
            .enumerate()
            .map(|(i, v)| {
                if self.excluded.contains(&(i + 1)) {
                    0.0
                } else {
                    v * 1e-6
                }
            })
            .collect();
        Zernike::new(Ordering::Standard, self.radius_in, None, &c)
    }

    /// The fitted tilt's height at the fit's radius, µin (`2·|(a₂, a₃)|`:
    /// Noll's tilt peaks at 2 on the unit circle); 0 when the fit has none.
    pub fn tilt_edge_uin(&self) -> f64 {
        let a = |j: usize| self.coefficients_uin.get(j - 1).copied().unwrap_or(0.0);
        2.0 * a(TILT[0]).hypot(a(TILT[1]))
    }
}

/// The fit and the cross-validation of every order tried.
#[derive(Clone, Debug)]
pub struct FitReport {
    pub fit: ErrorFit,
    pub orders: Vec<OrderScore>,
    /// Largest distance from a point of the part to a measured point, in.
    pub largest_hole_in: f64,
}

/// The largest distance from a point of the disc `r ≤ radius` (sampled
/// every 0.02·radius in r and 1° in φ) to the nearest of `pts`, and where.
pub fn largest_hole(pts: &[Point], radius: f64) -> (f64, f64, f64) {
    let mut worst = (0.0, 0.0, 0.0);
    for i in 0..=50 {
        let r = radius * f64::from(i) / 50.0;
        for k in 0..360 {
            let (s, c) = f64::from(k).to_radians().sin_cos();
            let (x, y) = (r * c, r * s);
            let d = pts
                .iter()
                .map(|p| (p.x_in - x).hypot(p.y_in - y))
                .fold(f64::INFINITY, f64::min);
            if d > worst.0 {
                worst = (d, r, f64::from(k));
            }
            if i == 0 {
                break;
            }
        }
    }
    worst
}

/// Basis values of the first `p` Noll terms at each point (normalised on
/// `radius`).
fn design(pts: &[Point], radius: f64, p: usize) -> Result<DMatrix<f64>, String> {
    let mut a = DMatrix::zeros(pts.len(), p);
    for j in 0..p {
        let mut unit = vec![0.0; j + 1];
        unit[j] = 1.0;
        let zj = Zernike::new(Ordering::Standard, radius, None, &unit)?;
        for (i, pt) in pts.iter().enumerate() {
            a[(i, j)] = zj.sag(pt.x_in, pt.y_in);
        }
    }
    Ok(a)
}

/// Least squares of `b` on the first `p` columns of `a`: coefficients,
/// residuals and leverages (SVD; columns the data cannot tell apart get
/// no weight).
fn solve(a: &DMatrix<f64>, b: &DVector<f64>) -> (DVector<f64>, DVector<f64>, Vec<f64>) {
    let svd = a.clone().svd(true, true);
    let smax = svd.singular_values.max();
    let tol = smax * 1e-10 * a.nrows().max(a.ncols()) as f64;
    let u = svd.u.as_ref().expect("u requested");
    let h: Vec<f64> = (0..a.nrows())
        .map(|i| {
            (0..svd.singular_values.len())
                .filter(|&k| svd.singular_values[k] > tol)
                .map(|k| u[(i, k)] * u[(i, k)])
                .sum()
        })
        .collect();
    let c = svd.solve(b, tol).expect("u and v_t requested");
    let r = b - a * &c;
    (c, r, h)
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    (s / n.max(1) as f64).sqrt()
}

/// Fits the error surface to `pts` over the disc of `radius` in (the part's
/// table range, which the coverage check spans), against an instrument of
/// `instrument_noise_uin` (1σ). `Err` says why the data cannot support a fit.
pub fn fit(
    pts: &[Point],
    radius: f64,
    instrument_noise_uin: f64,
    limits: &Limits,
) -> Result<FitReport, String> {
    let n = pts.len();
    if n < limits.min_points {
        return Err(format!(
            "{n} measured points: a fit needs at least {} (too few points)",
            limits.min_points
        ));
    }
    let (hole, hr, hphi) = largest_hole(pts, radius);
    if hole > limits.max_hole_in {
        return Err(format!(
            "a hole in the coverage: the point at X = {hr:.2} in, φ = {hphi:.0}° is {hole:.2} in from \
             the nearest measured point (at most {} in accepted): the fit would be a guess there",
            limits.max_hole_in
        ));
    }
    let b = DVector::from_iterator(n, pts.iter().map(|p| p.error_uin));
    let mut orders = Vec::new();
    let mut best: Option<(f64, u32, DVector<f64>, DVector<f64>)> = None;
    let a_full = design(pts, radius, terms_to_order(MAX_ORDER).min(n / 3).max(1))?;
    for order in 0..=MAX_ORDER {
        let p = terms_to_order(order);
        if p > n / 3 || p > a_full.ncols() {
            break;
        }
        let a = a_full.columns(0, p).into_owned();
        let (c, r, h) = solve(&a, &b);
        let loo = rms(r.iter().zip(&h).map(|(r, h)| r / (1.0 - h).max(1e-9)));
        orders.push(OrderScore {
            order,
            terms: p,
            loo_rms_uin: loo,
            residual_rms_uin: rms(r.iter().copied()),
        });
        if best.as_ref().is_none_or(|b| loo < b.0) {
            best = Some((loo, order, c, r));
        }
    }
    let (loo, order, c, r) = best.ok_or_else(|| format!("{n} points carry no term"))?;
    let p = terms_to_order(order);
    let ss: f64 = r.iter().map(|v| v * v).sum();
    let sigma = (ss / (n - p).max(1) as f64).sqrt();
    let mean = b.mean();
    let total: f64 = b.iter().map(|v| (v - mean) * (v - mean)).sum();
    if sigma > limits.noise_factor * instrument_noise_uin {
        return Err(format!(
            "the fit (radial order {order}, {p} terms) leaves σ̂ = {sigma:.1} µin, above {} × the \
             instrument's {instrument_noise_uin} µin: the measurement has structure a smooth \
             surface cannot follow (or noise the instrument does not have)",
            limits.noise_factor
        ));
    }
    Ok(FitReport {
        fit: ErrorFit {
            radius_in: radius,
            order,
            coefficients_uin: c.iter().copied().collect(),
            points: n,
            residual_rms_uin: rms(r.iter().copied()),
            noise_estimate_uin: sigma,
            loo_rms_uin: loo,
            noise_share: if total > 0.0 { ss / total } else { 0.0 },
            excluded: vec![],
        },
        orders,
        largest_hole_in: hole,
    })
}
