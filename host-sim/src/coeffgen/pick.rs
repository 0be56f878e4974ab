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
    let spec_of = |step, terms| {
        let spec = TableSpec {
            step,
            terms,
            ..base.clone()
        };
        spec.validate().is_ok().then_some(spec)
    };
    pick_smallest(
        steps,
        max_terms,
        bound_uin - firmware_allowance_uin,
        |step, terms| {
            spec_of(step, terms).map(|s| {
                let bytes = zslide::table::HEADER_LEN + s.node_count() * s.columns() * 4;
                (bytes, s.columns())
            })
        },
        |step, terms| {
            let spec = TableSpec {
                step,
                terms,
                ..base.clone()
            };
            error_split(&generate(&spec)?, x_lo, x_hi, sampling)
        },
    )
}

/// The picker's search, for any table builder (this module's tables and a
/// part's, `crate::part::table`): for each term count (1..=`max_terms`),
/// grids from coarse to fine; the first that meets `budget_uin` is the
/// smallest table with those terms. Truncation does not depend on the
/// grid, so a term count whose truncation alone exceeds the budget is
/// abandoned at once. `size(step, terms)` gives the table's bytes and
/// columns per node (`None`: a grid the format refuses); `measure(step,
/// terms)` its errors, called only for a table smaller than the best so
/// far.
pub fn pick_smallest<E>(
    steps: &[f64],
    max_terms: usize,
    budget_uin: f64,
    size: impl Fn(f64, usize) -> Option<(usize, usize)>,
    mut measure: impl FnMut(f64, usize) -> Result<ErrorSplit, E>,
) -> Result<Option<PickResult>, E> {
    let mut best: Option<PickResult> = None;
    for terms in 1..=max_terms {
        for &step in steps {
            let Some((bytes, columns)) = size(step, terms) else {
                continue;
            };
            if best.as_ref().is_some_and(|b| b.bytes <= bytes) {
                continue;
            }
            let errors = measure(step, terms)?;
            if errors.truncation_uin > budget_uin {
                break; // no grid fixes truncation
            }
            if errors.total_uin <= budget_uin {
                best = Some(PickResult {
                    step_in: step,
                    terms,
                    columns,
                    bytes,
                    errors,
                });
                break; // finer grids with these terms are only bigger
            }
        }
    }
    Ok(best)
}
