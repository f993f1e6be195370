//! Row plans: one description of how a per-Gaussian array changes when Gaussians are pruned,
//! cloned or split, applied identically to every such array (parameters, optimiser moments,
//! evolution buffers, residual memory, statistics).
//!
//! A plan lists the old rows that stay, in increasing order, and for every appended row the old
//! row it descends from. The new array is `kept rows (in order) ++ appended rows`. A parent need
//! not be kept itself (a split drops the parent and appends two children).

use thiserror::Error;

/// How to fill the rows a plan appends.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NewRows<T> {
    /// Copy the parent's row (buffers, memory, parameters before a deformation-aware offset).
    CopyParent,
    /// Fill every element of the new row with one value (e.g. zero Adam moments, as 3DGS does).
    Fill(T),
}

/// A row plan. See the module doc.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct RowPlan {
    /// Old rows kept, strictly increasing.
    pub kept: Vec<u32>,
    /// For each appended row, the old row it descends from.
    pub parent_from_new: Vec<u32>,
}

/// Why a row plan cannot be applied.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum RowPlanError {
    /// `kept` names a row outside the array.
    #[error("row plan: kept[{position}] = {row} is out of range for {rows} rows")]
    KeptOutOfRange {
        /// The index into `kept`.
        position: usize,
        /// The row it names.
        row: u32,
        /// The array's row count.
        rows: usize,
    },
    /// `kept` is not strictly increasing.
    #[error("row plan: kept[{position}] = {row} is not greater than the previous kept row")]
    KeptNotIncreasing {
        /// The index into `kept`.
        position: usize,
        /// The row it names.
        row: u32,
    },
    /// `parent_from_new` names a row outside the array.
    #[error("row plan: parent_from_new[{position}] = {row} is out of range for {rows} rows")]
    ParentOutOfRange {
        /// The index into `parent_from_new` (the appended row's number).
        position: usize,
        /// The parent row it names.
        row: u32,
        /// The array's row count.
        rows: usize,
    },
    /// The array's length is not a whole number of rows.
    #[error("row plan: array of length {len} is not a whole number of rows of stride {stride}")]
    BadStride {
        /// The array's length in elements.
        len: usize,
        /// Elements per row.
        stride: usize,
    },
    /// The array does not have the number of rows the plan was made for.
    #[error("row plan: array has {actual} rows, the plan expects {expected}")]
    RowCount {
        /// The row count the plan was made for.
        expected: usize,
        /// The array's row count.
        actual: usize,
    },
}

/// A per-Gaussian container that keeps its own rows aligned through a [`RowPlan`] (EvoGS's
/// evolution state: its buffer rows of every frame and its residual memory). Densification
/// applies its plans to any such container through one adapter (`densify::Planned`), knowing
/// nothing else of it.
pub trait FollowsRowPlan {
    /// Name used in errors.
    fn label(&self) -> String;
    /// Number of rows (Gaussians) held.
    fn row_count(&self) -> usize;
    /// Applies `plan` to every per-Gaussian array of the container.
    fn follow(&mut self, plan: &RowPlan) -> Result<(), Box<dyn std::error::Error + Send + Sync>>;
}

impl<T: FollowsRowPlan + ?Sized> FollowsRowPlan for &mut T {
    fn label(&self) -> String {
        (**self).label()
    }

    fn row_count(&self) -> usize {
        (**self).row_count()
    }

    fn follow(&mut self, plan: &RowPlan) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        (**self).follow(plan)
    }
}

impl RowPlan {
    /// The plan that changes nothing for `rows` rows.
    pub fn identity(rows: usize) -> Self {
        Self {
            kept: (0..rows as u32).collect(),
            parent_from_new: Vec::new(),
        }
    }

    /// Keep the rows where `keep` is true (pruning).
    pub fn prune(keep: &[bool]) -> Self {
        let kept = keep
            .iter()
            .enumerate()
            .filter(|&(_, &k)| k)
            .map(|(i, _)| i as u32)
            .collect();
        Self {
            kept,
            parent_from_new: Vec::new(),
        }
    }

    /// Number of rows after the plan.
    pub fn new_len(&self) -> usize {
        self.kept.len() + self.parent_from_new.len()
    }

    /// Checks the plan against an array of `rows` rows.
    pub fn validate(&self, rows: usize) -> Result<(), RowPlanError> {
        let mut previous: Option<u32> = None;
        for (position, &row) in self.kept.iter().enumerate() {
            if row as usize >= rows {
                return Err(RowPlanError::KeptOutOfRange {
                    position,
                    row,
                    rows,
                });
            }
            if previous.is_some_and(|p| row <= p) {
                return Err(RowPlanError::KeptNotIncreasing { position, row });
            }
            previous = Some(row);
        }
        for (position, &row) in self.parent_from_new.iter().enumerate() {
            if row as usize >= rows {
                return Err(RowPlanError::ParentOutOfRange {
                    position,
                    row,
                    rows,
                });
            }
        }
        Ok(())
    }

    /// Applies the plan to `data`, rows of `stride` elements, in place; `data` is unchanged on
    /// error. Equal to [`RowPlan::applied`] (a property test says so) without allocating a second
    /// copy of the array, which matters for the large per-Gaussian arrays: the parents' rows of
    /// the appended rows (a few percent) are gathered first, then kept rows move down in place
    /// (`kept` is strictly increasing, so a kept row never moves to a later position and never
    /// overwrites a row not yet moved), and the gathered rows are appended.
    pub fn apply<T: Copy>(
        &self,
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
        self.validate(data.len() / stride)?;
        let appended: Vec<T> = match new_rows {
            NewRows::CopyParent => {
                let mut out = Vec::with_capacity(self.parent_from_new.len() * stride);
                for &p in &self.parent_from_new {
                    let s = p as usize * stride;
                    out.extend_from_slice(&data[s..s + stride]);
                }
                out
            }
            NewRows::Fill(v) => vec![v; self.parent_from_new.len() * stride],
        };
        // Rows before the first gap stay where they are.
        let unmoved = self
            .kept
            .iter()
            .enumerate()
            .take_while(|&(j, &row)| j == row as usize)
            .count();
        for (j, &row) in self.kept.iter().enumerate().skip(unmoved) {
            let src = row as usize * stride;
            data.copy_within(src..src + stride, j * stride);
        }
        data.truncate(self.kept.len() * stride);
        data.reserve_exact(appended.len());
        data.extend_from_slice(&appended);
        Ok(())
    }

    /// Like [`RowPlan::apply`], but also checks that `data` has `expected_rows` rows.
    pub fn apply_checked<T: Copy>(
        &self,
        data: &mut Vec<T>,
        stride: usize,
        expected_rows: usize,
        new_rows: NewRows<T>,
    ) -> Result<(), RowPlanError> {
        if let Some(actual) = data.len().checked_div(stride)
            && actual != expected_rows
        {
            return Err(RowPlanError::RowCount {
                expected: expected_rows,
                actual,
            });
        }
        self.apply(data, stride, new_rows)
    }

    /// Returns the plan applied to `src` (rows of `stride` elements), leaving `src` unchanged.
    pub fn applied<T: Copy>(
        &self,
        src: &[T],
        stride: usize,
        new_rows: NewRows<T>,
    ) -> Result<Vec<T>, RowPlanError> {
        if stride == 0 || !src.len().is_multiple_of(stride) {
            return Err(RowPlanError::BadStride {
                len: src.len(),
                stride,
            });
        }
        let rows = src.len() / stride;
        self.validate(rows)?;
        let mut out = Vec::with_capacity(self.new_len() * stride);
        for &row in &self.kept {
            let start = row as usize * stride;
            out.extend_from_slice(&src[start..start + stride]);
        }
        for &parent in &self.parent_from_new {
            match new_rows {
                NewRows::CopyParent => {
                    let start = parent as usize * stride;
                    out.extend_from_slice(&src[start..start + stride]);
                }
                NewRows::Fill(value) => out.extend(std::iter::repeat_n(value, stride)),
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn split_drops_parent_and_appends_two_children() {
        let plan = RowPlan {
            kept: vec![0, 2],
            parent_from_new: vec![1, 1],
        };
        let mut data = vec![0, 0, 1, 1, 2, 2];
        plan.apply(&mut data, 2, NewRows::CopyParent).unwrap();
        assert_eq!(data, vec![0, 0, 2, 2, 1, 1, 1, 1]);
        let mut moments = vec![5.0f32; 3];
        plan.apply(&mut moments, 1, NewRows::Fill(0.0)).unwrap();
        assert_eq!(moments, vec![5.0, 5.0, 0.0, 0.0]);
    }

    #[test]
    fn bad_plans_are_rejected() {
        let data = vec![1u8; 6];
        let out_of_range = RowPlan {
            kept: vec![0, 3],
            parent_from_new: vec![],
        };
        assert_eq!(
            out_of_range.applied(&data, 2, NewRows::CopyParent),
            Err(RowPlanError::KeptOutOfRange {
                position: 1,
                row: 3,
                rows: 3
            })
        );
        let unordered = RowPlan {
            kept: vec![1, 1],
            parent_from_new: vec![],
        };
        assert_eq!(
            unordered.validate(3),
            Err(RowPlanError::KeptNotIncreasing {
                position: 1,
                row: 1
            })
        );
        let bad_parent = RowPlan {
            kept: vec![],
            parent_from_new: vec![7],
        };
        assert_eq!(
            bad_parent.validate(3),
            Err(RowPlanError::ParentOutOfRange {
                position: 0,
                row: 7,
                rows: 3
            })
        );
        assert_eq!(
            RowPlan::identity(3).applied(&data, 4, NewRows::CopyParent),
            Err(RowPlanError::BadStride { len: 6, stride: 4 })
        );
        let mut five = vec![0u8; 5];
        assert_eq!(
            RowPlan::identity(3).apply_checked(&mut five, 1, 3, NewRows::CopyParent),
            Err(RowPlanError::RowCount {
                expected: 3,
                actual: 5
            })
        );
        // An error leaves the data untouched.
        assert_eq!(five.len(), 5);
    }

    fn plan_strategy() -> impl Strategy<Value = (usize, RowPlan)> {
        (1usize..40).prop_flat_map(|rows| {
            (
                Just(rows),
                proptest::collection::vec(any::<bool>(), rows),
                proptest::collection::vec(0..rows as u32, 0..30),
            )
                .prop_map(|(rows, keep, parents)| {
                    let mut plan = RowPlan::prune(&keep);
                    plan.parent_from_new = parents;
                    (rows, plan)
                })
        })
    }

    proptest! {
        /// Every per-Gaussian array, whatever its stride and element type, ends with the same
        /// number of rows, kept rows are unchanged and children equal their parents.
        #[test]
        fn every_array_stays_aligned((rows, plan) in plan_strategy()) {
            // Three arrays of different strides/types whose rows are tagged by their old index.
            let mut params: Vec<f32> = (0..rows * 3).map(|e| (e / 3) as f32).collect();
            let mut buffer: Vec<half::f16> =
                (0..rows * 10).map(|e| half::f16::from_f32((e / 10) as f32)).collect();
            let mut memory: Vec<u32> = (0..rows).map(|r| r as u32).collect();
            let mut moments: Vec<f32> = vec![1.0; rows * 3];
            plan.apply(&mut params, 3, NewRows::CopyParent).unwrap();
            plan.apply(&mut buffer, 10, NewRows::CopyParent).unwrap();
            plan.apply(&mut memory, 1, NewRows::CopyParent).unwrap();
            plan.apply(&mut moments, 3, NewRows::Fill(0.0)).unwrap();
            let n = plan.new_len();
            prop_assert_eq!(params.len(), n * 3);
            prop_assert_eq!(buffer.len(), n * 10);
            prop_assert_eq!(memory.len(), n);
            prop_assert_eq!(moments.len(), n * 3);
            let origin: Vec<u32> =
                plan.kept.iter().chain(plan.parent_from_new.iter()).copied().collect();
            for (new_row, &old) in origin.iter().enumerate() {
                prop_assert_eq!(memory[new_row], old);
                prop_assert!(params[new_row * 3..new_row * 3 + 3].iter().all(|&v| v == old as f32));
                prop_assert!(buffer[new_row * 10..new_row * 10 + 10]
                    .iter()
                    .all(|&v| v.to_f32() == old as f32));
                let expected_moment = if new_row < plan.kept.len() { 1.0 } else { 0.0 };
                prop_assert!(moments[new_row * 3..new_row * 3 + 3].iter().all(|&v| v == expected_moment));
            }
        }

        /// The in-place `apply` equals the copying `applied` for every stride and fill, and a
        /// failing `apply` leaves the data unchanged.
        #[test]
        fn apply_in_place_equals_applied(
            (rows, plan) in plan_strategy(),
            stride in 1usize..5,
            fill in prop_oneof![Just(None), any::<i32>().prop_map(Some)],
        ) {
            let data: Vec<i32> = (0..(rows * stride) as i32).collect();
            let new_rows = fill.map_or(NewRows::CopyParent, NewRows::Fill);
            let expected = plan.applied(&data, stride, new_rows).unwrap();
            let mut got = data.clone();
            plan.apply(&mut got, stride, new_rows).unwrap();
            prop_assert_eq!(got, expected);
            if stride > 1 {
                let mut bad = data.clone();
                bad.push(0);
                prop_assert!(plan.apply(&mut bad, stride, new_rows).is_err());
                prop_assert_eq!(&bad[..data.len()], &data[..]);
            }
        }
    }
}
