//! Applying a plan: one trait, [`PerGaussian`], implemented by every per-Gaussian container,
//! and one function, [`apply_plan`], that applies a plan to a list of them and checks that they
//! all end with the plan's row count.
//!
//! What each container does with a plan:
//! - [`Gaussians`]: rows follow the [`RowPlan`] (new rows copy their parent), then the new rows'
//!   overridden values are written, then reset rows get opacity min(opacity, reset).
//! - [`Moments`] (one Adam group): new rows start at zero moments (as 3DGS's
//!   `cat_tensors_to_optimizer`); reset rows' opacity moments are zeroed (`reset_opacity` →
//!   `replace_tensor_to_optimizer`).
//! - [`Planned`]: a container that keeps its own rows through the [`RowPlan`]
//!   ([`FollowsRowPlan`]: EvoGS's evolution state, whose buffer rows of every frame and memory
//!   are copied from the parent).
//! - [`DensifyStats`]: zeroed after a densification step (3DGS's `densification_postfix`),
//!   otherwise rows follow the plan.
//! - [`Rows`]: any other array of rows, with a chosen fill for new rows.

use crate::error::DensifyError;
use crate::plan::DensifyPlan;
use crate::stats::DensifyStats;
use rayon::prelude::*;
use splat_core::Gaussians;
use splat_core::{FollowsRowPlan, NewRows, RowPlan, RowPlanError};
use tiny_nn::adam::{Adam, AdamGroup, GroupId};

/// A container of per-Gaussian rows that a plan can be applied to.
pub trait PerGaussian: Send {
    /// Name used in errors.
    fn label(&self) -> String;
    /// Number of rows (Gaussians) held.
    fn rows(&self) -> usize;
    /// Applies the plan. Called only when `rows() == plan.old_len`.
    fn apply(&mut self, plan: &DensifyPlan) -> Result<(), DensifyError>;
}

/// Applies `plan` to every array. Checks first that each has `plan.old_len` rows (nothing is
/// changed otherwise) and afterwards that each has `plan.new_len()` rows.
pub fn apply_plan(
    plan: &DensifyPlan,
    arrays: &mut [&mut dyn PerGaussian],
) -> Result<(), DensifyError> {
    plan.rows
        .validate(plan.old_len)
        .map_err(|source| DensifyError::RowPlan {
            array: "plan".into(),
            source,
        })?;
    check_plan(plan)?;
    for a in arrays.iter() {
        if a.rows() != plan.old_len {
            return Err(DensifyError::Rows {
                array: a.label(),
                expected: plan.old_len,
                actual: a.rows(),
            });
        }
    }
    // Containers are independent: apply them in parallel.
    arrays.par_iter_mut().try_for_each(|a| a.apply(plan))?;
    for a in arrays.iter() {
        if a.rows() != plan.new_len() {
            return Err(DensifyError::Rows {
                array: a.label(),
                expected: plan.new_len(),
                actual: a.rows(),
            });
        }
    }
    Ok(())
}

fn check_plan(plan: &DensifyPlan) -> Result<(), DensifyError> {
    let n_new = plan.rows.parent_from_new.len();
    let v = &plan.new_values;
    for (field, len) in [
        ("plan.new_values.means", v.means.len()),
        ("plan.new_values.log_scales", v.log_scales.len()),
        ("plan.new_values.rotations", v.rotations.len()),
        ("plan.new_values.opacity_logits", v.opacity_logits.len()),
        ("plan.new_values.sh_dc", v.sh_dc.len()),
    ] {
        if len != n_new {
            return Err(DensifyError::Length {
                field,
                expected: n_new,
                actual: len,
            });
        }
    }
    let new_len = plan.new_len();
    if let Some(w) = plan.reset_rows.windows(2).find(|w| w[1] <= w[0]) {
        return Err(DensifyError::Input {
            field: "plan.reset_rows",
            problem: format!("row {} does not increase after {}", w[1], w[0]),
        });
    }
    if let Some(&r) = plan.reset_rows.last()
        && r as usize >= new_len
    {
        return Err(DensifyError::Input {
            field: "plan.reset_rows",
            problem: format!("row {r} is out of range for {new_len} rows"),
        });
    }
    Ok(())
}

fn rows_err(array: &str) -> impl FnOnce(RowPlanError) -> DensifyError + '_ {
    move |source| DensifyError::RowPlan {
        array: array.to_string(),
        source,
    }
}

fn apply_rows<T: Copy + Send + Sync>(
    plan: &RowPlan,
    data: &mut Vec<T>,
    stride: usize,
    fill: NewRows<T>,
    label: &str,
) -> Result<(), DensifyError> {
    plan.apply(data, stride, fill).map_err(rows_err(label))
}

fn copy_rows<T: Copy + Send + Sync>(
    plan: &RowPlan,
    data: &mut Vec<T>,
    stride: usize,
    label: &str,
) -> Result<(), DensifyError> {
    apply_rows(plan, data, stride, NewRows::CopyParent, label)
}

impl PerGaussian for Gaussians {
    fn label(&self) -> String {
        "gaussians".into()
    }

    fn rows(&self) -> usize {
        self.len()
    }

    fn apply(&mut self, plan: &DensifyPlan) -> Result<(), DensifyError> {
        let r = &plan.rows;
        let stride = self.sh_stride();
        copy_rows(r, &mut self.means, 1, "gaussians.means")?;
        copy_rows(r, &mut self.log_scales, 1, "gaussians.log_scales")?;
        copy_rows(r, &mut self.rotations, 1, "gaussians.rotations")?;
        copy_rows(r, &mut self.opacity_logits, 1, "gaussians.opacity_logits")?;
        copy_rows(r, &mut self.sh, stride, "gaussians.sh")?;
        let start = plan.kept_len();
        let v = &plan.new_values;
        self.means[start..].copy_from_slice(&v.means);
        self.log_scales[start..].copy_from_slice(&v.log_scales);
        self.rotations[start..].copy_from_slice(&v.rotations);
        self.opacity_logits[start..].copy_from_slice(&v.opacity_logits);
        for (j, dc) in v.sh_dc.iter().enumerate() {
            let row = (start + j) * stride;
            self.sh[row..row + 3].copy_from_slice(dc);
        }
        let reset = plan.reset_logit();
        for &row in &plan.reset_rows {
            let o = &mut self.opacity_logits[row as usize];
            *o = o.min(reset);
        }
        Ok(())
    }
}

/// The Adam moments of one parameter group whose rows are Gaussians.
#[derive(Debug)]
pub struct Moments<'a> {
    /// The group; its first and second moments get the plan's rows (new rows start at zero).
    pub group: &'a mut AdamGroup,
    /// The column of a row that holds the opacity (zeroed at reset rows): `Some(0)` for a group
    /// holding only opacities, `Some(10)` for one interleaved 59-wide parameter row, `None` for
    /// a group without opacity.
    pub opacity_column: Option<usize>,
}

impl PerGaussian for Moments<'_> {
    fn label(&self) -> String {
        format!("Adam moments `{}`", self.group.name)
    }

    fn rows(&self) -> usize {
        self.group.m.len() / self.group.row_width.max(1)
    }

    fn apply(&mut self, plan: &DensifyPlan) -> Result<(), DensifyError> {
        let w = self.group.row_width;
        let label = self.label();
        if self.group.v.len() != self.group.m.len() {
            return Err(DensifyError::Rows {
                array: format!("{label} (second moment)"),
                expected: self.rows(),
                actual: self.group.v.len() / w.max(1),
            });
        }
        if let Some(c) = self.opacity_column
            && c >= w
        {
            return Err(DensifyError::Input {
                field: "opacity_column",
                problem: format!("column {c} is outside rows of {w} in {label}"),
            });
        }
        let zero = NewRows::Fill(0.0);
        let group = &mut *self.group;
        let (m, v) = rayon::join(
            || apply_rows(&plan.rows, &mut group.m, w, zero, &label),
            || apply_rows(&plan.rows, &mut group.v, w, zero, &label),
        );
        m?;
        v?;
        if let Some(c) = self.opacity_column {
            for &row in &plan.reset_rows {
                let e = row as usize * w + c;
                self.group.m[e] = 0.0;
                self.group.v[e] = 0.0;
            }
        }
        Ok(())
    }
}

/// The per-Gaussian groups of an optimiser (e.g. means, scales, rotations, opacity, SH DC, SH
/// rest), each with the column holding the opacity if any; treated as one container.
#[derive(Debug)]
pub struct OptimiserMoments<'a> {
    /// The optimiser whose groups are listed in `groups`; its other groups are left alone.
    pub adam: &'a mut Adam,
    /// (group, opacity column) of every group whose rows are Gaussians.
    pub groups: &'a [(GroupId, Option<usize>)],
}

impl OptimiserMoments<'_> {
    fn group_rows(&self, id: GroupId) -> Option<usize> {
        let g = self.adam.groups().get(id.0)?;
        Some(g.m.len() / g.row_width.max(1))
    }
}

impl PerGaussian for OptimiserMoments<'_> {
    fn label(&self) -> String {
        "optimiser moments".into()
    }

    /// The common row count of the groups; `usize::MAX` when a group is missing or the groups
    /// disagree (so [`apply_plan`] reports a mismatch before touching anything).
    fn rows(&self) -> usize {
        let mut rows = self.groups.iter().map(|&(id, _)| self.group_rows(id));
        match rows.next() {
            None => 0,
            Some(first) => {
                if first.is_some() && rows.all(|r| r == first) {
                    first.unwrap_or(usize::MAX)
                } else {
                    usize::MAX
                }
            }
        }
    }

    fn apply(&mut self, plan: &DensifyPlan) -> Result<(), DensifyError> {
        for (k, &(id, _)) in self.groups.iter().enumerate() {
            if self.groups[..k].iter().any(|&(other, _)| other == id) {
                return Err(DensifyError::Input {
                    field: "optimiser moments groups",
                    problem: format!("group {} is listed twice", id.0),
                });
            }
        }
        for &(id, opacity_column) in self.groups {
            let mut one = Moments {
                group: self.adam.group_mut(id),
                opacity_column,
            };
            one.apply(plan)?;
        }
        Ok(())
    }
}

impl PerGaussian for DensifyStats {
    fn label(&self) -> String {
        "densify statistics".into()
    }

    fn rows(&self) -> usize {
        self.len()
    }

    fn apply(&mut self, plan: &DensifyPlan) -> Result<(), DensifyError> {
        self.check()?;
        if plan.clears_stats {
            self.reset(plan.new_len());
            return Ok(());
        }
        let r = &plan.rows;
        copy_rows(r, &mut self.grad_sum, 1, "stats.grad_sum")?;
        copy_rows(r, &mut self.visible, 1, "stats.visible")?;
        copy_rows(r, &mut self.max_radius, 1, "stats.max_radius")?;
        copy_rows(r, &mut self.residual_sum, 1, "stats.residual_sum")?;
        copy_rows(r, &mut self.residual_count, 1, "stats.residual_count")?;
        copy_rows(r, &mut self.theta_sum, 1, "stats.theta_sum")?;
        copy_rows(r, &mut self.theta_count, 1, "stats.theta_count")
    }
}

/// A container that keeps its own rows through a row plan ([`FollowsRowPlan`]: EvoGS's
/// evolution state) as one of the arrays a plan is applied to: it follows the plan's
/// [`DensifyPlan::rows`], its errors become [`DensifyError::Container`]. It dereferences to the
/// container (`Planned(&mut state)` lends one; a backbone may keep its state in one).
#[derive(Clone, Debug, PartialEq)]
pub struct Planned<T>(pub T);

impl<T> std::ops::Deref for Planned<T> {
    type Target = T;

    fn deref(&self) -> &T {
        &self.0
    }
}

impl<T> std::ops::DerefMut for Planned<T> {
    fn deref_mut(&mut self) -> &mut T {
        &mut self.0
    }
}

impl<T: FollowsRowPlan + Send> PerGaussian for Planned<T> {
    fn label(&self) -> String {
        self.0.label()
    }

    fn rows(&self) -> usize {
        self.0.row_count()
    }

    fn apply(&mut self, plan: &DensifyPlan) -> Result<(), DensifyError> {
        self.0
            .follow(&plan.rows)
            .map_err(|source| DensifyError::Container {
                array: self.0.label(),
                source,
            })
    }
}

/// Any other per-Gaussian array: rows of `stride` elements, new rows filled by `fill`.
#[derive(Debug)]
pub struct Rows<'a, T> {
    /// The array's name in error messages.
    pub label: &'a str,
    /// The rows, row-major: `stride` elements per Gaussian.
    pub data: &'a mut Vec<T>,
    /// Elements per row.
    pub stride: usize,
    /// How the appended rows are filled (copied from the parent or set to a value).
    pub fill: NewRows<T>,
}

impl<T: Copy + Send + Sync> PerGaussian for Rows<'_, T> {
    fn label(&self) -> String {
        self.label.to_string()
    }

    fn rows(&self) -> usize {
        self.data.len() / self.stride.max(1)
    }

    fn apply(&mut self, plan: &DensifyPlan) -> Result<(), DensifyError> {
        apply_rows(&plan.rows, self.data, self.stride, self.fill, self.label)
    }
}
