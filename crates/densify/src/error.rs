//! The crate's error type.

use splat_core::RowPlanError;
use thiserror::Error;

/// Why statistics could not be accumulated, a plan made, or a plan applied.
#[derive(Debug, Error)]
pub enum DensifyError {
    /// An input slice does not have the length the Gaussian count implies.
    #[error("densify: `{field}` has {actual} entries, expected {expected}")]
    Length {
        /// The input, by name (e.g. `stats`, `deformation.corrected`).
        field: &'static str,
        /// The length the Gaussian count implies.
        expected: usize,
        /// Its length.
        actual: usize,
    },
    /// An input value is unusable (non-finite, out of range).
    #[error("densify: `{field}`: {problem}")]
    Input {
        /// The input, by name (e.g. `extent`, `plan.reset_rows`).
        field: &'static str,
        /// What is wrong with it.
        problem: String,
    },
    /// A configuration field is out of range.
    #[error("densify config: `{field}` = {value}: {problem}")]
    Config {
        /// The field of [`crate::DensifyConfig`].
        field: &'static str,
        /// Its value, as written.
        value: String,
        /// What is wrong with it (e.g. `must be at least 1`).
        problem: &'static str,
    },
    /// A per-Gaussian array does not have the row count the plan was made for (before), or
    /// did not end with the plan's row count (after: the length invariant).
    #[error("densify: per-Gaussian array `{array}` has {actual} rows, expected {expected}")]
    Rows {
        /// The array's label ([`crate::PerGaussian::label`]).
        array: String,
        /// The row count the plan requires.
        expected: usize,
        /// Its row count.
        actual: usize,
    },
    /// The row plan could not be applied to one array.
    #[error("densify: applying the row plan to `{array}`: {source}")]
    RowPlan {
        /// The array's label ([`crate::PerGaussian::label`]).
        array: String,
        /// Why the plan did not fit the array.
        #[source]
        source: RowPlanError,
    },
    /// A container that keeps its own rows refused the row plan ([`crate::Planned`]: e.g.
    /// EvoGS's evolution state).
    #[error("densify: applying the row plan to the {array}: {source}")]
    Container {
        /// The container's label ([`crate::PerGaussian::label`]).
        array: String,
        /// Its error.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}
