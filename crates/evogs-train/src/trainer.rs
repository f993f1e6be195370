//! The training loop (D-3DGS `train.py`), one iteration per [`Trainer::step`].
//!
//! Iteration `i` (from 1), in D-3DGS's order:
//! 1. every `sh_interval` iterations the active SH degree goes up by one;
//! 2. the view is the next of a seeded random permutation of the training views (a new
//!    permutation per epoch: D-3DGS pops random views from a refilled stack);
//! 3. before `warm_up` the deformation is zero, afterwards the backbone's output at the view's
//!    time with the canonical means detached;
//! 4. render, loss `0.8·L1 + 0.2·(1 − SSIM)`, backward through the rasterizer and the backbone;
//! 5. while `i < densify.until` the projected-mean gradients and radii are accumulated, and on
//!    densify's schedule a plan is made (clone/split/prune, opacity reset) and applied to every
//!    per-Gaussian array;
//! 6. while `i < iterations`, Adam steps with the lr of step `i − 1` (3DGS updates the lr after
//!    each step). As in 3DGS, the Gaussians are not stepped on an iteration that densified (the
//!    replaced tensors carry no gradient), and the opacities not on one that reset them.
//!
//! A run with a time budget ([`crate::budget`]) places each step at a **schedule iteration**
//! instead ([`Trainer::step_to`]): the SH steps, warm-up, densification and opacity resets, the
//! lr and the end of the optimiser's steps follow it, every event between the previous step's
//! schedule iteration and this one happening once; the views and everything seeded follow the
//! steps themselves. Without a budget the two counts are one ([`Trainer::step`]).
//!
//! The rasterizer is the backend `config.backend` names (`cpu`, `wgpu`, `auto`; see
//! [`splat_raster::select_rasterizer`] and [`Trainer::backend`]); the CPU one is the default.
//! The backbone's network runs where `config.net_backend` says ([`place_network`],
//! [`Trainer::network`]): on the rasterizer's device when asked and the backbone has a device
//! form (cargo feature `wgpu`; D-3DGS's network today), on the CPU otherwise. On the device its
//! gradient, Adam step and moments stay there too; [`Trainer::sync_host`] reads the parameters
//! and moments back before a checkpoint, a weight file or a check of the values, so checkpoints
//! and resume are the same on both. The loss runs where the rendered image is
//! ([`Trainer::loss_place`]): with the rasterizer on a device and a fixed background, on the
//! device (`crate::device_loss`: the training images uploaded once, the image and the loss's
//! gradient never read back or uploaded); on the CPU otherwise.
//!
//! Everything random is a pure function of (seed, iteration): the epoch's permutation is drawn
//! from a generator seeded by (seed, epoch), densify's split sampling from (seed, iteration),
//! so the checkpoint's RNG state is the seed and the iteration count.

use std::time::Instant;

use densify::{DensifyConfig, Schedule, make_plan};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use splat_core::{DeformedGeometry, deformation_gradient_into};
use splat_raster::{
    BackendInfo, BackwardOutput, DynRasterizer, ForwardOutput, Gaussians, PixelGrads,
    RenderOptions, select_rasterizer,
};

use crate::config::{Background, Method, TrainConfig};
use crate::data::SplitViews;
use crate::error::TrainError;
use crate::gain_report::GainReport;
use crate::init::random_gaussians;
use crate::memory::{DataSizes, MemoryEstimate};
use crate::state::SceneState;
use crate::timers::{Phase, PhaseTimes};
use evogs_backbones::{Backbone, DensifyPolicy};
use evogs_metrics::{ImageSize, LossWorkspace, psnr_from_mse};

/// What one iteration did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepReport {
    /// The iteration (from 1): steps taken.
    pub iteration: u64,
    /// Where in the schedule the step was ([`Trainer::step_to`]); `iteration` without a budget.
    pub schedule_iteration: u64,
    /// Whether it is the run's last step (set by [`crate::train`]; false from the trainer).
    pub last: bool,
    /// Photometric loss plus the backbone's own terms (EvoGS: λ1 L_sup + λ2 L_prior).
    pub loss: f64,
    /// PSNR of the training view.
    pub psnr: f64,
    /// Gaussians after the iteration.
    pub gaussians: usize,
    /// Whether densification changed the Gaussian set.
    pub densified: bool,
    /// L2 norm of the backbone's parameter gradients this iteration (`None` before the
    /// warm-up ends: the network is not used then; `None` with the network on a device, where
    /// its gradient stays). A diagnostic of the deformation's training.
    pub net_grad_norm: Option<f64>,
}

/// The backbone a config asks for ([`evogs_backbones::make_backbone`] of
/// [`TrainConfig::backbone_run`]), once its parameters are known to fit: the count is taken
/// from the settings before anything is allocated ([`evogs_backbones::parameter_count`]), and
/// a network whose parameters alone exceed `--memory-limit` or the memory this machine has
/// available is refused with the count, not attempted. Training, resuming, evaluating,
/// rendering and viewing a run all build their backbone here.
pub fn make_backbone(config: &TrainConfig) -> Result<Box<dyn Backbone>, TrainError> {
    let bytes = crate::memory::network_bytes(parameter_count(config)?, 1);
    let (limit, whose) = match config.memory_limit {
        Some(limit) => (Some(limit), "the memory limit (`--memory-limit`)"),
        None => (
            crate::memory::available_memory(),
            "the memory this machine has available",
        ),
    };
    if let Some(limit) = limit
        && bytes > limit
    {
        return Err(TrainError::config(
            "net",
            format!(
                "the {} {} network's parameters alone need {}, more than {whose}, {}",
                config.method,
                config.backbone,
                crate::memory::human_bytes(bytes),
                crate::memory::human_bytes(limit)
            ),
        ));
    }
    Ok(evogs_backbones::make_backbone(&config.backbone_run())?)
}

/// The parameters of the backbone a config asks for, counted from its settings without
/// allocating anything ([`evogs_backbones::parameter_count`]).
pub fn parameter_count(config: &TrainConfig) -> Result<usize, TrainError> {
    Ok(evogs_backbones::parameter_count(&config.backbone_run())?)
}

/// Checks the memory estimate of a run of `config` on training data of `data`'s sizes starting
/// with `gaussians` Gaussians, before anything of the run is allocated (the images too, when the
/// sizes come from the dataset's cameras, [`DataSizes::of_split`]): with `--memory-limit`, the
/// estimate must fit it (and the limit becomes a cap on the Gaussians, returned); without, it
/// must fit the memory this machine has available (where that is known), and the error names
/// the flag that overrides it.
pub fn check_memory(
    config: &TrainConfig,
    data: DataSizes,
    gaussians: usize,
) -> Result<Option<usize>, TrainError> {
    let memory = memory_estimate(config, data)?;
    let need = memory.at(gaussians);
    if let Some(limit) = config.memory_limit {
        return match memory.max_gaussians(limit) {
            Some(cap) if cap >= gaussians => Ok(Some(cap)),
            _ => Err(TrainError::config(
                "memory_limit",
                format!(
                    "{} is below the {} the run needs at the start ({})",
                    crate::memory::human_bytes(limit),
                    crate::memory::human_bytes(need),
                    memory.summary(gaussians)
                ),
            )),
        };
    }
    match crate::memory::available_memory() {
        Some(available) if need > available => Err(TrainError::config(
            "memory_limit",
            format!(
                "the run needs {} at the start, more than the {} this machine has available \
                 ({}); lower the sizes, or pass --memory-limit to set the limit yourself",
                crate::memory::human_bytes(need),
                crate::memory::human_bytes(available),
                memory.summary(gaussians)
            ),
        )),
        _ => Ok(None),
    }
}

/// Densify's configuration from the run's settings: standard 3DGS ADC for the baseline; for
/// EvoGS the policy of `evogs.densify` (trigger with densify's default τ_r, τ_θ; deformation-aware
/// clone/split with α = 0.5, as [`DensifyConfig::evogs`]).
pub fn densify_config(config: &TrainConfig) -> DensifyConfig {
    let evogs = DensifyConfig::evogs();
    let (trigger, deformation_alpha) = match (config.method, config.backbones.evogs.densify) {
        (Method::Baseline, _) | (_, DensifyPolicy::Standard) => (None, None),
        (Method::Evogs, DensifyPolicy::Trigger) => (evogs.trigger, None),
        (Method::Evogs, DensifyPolicy::TriggerDeform) => (evogs.trigger, evogs.deformation_alpha),
    };
    DensifyConfig {
        schedule: Schedule {
            white_background: config.background == Background::White,
            ..config.densify.schedule
        },
        seed: config.seed,
        trigger,
        deformation_alpha,
        ..config.densify
    }
}

/// [`MemoryEstimate`] of `config` on training data of `data`'s sizes, its network counted from
/// the settings ([`parameter_count`]).
fn memory_estimate(config: &TrainConfig, data: DataSizes) -> Result<MemoryEstimate, TrainError> {
    Ok(MemoryEstimate::new(
        config,
        &data.with_network(parameter_count(config)?),
    ))
}

/// Where a part of the iteration runs and why, one line: `network: wgpu (wgpu: on the
/// rasterizer's device)`, `network: cpu (auto: the rasterizer runs on the CPU)`, `loss: wgpu
/// (on the rasterizer's device, …)`. The deformation network's is [`TrainConfig::net_backend`]'s
/// ([`place_network`]); the loss's follows the rendered image ([`Trainer::loss_place`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Placement {
    /// The part: `network` or `loss`.
    pub part: &'static str,
    /// Whether it runs on the rasterizer's device.
    pub on_device: bool,
    /// Why (the setting and what decided it).
    pub reason: String,
}

impl std::fmt::Display for Placement {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let place = if self.on_device { "wgpu" } else { "cpu" };
        write!(f, "{}: {place} ({})", self.part, self.reason)
    }
}

/// Puts `backbone`'s network where `choice` asks ([`TrainConfig::net_backend`]), on the device
/// of `raster` when it has one: `wgpu` without a device or with a backbone that has no device
/// form is an error naming `--net-backend`; `auto` falls back to the CPU and says why.
pub fn place_network(
    choice: splat_raster::BackendChoice,
    raster: &dyn splat_raster::Rasterizer,
    backbone: &mut dyn Backbone,
) -> Result<Placement, TrainError> {
    use splat_raster::BackendChoice;
    let cpu = |reason: String| {
        Ok(Placement {
            part: "network",
            on_device: false,
            reason,
        })
    };
    let refuse = |problem: String| Err(TrainError::config("net_backend", problem));
    if choice == BackendChoice::Cpu {
        return cpu("asked: cpu".to_string());
    }
    #[cfg(feature = "wgpu")]
    {
        let Some(ctx) = raster.device() else {
            return match choice {
                BackendChoice::Wgpu => refuse(
                    "--net-backend wgpu runs the network on the rasterizer's device; the \
                     rasterizer runs on the CPU (--backend wgpu puts it on the GPU)"
                        .to_string(),
                ),
                _ => cpu("auto: the rasterizer runs on the CPU".to_string()),
            };
        };
        if choice == BackendChoice::Auto && !ctx.adapter().hardware {
            return cpu(format!(
                "auto: adapter {} is a software rasterizer, slower than the CPU",
                ctx.adapter().name
            ));
        }
        if backbone.use_device(&ctx)? {
            return Ok(Placement {
                part: "network",
                on_device: true,
                reason: format!("{choice}: on the rasterizer's device"),
            });
        }
        let name = backbone.name();
        match choice {
            BackendChoice::Wgpu => refuse(format!(
                "the {name} backbone's network has no GPU form yet (--net-backend cpu or auto \
                 keeps it on the CPU)"
            )),
            _ => cpu(format!(
                "auto: the {name} backbone's network has no GPU form yet"
            )),
        }
    }
    #[cfg(not(feature = "wgpu"))]
    {
        let _ = (raster, backbone);
        match choice {
            BackendChoice::Wgpu => refuse(
                "--net-backend wgpu: this build of evogs-train has no wgpu support (cargo \
                 feature `wgpu` off)"
                    .to_string(),
            ),
            _ => cpu("auto: built without wgpu".to_string()),
        }
    }
}

/// Puts the loss where the rendered image is: on the rasterizer's device when it has one and
/// the background is fixed (the training images uploaded once, [`crate::device_loss`]), on the
/// CPU otherwise (a random background makes each iteration's target on the host).
#[cfg(feature = "wgpu")]
fn place_loss(
    config: &TrainConfig,
    raster: &dyn splat_raster::Rasterizer,
    train: &SplitViews,
) -> Result<(Placement, Option<crate::device_loss::DeviceLoss>), TrainError> {
    let place = |on_device, reason| Placement {
        part: "loss",
        on_device,
        reason,
    };
    let Some(ctx) = raster.device() else {
        return Ok((place(false, "the rasterizer runs on the CPU".into()), None));
    };
    if config.background == Background::Random {
        let why = "a random background makes each iteration's target on the host";
        return Ok((place(false, why.into()), None));
    }
    if let Some(why) = images_over_budget(train, crate::device_loss::IMAGE_BUDGET) {
        return Ok((place(false, why), None));
    }
    let loss = crate::device_loss::DeviceLoss::new(ctx, train)?;
    let why = format!(
        "on the rasterizer's device, the {} training images there ({:.1} MiB)",
        train.views.len(),
        loss.image_bytes() as f64 / (1 << 20) as f64
    );
    Ok((place(true, why), Some(loss)))
}

/// Why `train`'s images stay off the device when they take more than `budget` bytes there
/// (interleaved RGB f32), `None` when they fit.
#[cfg(any(feature = "wgpu", test))]
fn images_over_budget(train: &SplitViews, budget: u64) -> Option<String> {
    let bytes: u64 = train
        .views
        .iter()
        .map(|v| 12 * v.image.pixels.len() as u64)
        .sum();
    (bytes > budget).then(|| {
        format!(
            "the {} training images take {:.1} MiB, above the {:.1} MiB kept on the device",
            train.views.len(),
            bytes as f64 / (1u64 << 20) as f64,
            budget as f64 / (1u64 << 20) as f64
        )
    })
}

/// A training run in memory.
///
/// Its fields are private: the Gaussians' rows and the backbone's per-Gaussian rows stay aligned
/// (every densification goes through [`SceneState::apply_plan`] with this backbone), and the
/// settings, views and extent the densification, memory limit and backbone were prepared with
/// stay the ones in use. Other crates read them through the accessors below.
pub struct Trainer {
    /// Settings.
    config: TrainConfig,
    /// Training views.
    train: SplitViews,
    /// Scene extent (3DGS: 1.1 × the largest camera distance from the cameras' mean).
    extent: f32,
    /// Gaussians, optimiser, statistics.
    state: SceneState,
    /// The deformation backbone.
    backbone: Box<dyn Backbone>,
    /// Iterations completed.
    iteration: u64,
    /// The schedule iteration of the last step ([`Trainer::step_to`]).
    schedule_iteration: u64,
    /// Time spent per phase (this process only).
    times: PhaseTimes,
    raster: DynRasterizer,
    backend: BackendInfo,
    network: Placement,
    /// Where the loss runs and why.
    loss_place: Placement,
    /// The loss on the rasterizer's device, when it runs there.
    #[cfg(feature = "wgpu")]
    device_loss: Option<crate::device_loss::DeviceLoss>,
    densify: DensifyConfig,
    order: (u64, Vec<usize>),
    /// Buffers of the loss and its gradient, reused every iteration.
    loss: LossWorkspace<f32>,
    /// The deformed Gaussians of the iteration, reused every iteration.
    geometry: DeformedGeometry,
    /// dL/d(deformation) rows of the iteration, reused every iteration.
    deformation_grad: Vec<f32>,
    /// The backbone's deformation rows of the iteration, reused every iteration.
    deformation: Vec<f32>,
    /// The backbone's parameter gradients of the iteration, reused every iteration.
    net_grads: Vec<Vec<f32>>,
    /// The rasterizer's forward output (images and backward state), reused every iteration.
    fwd: ForwardOutput,
    /// The rasterizer's gradients, reused every iteration.
    bwd: BackwardOutput,
    /// Per training view, its transmittance 1 − α per pixel under a random background (empty
    /// otherwise).
    transmittance: Vec<Vec<f32>>,
    /// The iteration's target image under a random background, reused every iteration.
    target: Vec<[f32; 3]>,
}

impl Trainer {
    /// A new run: random initial Gaussians, fresh network and optimiser.
    pub fn new(config: TrainConfig, train: SplitViews) -> Result<Self, TrainError> {
        // Before the initial Gaussians are allocated (up to `MAX_INIT_POINTS`).
        config.validate()?;
        check_memory(&config, DataSizes::of_views(&train), config.init_points)?;
        let gaussians = random_gaussians(
            config.init_points,
            config.init_half_extent,
            config.sh_degree,
            config.seed,
        );
        Self::with_gaussians(config, train, gaussians)
    }

    /// A new run from given initial Gaussians (e.g. a dataset's point cloud, see
    /// [`crate::init::gaussians_from_point_cloud`]) at iteration 0.
    pub fn with_gaussians(
        config: TrainConfig,
        train: SplitViews,
        gaussians: splat_raster::Gaussians,
    ) -> Result<Self, TrainError> {
        config.validate()?;
        // Before the backbone and the state are allocated.
        check_memory(&config, DataSizes::of_views(&train), gaussians.len())?;
        let mut backbone = make_backbone(&config)?;
        backbone.initialise(gaussians.view())?;
        let state = SceneState::new(gaussians, backbone.as_ref(), &config.lr)?;
        Self::from_parts(config, train, state, backbone, 0)
    }

    /// A run from its parts (used when resuming from a checkpoint).
    pub fn from_parts(
        config: TrainConfig,
        train: SplitViews,
        state: SceneState,
        backbone: Box<dyn Backbone>,
        iteration: u64,
    ) -> Result<Self, TrainError> {
        if train.views.is_empty() {
            return Err(TrainError::config("train", "no training views"));
        }
        let mut extent = densify::scene_extent(&train.cameras())?;
        if !(extent.is_finite() && extent > 0.0) {
            // One camera (or coincident centres): fall back to the initial cube's size.
            extent = 1.1 * config.init_half_extent;
        }
        let mut densify = densify_config(&config);
        densify.max_gaussians = config.gaussian_cap(train.views.len());
        densify.validate()?;
        let mut backbone = backbone;
        backbone.prepare(&train.times(), state.len(), extent)?;
        if let Some(cap) = check_memory(&config, DataSizes::of_views(&train), state.len())? {
            densify.max_gaussians = Some(densify.max_gaussians.map_or(cap, |m| m.min(cap)));
        }
        let (raster, backend) = select_rasterizer(config.backend)?;
        let network = place_network(config.net_backend, raster.as_ref(), backbone.as_mut())?;
        #[cfg(feature = "wgpu")]
        let (loss_place, device_loss) = place_loss(&config, raster.as_ref(), &train)?;
        #[cfg(not(feature = "wgpu"))]
        let loss_place = Placement {
            part: "loss",
            on_device: false,
            reason: "built without wgpu".into(),
        };
        let transmittance = if config.background == Background::Random {
            crate::data::load_transmittance(&train, config.downscale)?
        } else {
            Vec::new()
        };
        Ok(Self {
            densify,
            config,
            train,
            extent,
            state,
            backbone,
            iteration,
            schedule_iteration: iteration,
            times: PhaseTimes::default(),
            raster,
            backend,
            network,
            loss_place,
            #[cfg(feature = "wgpu")]
            device_loss,
            order: (u64::MAX, Vec::new()),
            loss: LossWorkspace::new(),
            geometry: DeformedGeometry::default(),
            deformation_grad: Vec::new(),
            deformation: Vec::new(),
            net_grads: Vec::new(),
            fwd: ForwardOutput::default(),
            bwd: BackwardOutput::default(),
            transmittance,
            target: Vec::new(),
        })
    }

    /// The run's settings.
    pub fn config(&self) -> &TrainConfig {
        &self.config
    }

    /// The training views.
    pub fn train_views(&self) -> &SplitViews {
        &self.train
    }

    /// Scene extent (3DGS: 1.1 × the largest camera distance from the cameras' mean).
    pub fn extent(&self) -> f32 {
        self.extent
    }

    /// Gaussians, optimiser, statistics.
    pub fn state(&self) -> &SceneState {
        &self.state
    }

    /// The deformation backbone. With its network on a device ([`Trainer::network`]), its
    /// parameters and their moments in [`Trainer::state`]'s optimiser are those of the last
    /// [`Trainer::sync_host`].
    pub fn backbone(&self) -> &dyn Backbone {
        self.backbone.as_ref()
    }

    /// Copies what lives on a device into the host's copies: the network's parameters
    /// ([`Trainer::backbone`]) and their Adam moments ([`Trainer::state`]), when the network
    /// steps there (`--net-backend wgpu`; one read-back), nothing otherwise. Before a
    /// checkpoint, a weight file or a check of the values.
    pub fn sync_host(&mut self) -> Result<(), TrainError> {
        self.state.sync_network(self.backbone.as_mut())
    }

    /// Iterations completed.
    pub fn iteration(&self) -> u64 {
        self.iteration
    }

    /// The schedule iteration of the last step (equal to [`Trainer::iteration`] without a
    /// budget).
    pub fn schedule_iteration(&self) -> u64 {
        self.schedule_iteration
    }

    /// Continues the schedule from `schedule_iteration` (a budget run resumed from its
    /// checkpoint; [`Trainer::from_parts`] starts it at the iteration).
    pub fn resume_schedule_at(&mut self, schedule_iteration: u64) {
        self.schedule_iteration = schedule_iteration;
    }

    /// Time spent per phase (this process only).
    pub fn times(&self) -> &PhaseTimes {
        &self.times
    }

    /// Starts the phase times again from zero (a bench measures the steps after a warm-up).
    pub fn reset_times(&mut self) {
        self.times = PhaseTimes::default();
    }

    /// The estimate of this run's peak memory ([`crate::memory`]); `at(n)` for `n` Gaussians.
    pub fn memory_estimate(&self) -> MemoryEstimate {
        // The config was counted when the trainer was made; it cannot fail now.
        memory_estimate(&self.config, DataSizes::of_views(&self.train))
            .expect("the run's parameters were counted")
    }

    /// The most Gaussians densification may grow to (`--max-gaussians` and `--memory-limit`),
    /// `None` without a limit.
    pub fn max_gaussians(&self) -> Option<usize> {
        self.densify.max_gaussians
    }

    /// The rasterizer backend in use (chosen from `config.backend`) and why.
    pub fn backend(&self) -> &BackendInfo {
        &self.backend
    }

    /// Where the deformation network runs and why ([`TrainConfig::net_backend`]).
    pub fn network(&self) -> &Placement {
        &self.network
    }

    /// The device's own time per labelled span of work since the rasterizer's device was made
    /// (GPU timestamps, `gpu_core::timestamps`: `raster forward`, `loss`, `raster backward`),
    /// milliseconds and spans; `None` on the CPU backend, on an adapter without timestamps and
    /// in a build without wgpu.
    pub fn device_times(&self) -> Option<std::collections::BTreeMap<String, (f64, u64)>> {
        #[cfg(feature = "wgpu")]
        {
            let ctx = self.raster.device()?;
            let (totals, _missed) = ctx.timestamps.as_ref()?.totals();
            Some(
                totals
                    .into_iter()
                    .map(|(label, t)| (label.to_string(), (t.nanos * 1e-6, t.count)))
                    .collect(),
            )
        }
        #[cfg(not(feature = "wgpu"))]
        None
    }

    /// Where the loss runs and why (on the rasterizer's device with `--backend wgpu` and a fixed
    /// background).
    pub fn loss_place(&self) -> &Placement {
        &self.loss_place
    }

    /// The host–device traffic of the rasterizer's device since the trainer was made
    /// ([`splat_raster::Rasterizer::traffic`]; `None` on the CPU backend).
    pub fn traffic(&self) -> Option<splat_raster::Traffic> {
        self.raster.traffic()
    }

    /// Whether the deformation is used at iteration `i` (after the warm-up).
    pub fn deforms_at(&self, iteration: u64) -> bool {
        iteration >= self.config.warm_up
    }

    /// Index of the training view of iteration `i` (from 1).
    pub fn view_at(&mut self, iteration: u64) -> usize {
        let n = self.train.views.len() as u64;
        let epoch = (iteration - 1) / n;
        let (cached, perm) = &mut self.order;
        if *cached != epoch {
            let mut rng = ChaCha8Rng::seed_from_u64(self.config.seed);
            rng.set_stream(epoch);
            perm.clear();
            perm.extend(0..n as usize);
            perm.shuffle(&mut rng);
            *cached = epoch;
        }
        self.order.1[((iteration - 1) % n) as usize]
    }

    /// Frees the buffers reused across iterations (the deformed Gaussians, the deformation rows
    /// and their gradient, the network's gradients, the rasterizer's outputs, the loss's
    /// workspace, the random background's target image); the next [`Trainer::step`] allocates
    /// them again and computes the same values.
    pub fn release_buffers(&mut self) {
        self.geometry = DeformedGeometry::default();
        self.deformation_grad = Vec::new();
        self.deformation = Vec::new();
        self.net_grads = Vec::new();
        self.fwd = ForwardOutput::default();
        self.bwd = BackwardOutput::default();
        self.loss = LossWorkspace::new();
        self.target = Vec::new();
    }

    /// Runs one iteration, one schedule iteration on from the last.
    pub fn step(&mut self) -> Result<StepReport, TrainError> {
        self.step_to(self.schedule_iteration + 1)
    }

    /// Runs one iteration at the schedule iteration `at` (at least 1, and not below the last
    /// step's): the schedule's events of every schedule iteration after the last step's up to
    /// `at` happen in this step, in order (SH steps, densification, opacity resets), none when
    /// `at` is the last step's; the warm-up, the statistics' window, the lr and the end of the
    /// optimiser's steps are those of `at`.
    pub fn step_to(&mut self, at: u64) -> Result<StepReport, TrainError> {
        if at == 0 || at < self.schedule_iteration {
            return Err(TrainError::config(
                "schedule_iteration",
                format!(
                    "{at}: a step cannot go back in the schedule (last step at {})",
                    self.schedule_iteration
                ),
            ));
        }
        let i = self.iteration + 1;
        let crossed = self.schedule_iteration + 1..=at;
        let mut t = Instant::now();
        for j in crossed.clone() {
            if j.is_multiple_of(self.config.sh_interval) {
                self.state.raise_active_sh(self.config.sh_degree);
            }
        }
        let vi = self.view_at(i);
        let deforms = self.deforms_at(at);
        t = self.times.lap(Phase::Data, t);
        if deforms && self.schedule_iteration < self.config.warm_up {
            // The deformation starts: a backbone that places its state on the Gaussians (SC-GS's
            // control points) places it on those the static warm-up has fitted, as SC-GS places
            // its control points after its pre-training.
            self.backbone.initialise(self.state.gaussians().view())?;
        }
        if deforms {
            let view = &self.train.views[vi];
            self.backbone.forward_into(
                self.state.gaussians().view(),
                view.time,
                true,
                &mut self.deformation,
            )?;
        }
        t = self.times.lap(Phase::NetForward, t);
        self.geometry.assign(
            self.state.gaussians(),
            deforms.then_some(self.deformation.as_slice()),
            self.backbone.layout(),
        );
        let gview = self.geometry.view(self.state.gaussians());
        let view = &self.train.views[vi];
        let background = self.config.background.at_iteration(self.config.seed, i);
        let opts = RenderOptions {
            background,
            sh_degree: Some(self.state.active_sh()),
        };
        // Under a random background the target is the view's image (over black) with the
        // background showing through its transmittance.
        let target = match self.transmittance.get(vi) {
            Some(transmittance) => {
                self.target.clear();
                self.target.extend(
                    view.image
                        .pixels
                        .iter()
                        .zip(transmittance)
                        .map(|(p, &t)| [0, 1, 2].map(|c| p[c] + t * background[c])),
                );
                &self.target
            }
            None => &view.image.pixels,
        };
        t = self.times.lap(Phase::Data, t);
        let size = ImageSize::new(view.image.width as usize, view.image.height as usize);
        #[cfg(feature = "wgpu")]
        let resident = self.device_loss.as_mut();
        #[cfg(not(feature = "wgpu"))]
        let resident: Option<()> = None;
        let loss = match resident {
            #[cfg(feature = "wgpu")]
            Some(device_loss) => {
                // The image, the loss's gradient and the target stay on the device.
                let fwd = &mut self.fwd;
                self.raster
                    .forward_resident(gview, &view.camera, &opts, fwd)?;
                t = self.times.lap(Phase::RasterForward, t);
                let color = fwd.device_color().expect("a resident forward pass");
                let (loss, d_color) = device_loss.compute(vi, size, color)?;
                t = self.times.lap(Phase::Loss, t);
                self.raster.backward_resident(
                    gview,
                    &view.camera,
                    &opts,
                    fwd,
                    d_color,
                    &mut self.bwd,
                )?;
                loss
            }
            _ => {
                let fwd = &mut self.fwd;
                self.raster.forward_into(gview, &view.camera, &opts, fwd)?;
                t = self.times.lap(Phase::RasterForward, t);
                let loss = self.loss.compute(size, &fwd.color, target)?;
                t = self.times.lap(Phase::Loss, t);
                self.raster.backward_into(
                    gview,
                    &view.camera,
                    &opts,
                    fwd,
                    PixelGrads::from_color(self.loss.gradient()),
                    &mut self.bwd,
                )?;
                loss
            }
        };
        let train_psnr = psnr_from_mse(loss.mse);
        let (fwd, grads) = (&self.fwd, &self.bwd.grads);
        t = self.times.lap(Phase::RasterBackward, t);
        if deforms {
            let stride = self.state.gaussians().sh_stride();
            let layout = self.backbone.layout();
            deformation_gradient_into(grads, stride, layout, &mut self.deformation_grad);
            self.backbone
                .backward_into(&self.deformation_grad, &mut self.net_grads)?;
        }
        // On the device the network's gradient stays there, for its step there.
        let on_device = self.network.on_device;
        let net_grads = (deforms && !on_device).then_some(self.net_grads.as_slice());
        t = self.times.lap(Phase::NetBackward, t);
        let (w, h) = (view.camera.width, view.camera.height);
        let schedule = self.densify.schedule;
        if schedule.accumulates(at) {
            self.state
                .add_view_stats(&grads.means2d, fwd.radii(), w, h)?;
            if deforms {
                let cues = self.backbone.densify_cues(self.extent)?;
                self.state
                    .add_evolution_stats(cues.residual_norm.as_deref(), cues.theta.as_deref())?;
            }
        }
        let mut densified = false;
        for j in crossed.clone().filter(|&j| schedule.acts(j)) {
            let plan = make_plan(
                &self.densify,
                &densify::PlanInput {
                    gaussians: self.state.gaussians().view(),
                    stats: self.state.stats(),
                    extent: self.extent,
                    iteration: j,
                    deformation: if deforms {
                        self.backbone.latest_deformation()
                    } else {
                        None
                    },
                },
            )?;
            densified |=
                plan.summary.after != plan.summary.before || plan.new_len() != plan.old_len;
            self.state.apply_plan(&plan, self.backbone.as_mut())?;
        }
        t = self.times.lap(Phase::Densify, t);
        if at < self.config.iterations {
            let lr_step = at as i64 - 1;
            if !crossed.clone().any(|j| schedule.densifies(j)) {
                let reset = crossed.clone().any(|j| schedule.resets_opacity(j));
                self.state.step_gaussians(grads, lr_step, reset)?;
            }
            if let Some(g) = net_grads {
                self.state
                    .step_network(self.backbone.as_mut(), g, lr_step)?;
            } else if deforms && on_device {
                self.state
                    .step_network_on_device(self.backbone.as_mut(), lr_step)?;
            }
        }
        let t = self.times.lap(Phase::Optimizer, t);
        if densified && deforms {
            // After the step's updates: a backbone that follows the Gaussians (SC-GS's control
            // points, with `--control-follow-densify`) follows them to the new set.
            self.backbone
                .gaussians_changed(self.state.gaussians().view())?;
            self.times.lap(Phase::Densify, t);
        }
        self.iteration = i;
        self.schedule_iteration = at;
        Ok(StepReport {
            iteration: i,
            schedule_iteration: at,
            last: false,
            loss: loss.loss
                + if deforms {
                    self.backbone.loss_terms()
                } else {
                    0.0
                },
            psnr: train_psnr,
            gaussians: self.state.len(),
            densified,
            net_grad_norm: net_grads.map(|g| {
                g.iter()
                    .flatten()
                    .map(|&v| f64::from(v) * f64::from(v))
                    .sum::<f64>()
                    .sqrt()
            }),
        })
    }

    /// The densification settings the run uses (the schedule, and EvoGS's trigger and
    /// deformation-aware clone/split when on).
    pub fn densify(&self) -> &DensifyConfig {
        &self.densify
    }

    /// An empty [`GainReport`] for this run: still below the motion floor in scene units per
    /// frame spacing (EvoGS's `motion_floor · extent`; evo-state's default for the baseline).
    pub fn new_gain_report(&self) -> GainReport {
        GainReport::new(self.config.backbones.evogs.evo.motion_floor * self.extent)
    }

    /// The last training step of the evolution (EvoGS only), for [`GainReport::add`].
    pub fn evolution_step(&self) -> Option<&evo_state::Step> {
        self.backbone.latest_step()
    }

    /// Motion statistics of the last training step (EvoGS with three history frames only);
    /// `evogs-experiments`' motion report accumulates them.
    pub fn motion_stats(&self) -> Option<&[evo_state::Stats]> {
        self.backbone.motion_stats()
    }

    /// The deformed Gaussians at `time` (canonical ones when the run has not reached the end of
    /// its warm-up: the network is not used then).
    pub fn deformed_at(&mut self, time: f32) -> Result<Gaussians, TrainError> {
        let deforms = self.deforms_at(self.schedule_iteration.max(1));
        deformed_gaussians(
            self.state.gaussians(),
            self.backbone.as_mut(),
            deforms,
            time,
        )
    }

    /// Renders the model at `time` from `camera` on the run's backend and background with every
    /// SH band, as evaluation does (colours not clamped). Changes nothing in the training state.
    pub fn render(
        &mut self,
        camera: &splat_raster::Camera,
        time: f32,
    ) -> Result<Vec<[f32; 3]>, TrainError> {
        let g = self.deformed_at(time)?;
        let opts = RenderOptions {
            background: self.config.background.rgb(),
            sh_degree: None,
        };
        Ok(self.raster.forward(g.view(), camera, &opts)?.color)
    }
}

/// The deformed Gaussians of a canonical set at `time`; `use_network = false` returns the
/// canonical set.
pub fn deformed_gaussians(
    canonical: &Gaussians,
    backbone: &mut dyn Backbone,
    use_network: bool,
    time: f32,
) -> Result<Gaussians, TrainError> {
    let d = if use_network {
        Some(backbone.forward(canonical.view(), time, false)?)
    } else {
        None
    };
    Ok(DeformedGeometry::new(canonical, d.as_deref(), backbone.layout()).into_gaussians(canonical))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Preset;
    use crate::data::View;
    use evogs_io::{ImageRgb, Split};
    use glam::Vec3;
    use splat_raster::Camera;

    fn views(n: usize) -> SplitViews {
        SplitViews {
            split: Split::Train,
            views: (0..n)
                .map(|k| View {
                    path: format!("r_{k}.png").into(),
                    image: ImageRgb::filled(8, 8, [0.5; 3]),
                    camera: Camera::look_at(
                        8,
                        8,
                        0.8,
                        Vec3::new(3.0 * (k as f32).cos(), 3.0 * (k as f32).sin(), 1.0),
                        Vec3::ZERO,
                        Vec3::Z,
                    ),
                    time: k as f32 / n.max(2) as f32,
                })
                .collect(),
        }
    }

    fn trainer(n: usize, seed: u64) -> Result<Trainer, TrainError> {
        let mut c = TrainConfig::preset(Preset::Tiny);
        c.init_points = 20;
        c.seed = seed;
        Trainer::new(c, views(n))
    }

    #[test]
    fn every_epoch_is_a_seeded_permutation_of_the_views() {
        let mut t = trainer(7, 1).unwrap();
        let epochs: Vec<Vec<usize>> = (0..4)
            .map(|e| (1..=7).map(|k| t.view_at(e * 7 + k)).collect())
            .collect();
        for e in &epochs {
            let mut sorted = e.clone();
            sorted.sort_unstable();
            assert_eq!(sorted, (0..7).collect::<Vec<_>>());
        }
        assert!(epochs.windows(2).any(|w| w[0] != w[1]), "epochs reshuffle");
        // A pure function of (seed, iteration): asking out of order gives the same views.
        let mut u = trainer(7, 1).unwrap();
        assert_eq!(u.view_at(20), epochs[2][5]);
        assert_eq!(u.view_at(3), epochs[0][2]);
        let mut other = trainer(7, 2).unwrap();
        let o: Vec<usize> = (1..=7).map(|k| other.view_at(k)).collect();
        assert_ne!(o, epochs[0]);
    }

    /// Adam steps taken by the positions group.
    fn position_steps(t: &Trainer) -> u64 {
        t.state().adam().groups()[0].step
    }

    #[test]
    fn steps_placed_in_the_schedule_run_each_event_once() {
        // Tiny at 300: SH up every 100 (degree 3 at 300), no densification before 50.
        let mut t = trainer(5, 0).unwrap();
        let r = t.step_to(1).unwrap();
        assert_eq!((r.iteration, r.schedule_iteration), (1, 1));
        t.step_to(99).unwrap();
        assert_eq!(t.state().active_sh(), 0);
        // One step across two SH steps (100, 200) takes both.
        t.step_to(250).unwrap();
        assert_eq!(t.state().active_sh(), 2);
        // Several steps may share a schedule iteration: the views go on, no event repeats, and
        // each steps the optimiser.
        let before = position_steps(&t);
        t.step_to(250).unwrap();
        assert_eq!(t.state().active_sh(), 2);
        assert_eq!(position_steps(&t), before + 1);
        assert_eq!((t.iteration(), t.schedule_iteration()), (4, 250));
        let e = t.step_to(249).unwrap_err().to_string();
        assert!(e.contains("schedule_iteration") && e.contains("249"), "{e}");
        // The schedule's last iteration does no optimiser step, as without a budget.
        let before = position_steps(&t);
        t.step_to(300).unwrap();
        assert_eq!(t.state().active_sh(), 3);
        assert_eq!(position_steps(&t), before);
        // Without a budget the two counts are one.
        let mut u = trainer(5, 0).unwrap();
        for _ in 0..3 {
            u.step().unwrap();
        }
        assert_eq!((u.iteration(), u.schedule_iteration()), (3, 3));
        assert!(u.step_to(0).is_err());
    }

    #[test]
    fn the_cap_follows_the_training_views() {
        // Tiny with a budget of 1 000 Gaussians × views above 20 initial points: 100 at 10 views,
        // 20 (the initial points) at 100; densify's own cap still bounds it.
        let mut c = TrainConfig::preset(Preset::Tiny);
        c.init_points = 20;
        c.gaussian_view_budget = Some(1_000);
        let cap = |c: &TrainConfig, n| Trainer::new(c.clone(), views(n)).unwrap().max_gaussians();
        assert_eq!(cap(&c, 10), Some(100));
        assert_eq!(cap(&c, 100), Some(20));
        c.densify.max_gaussians = Some(60);
        assert_eq!(cap(&c, 10), Some(60));
        c.gaussian_view_budget = None;
        assert_eq!(cap(&c, 1), Some(60));
    }

    #[test]
    fn images_over_the_device_budget_stay_on_the_host() {
        let v = views(3);
        let bytes: u64 = v
            .views
            .iter()
            .map(|w| 12 * w.image.pixels.len() as u64)
            .sum();
        assert!(bytes > 0);
        assert_eq!(images_over_budget(&v, bytes), None);
        let why = images_over_budget(&v, bytes - 1).expect("one byte over");
        assert!(why.starts_with("the 3 training images take "), "{why}");
    }

    #[test]
    fn no_views_is_an_error() {
        let e = trainer(0, 0).err().unwrap().to_string();
        assert!(e.contains("no training views"), "{e}");
    }
}
