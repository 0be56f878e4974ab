//! The smallest table that meets an error bound.

use super::budget::{error_split, ErrorSplit, Sampling};
use super::generate::generate;
use super::spec::{SpecError, TableSpec};

/// Grid steps the picker tries, coarse to fine (binary fractions first at
/// equal size: the firmware then finds the node by a shift).
pub const CANDIDATE_STEPS: &[f64] = &[
    0.25, 0.2, 0.125, 0.1, 0.0625, 0.05, 0.04, 0.03125, 0.025, 0.02, 0.015625, 0.0125, 0.01,
];

/// Binary-fraction steps only: with them the firmware finds the node and
/// the interpolation fraction of a binary X by a shift, not a division.
pub const BINARY_STEPS: &[f64] = &[0.25, 0.125, 0.0625, 0.03125, 0.015625, 0.0078125];

/// One candidate the picker measured.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PickResult {
    pub step_in: f64,
    pub terms: usize,
    pub columns: usize,
    pub bytes: usize,
    pub errors: ErrorSplit,
}

/// Picks the smallest table (bytes) of `base`'s representation and formats
/// whose total error over `[x_lo, x_hi]`, plus `firmware_allowance_uin` for
/// the firmware's own arithmetic, is within `bound_uin`. Tries the steps of
/// `steps` (e.g. [`CANDIDATE_STEPS`] or [`BINARY_STEPS`]) that divide the
/// range, and terms up to `max_terms`. Returns `None` if nothing meets the
/// bound.
#[allow(clippy::too_many_arguments)]
pub fn pick(
    base: &TableSpec,
    steps: &[f64],
    bound_uin: f64,
    firmware_allowance_uin: f64,
    x_lo: f64,
    x_hi: f64,
    max_terms: usize,
    sampling: Sampling,
) -> Result<Option<PickResult>, SpecError> {
    // For each term count, grids from coarse to fine: the first that meets
    // the budget is the smallest table with those terms. Truncation does not
    // depend on the grid, so a term count whose truncation alone exceeds the
    // budget is abandoned at once.
    let budget = bound_uin - firmware_allowance_uin;
    let mut best: Option<PickResult> = None;
    for terms in 1..=max_terms {
        for &step in steps {
            let spec = TableSpec {
                step,
                terms,
                ..base.clone()
            };
            if spec.validate().is_err() {
                continue;
            }
            let bytes = zslide::table::HEADER_LEN + spec.node_count() * spec.columns() * 4;
            if best.as_ref().is_some_and(|b| b.bytes <= bytes) {
                continue;
            }
            let g = generate(&spec)?;
            let errors = error_split(&g, x_lo, x_hi, sampling)?;
            if errors.truncation_uin > budget {
                break; // no grid fixes truncation
            }
            if errors.total_uin <= budget {
                best = Some(PickResult {
                    step_in: step,
                    terms,
                    columns: spec.columns(),
                    bytes,
                    errors,
                });
                break; // finer grids with these terms are only bigger
            }
        }
    }
    Ok(best)
}
