//! The plots of `cut --out DIR`, each as PNG and SVG with the CSV behind it:
//!
//! * `error_map`: the CMM error against φ, one curve per radius X = 1..7 in
//!   (Figures 5-6, 5-8);
//! * `error_x7`: the error at X = 7 in against φ, one curve per controller
//!   (Figures 5-7, 5-9);
//! * `following_error`: the following error (the slide's true position
//!   minus the exact command at the true X and φ) and the cutting force, tick by tick, over the trace window.
//!
//! Drawing and CSV: [`crate::plot`].

use super::part::{cmm_phi_deg, CmmGrid, CMM_X_IN};
pub use crate::plot::{write_plot, Series};

/// Error against φ at one radius column of a grid (NaN where unmeasured),
/// closed at 360° with the 0° value (the same point of the part), so that
/// the curve spans the whole turn.
pub fn column(grid: &CmmGrid, j: usize) -> Vec<(f64, f64)> {
    let mut c: Vec<(f64, f64)> = cmm_phi_deg()
        .into_iter()
        .zip(&grid.err_uin)
        .map(|(phi, row)| (phi, row[j].unwrap_or(f64::NAN)))
        .collect();
    if let Some(&(_, first)) = c.first() {
        c.push((360.0, first));
    }
    c
}

/// The error map: one curve per CMM radius.
pub fn error_map_series(grid: &CmmGrid) -> Vec<Series> {
    CMM_X_IN
        .iter()
        .enumerate()
        .map(|(j, x)| Series {
            label: format!("X = {x} in"),
            points: column(grid, j),
        })
        .collect()
}
