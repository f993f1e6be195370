//! Scene generation: canonical Gaussians, ground-truth trajectories and rendered frames.

use evogs_io::Split;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use splat_raster::{Camera, CpuRasterizer, Gaussians, Rasterizer, RenderOptions};

use super::cameras::sample_camera;
use super::motion::{MotionModel, Part};
use super::object;
use super::protocol::{
    Protocol, RIG_OFFSET, add_image_noise, jitter_pose, monocular_camera, monocular_start,
};
use super::{SceneSpec, SynthError};

/// Name of the fixed-camera sequence in errors and on disk (the D-NeRF dataset `DIR/fixed/`).
pub const FIXED_SPLIT: &str = "fixed";

/// ChaCha stream of the capture noise (stream 0 draws the cameras).
const NOISE_STREAM: u64 = 1;

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
    /// Training frames, times `k / (F − 1)`. With pose noise their cameras are the recorded
    /// (jittered) ones; the images were rendered from the true cameras.
    pub train: Vec<SynthFrame>,
    /// Test frames (held-out times and cameras under `dnerf`; training times and the `+` rig
    /// camera under `monocular`).
    pub test: Vec<SynthFrame>,
    /// Validation frames (held-out times and cameras).
    pub val: Vec<SynthFrame>,
    /// The fixed-camera sequence (`monocular` only, empty otherwise): every training time seen
    /// from the middle of the arc, never noisy; the ground truth of fixed-camera flicker.
    pub fixed: Vec<SynthFrame>,
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
    let (test_times, val_times) = match spec.protocol {
        Protocol::Dnerf => (
            spec.held_out_times(spec.test_frames, 0.5),
            spec.held_out_times(spec.val_frames, 0.0),
        ),
        Protocol::Monocular => (
            spec.rig_times(spec.test_frames, 0.5),
            spec.rig_times(spec.val_frames, 0.0),
        ),
    };
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

    // The cameras of each split (the fixed-camera sequence only under `monocular`).
    let (size, fov) = (spec.image_size, spec.camera_angle_x);
    let (train_cameras, test_cameras, val_cameras, fixed) = match spec.protocol {
        Protocol::Dnerf => {
            let mut draw = |n: usize| -> Vec<Camera> {
                (0..n)
                    .map(|_| sample_camera(&mut rng, size, fov, distance))
                    .collect()
            };
            let train = draw(train_times.len());
            let test = draw(test_times.len());
            let val = draw(val_times.len());
            (train, test, val, Vec::new())
        }
        Protocol::Monocular => {
            let start = monocular_start(&mut rng);
            let arc = |times: &[f32], offset: f32| -> Vec<Camera> {
                times
                    .iter()
                    .map(|&t| monocular_camera(start, t, offset, size, fov, distance))
                    .collect()
            };
            let middle = monocular_camera(start, 0.5, 0.0, size, fov, distance);
            let fixed = train_times.iter().map(|&t| (t, middle)).collect();
            (
                arc(&train_times, 0.0),
                arc(&test_times, RIG_OFFSET),
                arc(&val_times, -RIG_OFFSET),
                fixed,
            )
        }
    };

    let state_at = |t: f32| {
        let k = times.partition_point(|&x| x < t);
        &states[k]
    };
    let raster = CpuRasterizer::new();
    let options = RenderOptions::default();
    let render = |split: &'static str,
                  split_times: &[f32],
                  cameras: Vec<Camera>|
     -> Result<Vec<SynthFrame>, SynthError> {
        split_times
            .iter()
            .zip(cameras)
            .enumerate()
            .map(|(index, (&time, camera))| {
                let out = raster
                    .forward(state_at(time).view(), &camera, &options)
                    .map_err(|source| SynthError::Render {
                        split,
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
    let mut train = render(Split::Train.name(), &train_times, train_cameras)?;
    let test = render(Split::Test.name(), &test_times, test_cameras)?;
    let val = render(Split::Val.name(), &val_times, val_cameras)?;
    let (fixed_times, fixed_cameras): (Vec<f32>, Vec<Camera>) = fixed.into_iter().unzip();
    let fixed = render(FIXED_SPLIT, &fixed_times, fixed_cameras)?;

    // Capture noise on the training frames, from its own random stream so that the cameras
    // and colours of a noise-free scene do not depend on it.
    if !spec.noise.is_off() {
        let mut noise_rng = ChaCha8Rng::seed_from_u64(seed);
        noise_rng.set_stream(NOISE_STREAM);
        for frame in &mut train {
            if spec.noise.pose > 0.0 {
                frame.camera =
                    jitter_pose(&mut noise_rng, &frame.camera, spec.noise.pose, distance);
            }
            if spec.noise.image > 0.0 {
                add_image_noise(&mut noise_rng, frame, spec.noise.image);
            }
        }
    }

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
        fixed,
        trajectories,
    })
}
