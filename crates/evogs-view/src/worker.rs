//! The render thread of one run: it owns the loaded run (rendering needs it mutably), takes
//! jobs from a [`Latest`] slot, and with `--watch` reloads the run when its files change.
//!
//! A reload happens between two renders: the thread polls the modification times and sizes of
//! the run's files every [`WATCH_POLL`] and reloads once they have stayed the same for one
//! poll after changing (training writes them one after another). A reload that fails (a
//! half-written or damaged file) keeps the previous model and reports the error in
//! [`RunInfo::reload_error`].
//!
//! Which files a run is loaded from ([`Source`]): while it trains, its checkpoint
//! (`checkpoint.safetensors`, read by the trainer's loader, [`LoadedRun::open_checkpoint`]);
//! once the end-of-run files are written (`train_metrics.json`, written last, is at least as
//! new as the checkpoint), those ([`LoadedRun::open`]).

use std::path::{Path, PathBuf};
use std::sync::mpsc::{Sender, channel};
use std::sync::{Arc, PoisonError, RwLock};
use std::time::{Duration, Instant, SystemTime};

use evogs_eval::LoadedRun;
use evogs_eval::render::{CONTROL_COLOUR, draw_points, render_deformed};
use evogs_io::{Frame, ImageRgb, Split};
use evogs_train::TrainError;
use evogs_train::data::open_dataset;
use evogs_video::camera_path::{SceneFit, resize_camera, split_cameras};
use splat_raster::{BackendChoice, Camera, ForwardOutput, Gaussians};

use crate::ViewError;
use crate::latest::{Latest, Taken};
use crate::params::{BadRequest, CameraParam};

/// Which files a run is loaded from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Source {
    /// The end-of-run files (`canonical.ply`, `deform.safetensors`, `train_metrics.json`).
    EndOfRun,
    /// `checkpoint.safetensors` of a run that is still training (or was stopped before its
    /// end-of-run files were written).
    Checkpoint,
}

impl Source {
    /// The checkpoint when it is newer than `train_metrics.json` (the last end-of-run file a
    /// run writes) or when that file does not exist; the end-of-run files otherwise (and, when
    /// that checkpoint cannot be read but the end-of-run files are there, those: what `evogs
    /// eval` and `render` read).
    pub fn of(root: &Path) -> Self {
        let paths = evogs_train::RunPaths::new(root);
        let modified = |p: PathBuf| std::fs::metadata(p).and_then(|m| m.modified()).ok();
        match (
            modified(paths.train_metrics()),
            modified(paths.checkpoint()),
        ) {
            (None, Some(_)) => Self::Checkpoint,
            (Some(end), Some(checkpoint)) if checkpoint > end => Self::Checkpoint,
            _ => Self::EndOfRun,
        }
    }

    /// Loads the run at `root` from these files.
    pub fn open(self, root: &Path) -> Result<LoadedRun, TrainError> {
        match self {
            Self::EndOfRun => LoadedRun::open(root),
            Self::Checkpoint => LoadedRun::open_checkpoint(root),
        }
    }
}

/// How often `--watch` looks at the run's files.
pub const WATCH_POLL: Duration = Duration::from_millis(500);

/// A dataset camera as the page and the API see it.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct CameraEntry {
    /// World-to-camera rotation, row by row (the camera's x, y, z axes in world).
    #[serde(rename = "R")]
    pub rotation: [f32; 9],
    /// The camera centre.
    #[serde(rename = "C")]
    pub center: [f32; 3],
    /// `fx, fy, cx, cy` in pixels of `w × h`.
    #[serde(rename = "K")]
    pub intrinsics: [f32; 4],
    /// Image width.
    pub w: u32,
    /// Image height.
    pub h: u32,
    /// The frame's time.
    pub t: f32,
}

impl CameraEntry {
    fn new(camera: &Camera, time: f32) -> Self {
        let rows = [0, 1, 2].map(|i| camera.rotation.row(i).to_array());
        Self {
            rotation: std::array::from_fn(|k| rows[k / 3][k % 3]),
            center: camera.center().to_array(),
            intrinsics: [camera.fx, camera.fy, camera.cx, camera.cy],
            w: camera.width,
            h: camera.height,
            t: time,
        }
    }
}

/// What the page is told about a run (`/api/info`), and what the server needs to serve its
/// dataset cameras and ground truth.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RunInfo {
    /// The run directory's name.
    pub name: String,
    /// The run directory as `evogs view` was given it, made absolute: what the page's
    /// `evogs render --run` line names, so that the line works from any folder.
    pub path: String,
    /// The method on its backbone as the papers name it (`D-3DGS`, `EvoGS(D-3DGS)`, `SC-GS`).
    pub label: String,
    /// `baseline` or `evogs`.
    pub method: serde_json::Value,
    /// The deformation backbone.
    pub backbone: serde_json::Value,
    /// Iterations trained.
    pub iteration: u64,
    /// Iterations planned.
    pub iterations: u64,
    /// Canonical Gaussians.
    pub gaussians: usize,
    /// The control points that carry the motion (SC-GS's), `None` for a backbone without them;
    /// `controls=1` draws them over a view.
    pub control_points: Option<usize>,
    /// The backend that renders, and why.
    pub backend: String,
    /// Mean PSNR of each evaluated split (`eval_<split>.json`), by split name.
    pub psnr: serde_json::Map<String, serde_json::Value>,
    /// The last training iteration's PSNR on its training view.
    pub train_psnr: f64,
    /// The files the model was loaded from.
    pub source: Source,
    /// Loads so far (1 after start; each `--watch` reload adds one).
    pub version: u64,
    /// What the viewer chose that the user should know (a newer checkpoint it could not read,
    /// so the end-of-run files are shown).
    pub note: Option<String>,
    /// Why the last reload failed, if it did (the previous model is still shown).
    pub reload_error: Option<String>,
    /// The run's resolution (its first training camera's size).
    pub width: u32,
    /// The run's resolution.
    pub height: u32,
    /// The render background.
    pub background: [f32; 3],
    /// The scene's up vector and look-at point fitted to the training cameras.
    pub up: [f32; 3],
    /// The look-at point.
    pub target: [f32; 3],
    /// The cameras of each split (empty when the split has none), by split name.
    pub cameras: std::collections::BTreeMap<&'static str, Vec<CameraEntry>>,
    /// The dataset frames of each split, for the ground truth.
    #[serde(skip)]
    pub frames: std::collections::BTreeMap<&'static str, Vec<Frame>>,
    /// The factor images are resized by (the run's `downscale`).
    #[serde(skip)]
    pub factor: f32,
    /// The cameras of each split with their times, exactly as `evogs render` resolves
    /// `dataset:SPLIT:INDEX`.
    #[serde(skip)]
    pub split_cameras: std::collections::BTreeMap<&'static str, Vec<(Camera, f32)>>,
}

impl RunInfo {
    /// The camera and time of `split`'s camera `index`.
    pub fn dataset_camera(&self, split: Split, index: usize) -> Result<(Camera, f32), BadRequest> {
        let cams = self
            .split_cameras
            .get(split.name())
            .map(Vec::as_slice)
            .unwrap_or_default();
        cams.get(index).copied().ok_or_else(|| {
            BadRequest(format!(
                "camera {index} of split {split} does not exist: the split has {} cameras",
                cams.len()
            ))
        })
    }

    /// The ground-truth image of `split`'s camera `index` at the run's resolution, over the
    /// run's background.
    pub fn ground_truth(&self, split: Split, index: usize) -> Result<ImageRgb, GtError> {
        let frames = self
            .frames
            .get(split.name())
            .map(Vec::as_slice)
            .unwrap_or_default();
        let frame = frames.get(index).ok_or_else(|| {
            GtError::Bad(BadRequest(format!(
                "image {index} of split {split} does not exist: the split has {} images",
                frames.len()
            )))
        })?;
        evogs_io::load_view(
            &frame.image_path,
            &frame.camera.camera,
            self.background,
            self.factor,
        )
        .map(|(image, _)| image)
        .map_err(|e| GtError::Failed(e.to_string()))
    }
}

/// Why a ground-truth image could not be served.
#[derive(Debug)]
pub enum GtError {
    /// The request names no image (HTTP 404).
    Bad(BadRequest),
    /// The image file could not be read (HTTP 500).
    Failed(String),
}

/// A rendered view.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// The image, colours in [0, 1].
    pub image: ImageRgb,
    /// The camera it was rendered from.
    pub camera: Camera,
    /// The time it shows.
    pub time: f32,
    /// Milliseconds the render took (deformation and rasterization).
    pub millis: f64,
    /// Of which deforming the Gaussians to the time (0 when the last view's time was the same:
    /// the deformed Gaussians are kept for the next view).
    pub deform_millis: f64,
    /// Of which rasterizing.
    pub raster_millis: f64,
    /// The run's load count at render time ([`RunInfo::version`]).
    pub version: u64,
}

/// Why a render did not happen.
#[derive(Debug)]
pub enum RenderFailure {
    /// A newer request for the same run came before this one started (HTTP 409).
    Superseded,
    /// The request names a camera the run does not have (HTTP 404).
    Bad(BadRequest),
    /// Rendering failed (HTTP 500).
    Failed(String),
}

/// Why `controls=1` cannot be served for a run.
pub const NO_CONTROLS: &str =
    "`controls`: the run's backbone has no control points (those of --backbone scgs)";

/// A render request.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderJob {
    /// The camera.
    pub camera: CameraParam,
    /// The time; absent: the dataset camera's time, or 0.
    pub time: Option<f32>,
    /// Output size.
    pub width: Option<u32>,
    /// Output size.
    pub height: Option<u32>,
    /// Draw the run's control points over the view (a run with [`RunInfo::control_points`]).
    pub controls: bool,
}

/// A job and where its answer goes.
type Posted = (RenderJob, Sender<Result<Rendered, RenderFailure>>);

/// What the server shares with one run's render thread.
pub struct RunHandle {
    slot: Latest<Posted>,
    info: RwLock<Arc<RunInfo>>,
    thread: std::sync::Mutex<Option<std::thread::JoinHandle<()>>>,
}

impl RunHandle {
    /// Loads the run at `root` on a new render thread with `backend`; returns once it is loaded
    /// (or with the error naming the file and the field).
    pub fn start(root: &Path, backend: BackendChoice, watch: bool) -> Result<Arc<Self>, ViewError> {
        let (ready_tx, ready_rx) = channel();
        let root = root.to_path_buf();
        let (handle_tx, handle_rx) = channel::<Arc<RunHandle>>();
        let thread = std::thread::Builder::new()
            .name("evogs-view-render".into())
            .spawn(move || {
                let mut state = match Loaded::load(&root, backend, 1) {
                    Ok(state) => state,
                    Err(e) => {
                        let _ = ready_tx.send(Err(e));
                        return;
                    }
                };
                let _ = ready_tx.send(Ok(Arc::clone(&state.info)));
                let Ok(handle) = handle_rx.recv() else { return };
                render_loop(&handle, &mut state, &root, backend, watch);
            })
            .map_err(|e| ViewError::Thread(e.to_string()))?;
        let info = match ready_rx.recv() {
            Ok(Ok(info)) => info,
            Ok(Err(e)) => return Err(e.into()),
            Err(_) => return Err(ViewError::Thread("the render thread stopped".into())),
        };
        let handle = Arc::new(Self {
            slot: Latest::new(),
            info: RwLock::new(info),
            thread: std::sync::Mutex::new(Some(thread)),
        });
        handle_tx
            .send(Arc::clone(&handle))
            .map_err(|_| ViewError::Thread("the render thread stopped".into()))?;
        Ok(handle)
    }

    /// The run's current description.
    pub fn info(&self) -> Arc<RunInfo> {
        Arc::clone(&self.info.read().unwrap_or_else(PoisonError::into_inner))
    }

    /// Renders `job`'s view; a newer request that arrives before this one starts supersedes it.
    pub fn render(&self, job: RenderJob) -> Result<Rendered, RenderFailure> {
        let (tx, rx) = channel();
        if let Some((_, old)) = self.slot.post((job, tx)) {
            let _ = old.send(Err(RenderFailure::Superseded));
        }
        rx.recv()
            .unwrap_or_else(|_| Err(RenderFailure::Failed("the render thread stopped".into())))
    }

    /// Stops the render thread after its current job.
    pub fn stop(&self) {
        self.slot.close();
        let thread = self
            .thread
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .take();
        if let Some(t) = thread {
            let _ = t.join();
        }
    }
}

/// The run and its description, owned by the render thread.
struct Loaded {
    run: LoadedRun,
    info: Arc<RunInfo>,
    stamps: Vec<Option<(SystemTime, u64)>>,
    /// The Gaussians deformed to the last view's time (its bits), reused while the time stays.
    deformed: Option<(u32, Gaussians)>,
    /// The last forward pass, whose buffers the next one reuses.
    fwd: ForwardOutput,
}

/// The files whose change makes `--watch` reload.
fn watched(root: &Path) -> Vec<PathBuf> {
    let paths = evogs_train::RunPaths::new(root);
    vec![
        paths.config(),
        paths.canonical(),
        paths.weights(),
        paths.evo_state(),
        paths.train_metrics(),
        paths.checkpoint(),
    ]
}

fn stamps(root: &Path) -> Vec<Option<(SystemTime, u64)>> {
    watched(root)
        .iter()
        .map(|p| {
            let m = std::fs::metadata(p).ok()?;
            Some((m.modified().ok()?, m.len()))
        })
        .collect()
}

impl Loaded {
    fn load(root: &Path, backend: BackendChoice, version: u64) -> Result<Self, TrainError> {
        let before = stamps(root);
        let mut source = Source::of(root);
        let mut note = None;
        let mut run = match source.open(root) {
            Ok(run) => run,
            // One rule with `evogs eval` and `render`: a run whose end-of-run files are there
            // is shown from them when its newer checkpoint cannot be read.
            Err(e)
                if source == Source::Checkpoint
                    && evogs_train::RunPaths::new(root).train_metrics().is_file() =>
            {
                note = Some(format!(
                    "its newer checkpoint could not be read ({e}); showing the end-of-run files"
                ));
                source = Source::EndOfRun;
                source.open(root)?
            }
            Err(e) => return Err(e),
        };
        let backend = run.use_backend(backend)?.to_string();
        let mut cameras = std::collections::BTreeMap::new();
        let mut split_cams = std::collections::BTreeMap::new();
        let mut frames = std::collections::BTreeMap::new();
        let dataset = open_dataset(run.data()?, run.run.train.time_from)?;
        for split in Split::ALL {
            // A split the dataset does not have is simply empty here.
            let cams = split_cameras(&run, split).unwrap_or_default();
            cameras.insert(
                split.name(),
                cams.iter().map(|(c, t)| CameraEntry::new(c, *t)).collect(),
            );
            split_cams.insert(split.name(), cams);
            frames.insert(split.name(), dataset.split(split).to_vec());
        }
        let train = split_cams.get("train").cloned().unwrap_or_default();
        let fit_cams: Vec<Camera> = train.iter().map(|(c, _)| *c).collect();
        let fit = SceneFit::fit(&fit_cams)?;
        let (width, height) = fit_cams.first().map_or((400, 400), |c| (c.width, c.height));
        let mut psnr = serde_json::Map::new();
        for split in Split::ALL {
            let path = run.paths.eval_json(split);
            let value = std::fs::read_to_string(&path)
                .ok()
                .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
                .and_then(|v| v.get("mean_psnr").cloned());
            if let Some(v) = value {
                psnr.insert(split.name().to_string(), v);
            }
        }
        let control_points = run
            .backbone
            .control_points_at(0.0)
            .map_err(TrainError::from)?
            .map(|p| p.len());
        let info = RunInfo {
            name: root.file_name().map_or_else(
                || root.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            ),
            path: std::path::absolute(root)
                .unwrap_or_else(|_| root.to_path_buf())
                .display()
                .to_string(),
            label: run.run.train.method.label(run.run.train.backbone),
            method: serde_json::to_value(run.run.train.method).unwrap_or_default(),
            backbone: serde_json::to_value(run.run.train.backbone).unwrap_or_default(),
            iteration: run.summary.iteration,
            iterations: run.summary.iterations,
            gaussians: run.canonical.len(),
            control_points,
            backend,
            psnr,
            train_psnr: run.summary.last_psnr,
            source,
            version,
            note,
            reload_error: None,
            width,
            height,
            background: run.run.train.background.rgb(),
            up: fit.up.to_array(),
            target: fit.target.to_array(),
            cameras,
            frames,
            factor: run.run.train.downscale,
            split_cameras: split_cams,
        };
        Ok(Self {
            run,
            info: Arc::new(info),
            stamps: before,
            deformed: None,
            fwd: ForwardOutput::default(),
        })
    }

    fn render(&mut self, job: &RenderJob) -> Result<Rendered, RenderFailure> {
        let (camera, time) = match job.camera {
            CameraParam::Dataset { split, index } => {
                let (camera, time) = self
                    .info
                    .dataset_camera(split, index)
                    .map_err(RenderFailure::Bad)?;
                (
                    resize_camera(camera, job.width, job.height),
                    job.time.unwrap_or(time),
                )
            }
            CameraParam::Pose(camera) => (camera, job.time.unwrap_or(0.0)),
        };
        // What `render_at` does, in its two halves, so that the deformation is computed once
        // per time and each half is timed.
        let start = Instant::now();
        let g = match &mut self.deformed {
            Some((bits, g)) if *bits == time.to_bits() => &*g,
            slot => {
                let g = self
                    .run
                    .deformed(time)
                    .map_err(|e| RenderFailure::Failed(e.to_string()))?;
                &slot.insert((time.to_bits(), g)).1
            }
        };
        let deformed = Instant::now();
        let mut image = render_deformed(&self.run, g, &camera, &mut self.fwd)
            .map_err(|e| RenderFailure::Failed(e.to_string()))?;
        if job.controls {
            // `evogs render --show-controls`'s points and colour.
            let points = self
                .run
                .backbone
                .control_points_at(time)
                .map_err(|e| RenderFailure::Failed(e.to_string()))?
                .ok_or_else(|| RenderFailure::Bad(BadRequest(NO_CONTROLS.to_string())))?;
            draw_points(&mut image, &camera, &points, CONTROL_COLOUR);
        }
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        Ok(Rendered {
            image,
            camera,
            time,
            millis: ms(start.elapsed()),
            deform_millis: ms(deformed - start),
            raster_millis: ms(deformed.elapsed()),
            version: self.info.version,
        })
    }
}

fn render_loop(
    handle: &RunHandle,
    state: &mut Loaded,
    root: &Path,
    backend: BackendChoice,
    watch: bool,
) {
    let mut last_check = Instant::now();
    let mut changed: Option<Vec<Option<(SystemTime, u64)>>> = None;
    loop {
        let wait = if watch {
            WATCH_POLL
        } else {
            Duration::from_secs(3600)
        };
        match handle.slot.take_timeout(wait) {
            Taken::Job((job, reply)) => {
                let _ = reply.send(state.render(&job));
            }
            Taken::Timeout => {}
            Taken::Closed => return,
        }
        if !watch || last_check.elapsed() < WATCH_POLL {
            continue;
        }
        last_check = Instant::now();
        let now = stamps(root);
        if now == state.stamps {
            changed = None;
            continue;
        }
        // Reload once the files stayed the same for one poll.
        if changed.as_ref() != Some(&now) {
            changed = Some(now);
            continue;
        }
        changed = None;
        let version = state.info.version + 1;
        // A loader that panicked on some damaged file must not end the render thread: the
        // reload counts as failed. `AssertUnwindSafe` is sound: the closure only builds a new
        // value and shares nothing with `state` that a panic could leave half-changed.
        let loaded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            Loaded::load(root, backend, version)
        }))
        .unwrap_or_else(|_| {
            Err(TrainError::file(
                root,
                "the run's files could not be read (the loader panicked)",
            ))
        });
        match loaded {
            Ok(new) => *state = new,
            Err(e) => {
                let mut info = (*state.info).clone();
                info.reload_error = Some(e.to_string());
                state.info = Arc::new(info);
                // Do not retry until the files change again.
                state.stamps = stamps(root);
            }
        }
        *handle.info.write().unwrap_or_else(PoisonError::into_inner) = Arc::clone(&state.info);
    }
}
