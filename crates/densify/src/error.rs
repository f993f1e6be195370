//! The crate's error type.

use evo_state::EvoError;
use splat_core::RowPlanError;
use thiserror::Error;

/// Why statistics could not be accumulated, a plan made, or a plan applied.
#[derive(Debug, Error)]
pub enum DensifyError {
    /// An input slice does not have the length the Gaussian count implies.
    #[error("densify: `{field}` has {actual} entries, expected {expected}")]
    Length {
        field: &'static str,
        expected: usize,
        actual: usize,
    },
    /// An input value is unusable (non-finite, out of range).
    #[error("densify: `{field}`: {problem}")]
    Input {
        field: &'static str,
        problem: String,
    },
    /// A configuration field is out of range.
    #[error("densify config: `{field}` = {value}: {problem}")]
    Config {
        field: &'static str,
        value: String,
        problem: &'static str,
    },
    /// A per-Gaussian array does not have the row count the plan was made for (before), or
    /// did not end with the plan's row count (after: the length invariant).
    #[error("densify: per-Gaussian array `{array}` has {actual} rows, expected {expected}")]
    Rows {
        array: String,
        expected: usize,
        actual: usize,
    },
    /// The row plan could not be applied to one array.
    #[error("densify: applying the row plan to `{array}`: {source}")]
    RowPlan {
        array: String,
        #[source]
        source: RowPlanError,
    },
    /// The evolution state refused the row plan.
    #[error("densify: applying the row plan to the evolution state: {0}")]
    Evo(#[from] EvoError),
}
