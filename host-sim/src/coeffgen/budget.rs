//! What the firmware's approximation of the command costs, split into
//! truncation (terms), interpolation (grid) and quantisation
//! (`docs/COEFFICIENTS.md`).

use super::fit::{columns_of, eval_columns};
use super::generate::Generated;
use super::spec::{SpecError, TableSpec};
use crate::surface::Section;
use std::f64::consts::PI;
use zslide::table::Representation;

/// Linear interpolation of node-major columns at X (f64 mirror of the
/// firmware's fixed-point interpolation), clamped to the grid.
pub fn interpolate(x_nodes: &[f64], cols: &[Vec<f64>], x: f64) -> Vec<f64> {
    let n = x_nodes.len();
    let x0 = x_nodes[0];
    let dx = (x_nodes[n - 1] - x0) / (n - 1) as f64;
    let f = ((x - x0) / dx).clamp(0.0, (n - 1) as f64);
    let i = (f.floor() as usize).min(n - 2);
    let t = f - i as f64;
    cols[i]
        .iter()
        .zip(&cols[i + 1])
        .map(|(a, b)| a + t * (b - a))
        .collect()
}

/// Maximum errors of the command approximation, microinches, over the X range
/// of the report and all φ.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ErrorSplit {
    /// Series truncated to the table's terms, exact coefficients at X.
    pub truncation_uin: f64,
    /// Linear interpolation of exact nodal coefficients vs exact at X (series
    /// level, same terms).
    pub interpolation_uin: f64,
    /// Quantised vs exact nodal coefficients, interpolated.
    pub quantization_uin: f64,
    /// Everything: interpolated quantised series vs the exact surface.
    pub total_uin: f64,
    /// `total` restricted to the grid nodes.
    pub total_at_nodes_uin: f64,
    /// `total` midway between nodes.
    pub total_midway_uin: f64,
    /// Largest peak-to-peak Z motion over φ in the range, inches (the slide
    /// must be able to make it: ±0.010 in for the 1983 gauge).
    pub z_peak_to_peak_in: f64,
    /// Where `total` peaks.
    pub worst_x_in: f64,
    pub worst_phi_deg: f64,
}

/// Sampling density of the error report.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sampling {
    /// X samples per grid interval (≥ 2; 0 and ½ are always included).
    pub per_interval: usize,
    /// φ samples per turn.
    pub phi: usize,
}

impl Default for Sampling {
    fn default() -> Self {
        Self {
            per_interval: 4,
            phi: 720,
        }
    }
}

/// What the error split measures a table against: the exact section at
/// X, its columns in the table's representation, and Z at φ (the
/// paraboloid of a `TableSpec`, or a part of one's own: `part::table`).
pub trait SectionSource {
    type Section;
    type Error;
    fn section(&self, x: f64) -> Result<Self::Section, Self::Error>;
    /// The section's exact columns in the table's representation and terms.
    fn columns(&self, sec: &Self::Section) -> Vec<f64>;
    fn z(&self, sec: &Self::Section, phi: f64) -> Result<f64, Self::Error>;
}

/// A table's nodes and columns as the split reads them.
pub struct TableColumns<'a> {
    pub representation: Representation,
    /// Node X, in (uniform).
    pub x: &'a [f64],
    /// Exact and quantised columns, node-major.
    pub exact: &'a [Vec<f64>],
    pub quantised: &'a [Vec<f64>],
}

/// The paraboloid of a coeffgen spec.
struct SpecSurface<'a>(&'a TableSpec);

impl SectionSource for SpecSurface<'_> {
    type Section = Section;
    type Error = SpecError;
    fn section(&self, x: f64) -> Result<Section, SpecError> {
        Ok(self.0.surface.section(x)?)
    }
    fn columns(&self, sec: &Section) -> Vec<f64> {
        columns_of(sec, self.0.representation, self.0.terms)
    }
    fn z(&self, sec: &Section, phi: f64) -> Result<f64, SpecError> {
        Ok(sec.z(phi))
    }
}

/// Measures the error split of a generated table over `[x_lo, x_hi]`.
pub fn error_split(
    g: &Generated,
    x_lo: f64,
    x_hi: f64,
    sampling: Sampling,
) -> Result<ErrorSplit, SpecError> {
    let quant: Vec<Vec<f64>> = (0..g.x.len()).map(|i| g.quantised(i)).collect();
    let table = TableColumns {
        representation: g.spec.representation,
        x: &g.x,
        exact: &g.cols,
        quantised: &quant,
    };
    split_of(&SpecSurface(&g.spec), &table, x_lo, x_hi, sampling)
}

/// The error split of `table` against `src` over `[x_lo, x_hi]`: at
/// `sampling.per_interval` X an interval and `sampling.phi` φ a turn,
/// truncation (exact columns vs Z), interpolation (interpolated exact vs
/// exact columns), quantisation (interpolated quantised vs interpolated
/// exact) and the total (interpolated quantised vs Z).
pub fn split_of<S: SectionSource>(
    src: &S,
    table: &TableColumns,
    x_lo: f64,
    x_hi: f64,
    sampling: Sampling,
) -> Result<ErrorSplit, S::Error> {
    let rep = table.representation;
    let xs = table.x;
    let n_iv = xs.len() - 1;
    let dx = (xs[n_iv] - xs[0]) / n_iv as f64;
    let per = sampling.per_interval.max(2);
    let phis: Vec<f64> = (0..sampling.phi)
        .map(|j| 2.0 * PI * j as f64 / sampling.phi as f64)
        .collect();
    let mut e = ErrorSplit {
        truncation_uin: 0.0,
        interpolation_uin: 0.0,
        quantization_uin: 0.0,
        total_uin: 0.0,
        total_at_nodes_uin: 0.0,
        total_midway_uin: 0.0,
        z_peak_to_peak_in: 0.0,
        worst_x_in: x_lo,
        worst_phi_deg: 0.0,
    };
    for iv in 0..=n_iv {
        for k in 0..per {
            if iv == n_iv && k > 0 {
                break;
            }
            let x = xs[0] + (iv as f64 + k as f64 / per as f64) * dx;
            if x < x_lo - 1e-12 || x > x_hi + 1e-12 {
                continue;
            }
            let sec = src.section(x)?;
            let exact_cols = src.columns(&sec);
            let interp_cols = interpolate(xs, table.exact, x);
            let interp_q = interpolate(xs, table.quantised, x);
            let at_node = k == 0;
            let midway = 2 * k == per;
            let (mut z_lo, mut z_hi) = (f64::MAX, f64::MIN);
            for &phi in &phis {
                let z = src.z(&sec, phi)?;
                z_lo = z_lo.min(z);
                z_hi = z_hi.max(z);
                let s_exact = eval_columns(rep, &exact_cols, phi);
                let s_interp = eval_columns(rep, &interp_cols, phi);
                let s_q = eval_columns(rep, &interp_q, phi);
                let tr = (s_exact - z).abs() * 1e6;
                let ip = (s_interp - s_exact).abs() * 1e6;
                let qu = (s_q - s_interp).abs() * 1e6;
                let to = (s_q - z).abs() * 1e6;
                e.truncation_uin = e.truncation_uin.max(tr);
                e.interpolation_uin = e.interpolation_uin.max(ip);
                e.quantization_uin = e.quantization_uin.max(qu);
                if to > e.total_uin {
                    e.total_uin = to;
                    e.worst_x_in = x;
                    e.worst_phi_deg = phi.to_degrees();
                }
                if at_node {
                    e.total_at_nodes_uin = e.total_at_nodes_uin.max(to);
                }
                if midway {
                    e.total_midway_uin = e.total_midway_uin.max(to);
                }
            }
            e.z_peak_to_peak_in = e.z_peak_to_peak_in.max(z_hi - z_lo);
        }
    }
    Ok(e)
}

/// Worst-case bound of the quantisation error from the format alone:
/// half an LSB per column times the column's largest basis value (1).
pub fn quantization_bound_uin(spec: &TableSpec) -> f64 {
    spec.columns() as f64 * 0.5 * (-f64::from(spec.coeff_frac_bits)).exp2() * 1e6
}
