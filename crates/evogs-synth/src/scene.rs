//! Scene generation: canonical Gaussians, ground-truth trajectories and rendered frames.

use evogs_io::Split;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use splat_raster::{Camera, CpuRasterizer, Gaussians, Rasterizer, RenderOptions};

use super::cameras::sample_camera;
use super::motion::{MotionModel, Part};
use super::object;
use super::{SceneSpec, SynthError};

/// One rendered frame.
#[derive(Clone, Debug, PartialEq)]
pub struct SynthFrame {
    /// Time in [0, 1].
    pub time: f32,
    /// The camera (OpenCV axes).
    pub camera: Camera,
    /// Colour rendered over black, i.e. premultiplied by `alpha`; row-major.
    pub color: Vec<[f32; 3]>,
    /// Accumulated opacity.
    pub alpha: Vec<f32>,
}

impl SynthFrame {
    /// The image composited over a background: `color + background · (1 − alpha)`, which is
    /// exactly the render with that background.
    pub fn image_over(&self, background: [f32; 3]) -> Vec<[f32; 3]> {
        self.color
            .iter()
            .zip(&self.alpha)
            .map(|(c, &a)| std::array::from_fn(|k| c[k] + background[k] * (1.0 - a)))
            .collect()
    }
}

/// Ground-truth state of every Gaussian at every distinct frame time (all splits, sorted).
/// Only what changes is stored: rotations only when the scene turns Gaussians, SH DC only when
/// it changes appearance.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectories {
    /// Sorted distinct times.
    pub times: Vec<f32>,
    /// `means[k][i]`: Gaussian `i`'s mean at `times[k]`.
    pub means: Vec<Vec<[f32; 3]>>,
    /// `rotations[k][i]`, raw quaternion `w, x, y, z`, when the scene rotates Gaussians.
    pub rotations: Option<Vec<Vec<[f32; 4]>>>,
    /// `sh_dc[k][i]`, the degree-0 SH coefficients, when the scene changes appearance.
    pub sh_dc: Option<Vec<Vec<[f32; 3]>>>,
}

/// A generated scene.
#[derive(Clone, Debug, PartialEq)]
pub struct SyntheticScene {
    /// What it was generated from.
    pub spec: SceneSpec,
    /// The seed.
    pub seed: u64,
    /// Canonical Gaussians (time-independent raw parameters, SH degree 0).
    pub canonical: Gaussians,
    /// Part of each Gaussian.
    pub parts: Vec<Part>,
    /// Training frames, times `k / (F − 1)`.
    pub train: Vec<SynthFrame>,
    /// Test frames (held-out times and cameras).
    pub test: Vec<SynthFrame>,
    /// Validation frames (held-out times and cameras).
    pub val: Vec<SynthFrame>,
    /// Ground truth at every distinct frame time.
    pub trajectories: Trajectories,
}

impl SyntheticScene {
    /// The motion model of the scene.
    pub fn motion(&self) -> MotionModel {
        MotionModel::of(&self.spec)
    }

    /// The ground-truth Gaussians at any time.
    pub fn gaussians_at(&self, t: f32) -> Gaussians {
        self.motion().deform(&self.canonical, &self.parts, t)
    }

    /// The frames of a split.
    pub fn split(&self, split: Split) -> &[SynthFrame] {
        match split {
            Split::Train => &self.train,
            Split::Test => &self.test,
            Split::Val => &self.val,
        }
    }
}

/// Generates the scene of `spec` for `seed`: deterministic (same spec and seed, same scene).
pub fn generate(spec: &SceneSpec, seed: u64) -> Result<SyntheticScene, SynthError> {
    spec.validate()?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let palette = (seed % 4) as usize;
    let occluder = spec
        .occlusion
        .as_ref()
        .map(|o| (spec.occluder_gaussians, o));
    let (canonical, parts) = object::build(
        spec.body_gaussians,
        spec.satellite_gaussians,
        occluder,
        palette,
    );
    let motion = MotionModel::of(spec);

    let train_times = spec.train_times();
    let test_times = spec.held_out_times(spec.test_frames, 0.5);
    let val_times = spec.held_out_times(spec.val_frames, 0.0);
    let mut times: Vec<f32> = [&train_times, &test_times, &val_times]
        .into_iter()
        .flatten()
        .copied()
        .collect();
    times.sort_by(f32::total_cmp);
    times.dedup();

    let states: Vec<Gaussians> = times
        .iter()
        .map(|&t| motion.deform(&canonical, &parts, t))
        .collect();
    // Camera distance: the whole motion fits the field of view (bounding sphere of all means
    // plus three standard deviations, 10% margin).
    let max_sigma = canonical
        .log_scales
        .iter()
        .flatten()
        .fold(0f32, |m, &s| m.max(s.exp()));
    let bound = states
        .iter()
        .flat_map(|g| g.means.iter())
        .fold(0f32, |m, p| {
            m.max((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt())
        })
        + 3.0 * max_sigma;
    let distance = 1.1 * bound / (0.5 * spec.camera_angle_x).sin();

    let state_at = |t: f32| {
        let k = times.partition_point(|&x| x < t);
        &states[k]
    };
    let raster = CpuRasterizer::new();
    let options = RenderOptions::default();
    let mut render = |split: Split, split_times: &[f32]| -> Result<Vec<SynthFrame>, SynthError> {
        split_times
            .iter()
            .enumerate()
            .map(|(index, &time)| {
                let camera =
                    sample_camera(&mut rng, spec.image_size, spec.camera_angle_x, distance);
                let out = raster
                    .forward(state_at(time).view(), &camera, &options)
                    .map_err(|source| SynthError::Render {
                        split: split.name(),
                        index,
                        source,
                    })?;
                Ok(SynthFrame {
                    time,
                    camera,
                    color: out.color,
                    alpha: out.alpha,
                })
            })
            .collect()
    };
    let train = render(Split::Train, &train_times)?;
    let test = render(Split::Test, &test_times)?;
    let val = render(Split::Val, &val_times)?;

    let trajectories = Trajectories {
        means: states.iter().map(|g| g.means.clone()).collect(),
        rotations: motion
            .rotates()
            .then(|| states.iter().map(|g| g.rotations.clone()).collect()),
        sh_dc: motion.recolours().then(|| {
            states
                .iter()
                .map(|g| g.sh.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
                .collect()
        }),
        times,
    };
    Ok(SyntheticScene {
        spec: spec.clone(),
        seed,
        canonical,
        parts,
        train,
        test,
        val,
        trajectories,
    })
}
