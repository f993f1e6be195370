//! Applying a [`RowPlan`] in place: the same result as [`RowPlan::apply`], without allocating
//! a second copy of the array.
//!
//! `RowPlan::apply` builds a new vector, which for the large per-Gaussian arrays (parameters and
//! Adam moments, hundreds of MB at 1M Gaussians) costs a fresh allocation, its page faults and
//! the release of the old one. Here the parents' rows of the appended rows (a few percent) are
//! gathered first, then kept rows are moved down in place (`kept` is strictly increasing, so a
//! kept row never moves to a later position and never overwrites a row not yet moved), and the
//! gathered rows are appended. Equality with `RowPlan::apply` is a property test.

use evo_state::rows::RowPlanError;
use evo_state::{NewRows, RowPlan};

/// Applies `plan` to `data` (rows of `stride` elements) in place; same result and errors as
/// [`RowPlan::apply`], and `data` is unchanged on error.
pub fn apply_in_place<T: Copy>(
    plan: &RowPlan,
    data: &mut Vec<T>,
    stride: usize,
    new_rows: NewRows<T>,
) -> Result<(), RowPlanError> {
    if stride == 0 || !data.len().is_multiple_of(stride) {
        return Err(RowPlanError::BadStride {
            len: data.len(),
            stride,
        });
    }
    plan.validate(data.len() / stride)?;
    let appended: Vec<T> = match new_rows {
        NewRows::CopyParent => {
            let mut out = Vec::with_capacity(plan.parent_from_new.len() * stride);
            for &p in &plan.parent_from_new {
                let s = p as usize * stride;
                out.extend_from_slice(&data[s..s + stride]);
            }
            out
        }
        NewRows::Fill(v) => vec![v; plan.parent_from_new.len() * stride],
    };
    // Rows before the first gap stay where they are.
    let unmoved = plan
        .kept
        .iter()
        .enumerate()
        .take_while(|&(j, &row)| j == row as usize)
        .count();
    if stride == 1 {
        for (j, &row) in plan.kept.iter().enumerate().skip(unmoved) {
            data[j] = data[row as usize];
        }
    } else {
        for (j, &row) in plan.kept.iter().enumerate().skip(unmoved) {
            let src = row as usize * stride;
            data.copy_within(src..src + stride, j * stride);
        }
    }
    data.truncate(plan.kept.len() * stride);
    data.reserve_exact(appended.len());
    data.extend_from_slice(&appended);
    Ok(())
}
