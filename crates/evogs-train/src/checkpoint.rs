//! Checkpoints: one safetensors file holding everything a run needs to continue exactly — the
//! Gaussians, the Adam moments and step counts of every group, the densification statistics,
//! the backbone's parameters — with the iteration, the active SH degree and the seed (the RNG
//! state, see [`crate::trainer`]) in its metadata. Written to a temporary file and renamed.

use std::collections::HashMap;
use std::path::Path;

use half::f16;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};
use serde::{Deserialize, Serialize};
use splat_raster::{Gaussians, sh_coeff_count};
use tiny_nn::{StoreMut, StoreRef};

use evogs_backbones::Backbone;

use crate::budget::BudgetProgress;
use crate::error::TrainError;
use crate::state::SceneState;
use crate::train_log::LogInterval;

/// Metadata key of the JSON header.
const META_KEY: &str = "evogs.checkpoint";

/// The scalar part of a checkpoint.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CheckpointMeta {
    /// Iterations completed.
    pub iteration: u64,
    /// Active SH degree.
    pub active_sh: u32,
    /// Maximum SH degree of the Gaussians.
    pub sh_degree: u32,
    /// Number of Gaussians.
    pub gaussians: usize,
    /// Seed of the run (with `iteration`, the whole RNG state).
    pub seed: u64,
    /// Adam step count of every group, by group name.
    pub adam_steps: Vec<(String, u64)>,
    /// Where a budget run stands ([`crate::budget`]); absent in runs without a budget.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub budget: Option<BudgetProgress>,
    /// The training log's interval at the checkpoint ([`crate::train_log`]); absent in
    /// checkpoints written before it was kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub log: Option<LogInterval>,
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn u32_bytes(v: &[u32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Writes a checkpoint of `state` and `backbone` after `iteration` iterations (with the
/// progress of a budget run where there is one, and the training log's interval).
pub fn save_checkpoint(
    path: &Path,
    state: &SceneState,
    backbone: &dyn Backbone,
    iteration: u64,
    seed: u64,
    budget: Option<BudgetProgress>,
    log: Option<LogInterval>,
) -> Result<(), TrainError> {
    let g = state.gaussians();
    let mut tensors: Vec<(String, Dtype, Vec<u8>)> = vec![
        (
            "gaussians.means".into(),
            Dtype::F32,
            f32_bytes(g.means.as_flattened()),
        ),
        (
            "gaussians.log_scales".into(),
            Dtype::F32,
            f32_bytes(g.log_scales.as_flattened()),
        ),
        (
            "gaussians.rotations".into(),
            Dtype::F32,
            f32_bytes(g.rotations.as_flattened()),
        ),
        (
            "gaussians.opacity_logits".into(),
            Dtype::F32,
            f32_bytes(&g.opacity_logits),
        ),
        ("gaussians.sh".into(), Dtype::F32, f32_bytes(&g.sh)),
    ];
    let s = state.stats();
    tensors.extend([
        ("stats.grad_sum".into(), Dtype::F32, f32_bytes(&s.grad_sum)),
        ("stats.visible".into(), Dtype::U32, u32_bytes(&s.visible)),
        (
            "stats.max_radius".into(),
            Dtype::F32,
            f32_bytes(&s.max_radius),
        ),
        (
            "stats.residual_sum".into(),
            Dtype::F32,
            f32_bytes(&s.residual_sum),
        ),
        (
            "stats.residual_count".into(),
            Dtype::U32,
            u32_bytes(&s.residual_count),
        ),
        (
            "stats.theta_sum".into(),
            Dtype::F32,
            f32_bytes(&s.theta_sum),
        ),
        (
            "stats.theta_count".into(),
            Dtype::U32,
            u32_bytes(&s.theta_count),
        ),
    ]);
    for group in state.adam().groups() {
        tensors.push((
            format!("adam.{}.m", group.name),
            Dtype::F32,
            f32_bytes(&group.m),
        ));
        tensors.push((
            format!("adam.{}.v", group.name),
            Dtype::F32,
            f32_bytes(&group.v),
        ));
    }
    for (name, buf) in backbone.params() {
        let (dt, bytes) = match buf {
            StoreRef::F32(v) => (Dtype::F32, f32_bytes(v)),
            StoreRef::F16(v) => (Dtype::F16, v.iter().flat_map(|x| x.to_le_bytes()).collect()),
        };
        tensors.push((format!("backbone.{name}"), dt, bytes));
    }
    let meta = CheckpointMeta {
        iteration,
        active_sh: state.active_sh(),
        sh_degree: g.sh_degree,
        gaussians: g.len(),
        seed,
        adam_steps: state
            .adam()
            .groups()
            .iter()
            .map(|gr| (gr.name.clone(), gr.step))
            .collect(),
        budget,
        log,
    };
    let meta_json = serde_json::to_string(&meta)
        .map_err(|e| TrainError::file(path, format!("cannot encode metadata: {e}")))?;
    let mut views = Vec::with_capacity(tensors.len());
    for (name, dt, bytes) in &tensors {
        let elems = bytes.len() * 8 / dt.bitsize();
        let view = TensorView::new(*dt, vec![elems], bytes)
            .map_err(|e| TrainError::field(path, name, format!("cannot describe tensor: {e}")))?;
        views.push((name.clone(), view));
    }
    let data = safetensors::serialize(
        views,
        Some(HashMap::from([(META_KEY.to_string(), meta_json)])),
    )
    .map_err(|e| TrainError::file(path, format!("cannot serialise: {e}")))?;
    evogs_io::atomic::write_atomically(path, |w| {
        use std::io::Write;
        w.write_all(&data).map_err(|e| evogs_io::IoError::Io {
            path: path.to_path_buf(),
            cause: e,
        })
    })?;
    Ok(())
}

struct Reader<'a> {
    path: &'a Path,
    st: SafeTensors<'a>,
}

impl Reader<'_> {
    fn raw(&self, name: &str, dtype: Dtype, len: usize) -> Result<&[u8], TrainError> {
        let t = self
            .st
            .tensor(name)
            .map_err(|e| TrainError::field(self.path, name, format!("missing tensor ({e})")))?;
        if t.dtype() != dtype {
            return Err(TrainError::field(
                self.path,
                name,
                format!("dtype {:?}, expected {dtype:?}", t.dtype()),
            ));
        }
        if t.shape() != [len] {
            return Err(TrainError::field(
                self.path,
                name,
                format!("shape {:?}, expected [{len}]", t.shape()),
            ));
        }
        Ok(t.data())
    }

    fn f32s(&self, name: &str, len: usize) -> Result<Vec<f32>, TrainError> {
        let data = self.raw(name, Dtype::F32, len)?;
        Ok(data
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect())
    }

    fn u32s(&self, name: &str, len: usize) -> Result<Vec<u32>, TrainError> {
        let data = self.raw(name, Dtype::U32, len)?;
        Ok(data
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect())
    }
}

fn rows<const W: usize>(v: Vec<f32>) -> Vec<[f32; W]> {
    v.chunks_exact(W)
        .map(|c| std::array::from_fn(|k| c[k]))
        .collect()
}

/// Reads a checkpoint into `state` (whose groups and backbone must have been built from the same
/// config) and `backbone`; returns its metadata. Every problem names the file and the tensor.
pub fn load_checkpoint(
    path: &Path,
    state: &mut SceneState,
    backbone: &mut dyn Backbone,
) -> Result<CheckpointMeta, TrainError> {
    let bytes = std::fs::read(path).map_err(|e| TrainError::io(path, e))?;
    let (_, header) = SafeTensors::read_metadata(&bytes)
        .map_err(|e| TrainError::file(path, format!("not a safetensors checkpoint: {e}")))?;
    let meta_json = header
        .metadata()
        .as_ref()
        .and_then(|m| m.get(META_KEY))
        .ok_or_else(|| TrainError::field(path, META_KEY, "missing checkpoint metadata"))?;
    let meta: CheckpointMeta = serde_json::from_str(meta_json)
        .map_err(|e| TrainError::field(path, META_KEY, format!("invalid JSON: {e}")))?;
    // Every Gaussian stores at least one f32 of its own: a count beyond that is a damaged
    // header, refused before anything of that size is allocated.
    if meta.gaussians > bytes.len() / 4 {
        return Err(TrainError::field(
            path,
            "gaussians",
            format!(
                "{} Gaussians cannot fit in a file of {} bytes",
                meta.gaussians,
                bytes.len()
            ),
        ));
    }
    if meta.sh_degree != state.gaussians().sh_degree {
        return Err(TrainError::field(
            path,
            "sh_degree",
            format!(
                "{}, but the run's config says {}",
                meta.sh_degree,
                state.gaussians().sh_degree
            ),
        ));
    }
    let st = SafeTensors::deserialize(&bytes)
        .map_err(|e| TrainError::file(path, format!("not a safetensors checkpoint: {e}")))?;
    let r = Reader { path, st };
    let n = meta.gaussians;
    let stride = sh_coeff_count(meta.sh_degree) * 3;
    let gaussians = Gaussians {
        sh_degree: meta.sh_degree,
        means: rows::<3>(r.f32s("gaussians.means", n * 3)?),
        log_scales: rows::<3>(r.f32s("gaussians.log_scales", n * 3)?),
        rotations: rows::<4>(r.f32s("gaussians.rotations", n * 4)?),
        opacity_logits: r.f32s("gaussians.opacity_logits", n)?,
        sh: r.f32s("gaussians.sh", n * stride)?,
    };
    let mut stats = densify::DensifyStats::new(n);
    stats.grad_sum = r.f32s("stats.grad_sum", n)?;
    stats.visible = r.u32s("stats.visible", n)?;
    stats.max_radius = r.f32s("stats.max_radius", n)?;
    stats.residual_sum = r.f32s("stats.residual_sum", n)?;
    stats.residual_count = r.u32s("stats.residual_count", n)?;
    stats.theta_sum = r.f32s("stats.theta_sum", n)?;
    stats.theta_count = r.u32s("stats.theta_count", n)?;
    let steps: HashMap<&str, u64> = meta
        .adam_steps
        .iter()
        .map(|(k, v)| (k.as_str(), *v))
        .collect();
    for (name, dst) in backbone.params_mut() {
        let key = format!("backbone.{name}");
        match dst {
            StoreMut::F32(v) => {
                let src = r.f32s(&key, v.len())?;
                v.copy_from_slice(&src);
            }
            StoreMut::F16(v) => {
                let data = r.raw(&key, Dtype::F16, v.len())?;
                for (x, b) in v.iter_mut().zip(data.chunks_exact(2)) {
                    *x = f16::from_le_bytes([b[0], b[1]]);
                }
            }
        }
    }
    state.restore(gaussians, stats, meta.active_sh, |group| {
        let per_gaussian = !group.name.starts_with("net.");
        let len = if per_gaussian {
            n * group.row_width
        } else {
            group.m.len()
        };
        group.m = r.f32s(&format!("adam.{}.m", group.name), len)?;
        group.v = r.f32s(&format!("adam.{}.v", group.name), len)?;
        group.step = *steps.get(group.name.as_str()).ok_or_else(|| {
            TrainError::field(path, format!("adam_steps.{}", group.name), "missing")
        })?;
        Ok(())
    })?;
    Ok(meta)
}
