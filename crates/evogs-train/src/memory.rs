//! An estimate of a training run's peak memory, printed by `evogs train` at the start and
//! checked, before anything of the run is allocated, against `--memory-limit`
//! ([`MemoryEstimate::max_gaussians`]) or else the memory the machine has available
//! ([`available_memory`]; `evogs_train::trainer::check_memory`).
//!
//! What it is: the peak of a checkpoint write, from the settings and the sizes known at the
//! start. A training step holds the training images, the process's fixed cost, the per-pixel
//! render and loss buffers, the network (parameters, gradients, Adam moments) and a cost per
//! Gaussian (parameters, Adam moments, gradients, densification statistics, the rasterizer's
//! records and tile lists, the deformation rows and the network's per-row activations, EvoGS's
//! buffer and per-frame memory). The step's buffers stay allocated between steps (the training
//! iteration allocates nothing once warmed up), so writing a checkpoint holds all of that and,
//! on top, the serialised copies of the state (EvoGS's buffer and memory, or the Gaussians with
//! their Adam moments and statistics, whichever is larger). The Gaussian count is the one
//! unknown at the start: [`MemoryEstimate::at`] gives the estimate for any count, and a memory
//! limit becomes a cap on the count.
//!
//! What it is not: a measurement. The per-row network activations are modelled as the layer
//! widths (the exact buffers depend on the backbone), the tile lists as [`TILES_PER_GAUSSIAN`]
//! tiles per Gaussian, and the fixed cost ([`PROCESS_BYTES`]) was measured once; the figures it
//! was checked against are in `results/memory.md`.

use crate::config::{Background, TrainConfig};

/// Bytes of a process that holds no data yet: the binary, its libraries, the thread pool and
/// the allocator's own (peak RSS of `evogs train` under a memory limit, less the rest of the
/// estimate, on a 24×24 synthetic scene and on lego: 14 and 10.5 MiB, see
/// `results/memory.md`).
pub const PROCESS_BYTES: u64 = 12 << 20;

/// Tiles (16×16 pixels) a Gaussian's footprint touches on average, for the rasterizer's tile
/// lists (8 bytes per Gaussian–tile pair).
pub const TILES_PER_GAUSSIAN: u64 = 4;

/// Bytes per pixel of the render buffers of one step: the rendered colour, alpha and depth, the
/// compositor's final transmittance and last contributor, the loss gradient and the SSIM's
/// blurred images (forward and backward).
pub const BYTES_PER_PIXEL: u64 = 4 * (3 + 1 + 1 + 1 + 1 + 3 + 5 * 3 * 2);

/// The sizes a run's memory depends on besides its settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryInputs {
    /// Training views (images held in memory).
    pub views: usize,
    /// Pixels of one training image after resizing.
    pub pixels: usize,
    /// Distinct training times (EvoGS keeps a buffer and a memory row per time).
    pub frames: usize,
    /// Floats in the network's parameters.
    pub network_params: usize,
}

/// The sizes of a run's training data the estimate depends on: read from the loaded views
/// ([`DataSizes::of_views`]) or, before any image is loaded, from the dataset's cameras
/// ([`DataSizes::of_split`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DataSizes {
    /// Training views.
    pub views: usize,
    /// Pixels of one training image after resizing.
    pub pixels: usize,
    /// Distinct training times.
    pub frames: usize,
}

impl DataSizes {
    /// The sizes of loaded training views (the first view's image, as every view shares it).
    pub fn of_views(train: &crate::data::SplitViews) -> Self {
        Self {
            views: train.views.len(),
            pixels: train
                .views
                .first()
                .map_or(0, |v| v.image.width as usize * v.image.height as usize),
            frames: train.times().len(),
        }
    }

    /// The sizes of a split read from the dataset's cameras before any image is loaded: its
    /// frames, its distinct times, and the first frame's camera resized by `factor` (the loaded
    /// views must all share that size, `data::load_dataset_split` checks).
    pub fn of_split(dataset: &evogs_io::Dataset, split: evogs_io::Split, factor: f32) -> Self {
        let frames = dataset.split(split);
        let mut times: Vec<f32> = frames.iter().map(|f| f.time).collect();
        times.sort_by(f32::total_cmp);
        times.dedup();
        Self {
            views: frames.len(),
            pixels: frames.first().map_or(0, |f| {
                let c = f.camera.camera.scaled(factor);
                c.width as usize * c.height as usize
            }),
            frames: times.len(),
        }
    }

    /// The estimate's inputs with a network of `network_params` floats.
    pub fn with_network(self, network_params: usize) -> MemoryInputs {
        MemoryInputs {
            views: self.views,
            pixels: self.pixels,
            frames: self.frames,
            network_params,
        }
    }
}

/// The estimate, by part (bytes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryEstimate {
    /// The training images (f32 RGB, and 1 − α under a random background).
    pub images: u64,
    /// Everything that does not grow with the Gaussians: the process, the render buffers and
    /// the network (parameters, gradients and two Adam moments).
    pub fixed: u64,
    /// Of which the network.
    pub network: u64,
    /// Of which the render and loss buffers of a step.
    pub render: u64,
    /// Bytes per Gaussian during a step.
    pub per_gaussian: u64,
    /// Of which EvoGS's buffer and per-frame memory (0 for other methods).
    pub evolution_per_gaussian: u64,
    /// Bytes per Gaussian a checkpoint write holds on top of a step's: the larger of the two
    /// serialised files (EvoGS's state in one copy; the checkpoint's tensors (parameters, Adam
    /// moments, densification statistics) and the file they are serialised into, two copies).
    pub checkpoint_per_gaussian: u64,
}

impl MemoryEstimate {
    /// The estimate for `config` on a dataset of `inputs`.
    pub fn new(config: &TrainConfig, inputs: &MemoryInputs) -> Self {
        const F32: u64 = 4;
        // A random background keeps each image's transmittance beside it, and a step's target.
        let random = u64::from(config.background == Background::Random);
        // Saturating: a size read from a file must not wrap the estimate below a limit.
        let images = (inputs.views as u64)
            .saturating_mul(inputs.pixels as u64)
            .saturating_mul((3 + random) * F32);
        let network = network_bytes(inputs.network_params, 4);
        let render = (inputs.pixels as u64).saturating_mul(BYTES_PER_PIXEL + random * 3 * F32);
        // The backbone's own buffers (activations, evolution state): the backbone crate models
        // them, so that nothing here names a backbone.
        let backbone = config.backbone_run().working_bytes(inputs.frames);
        let fixed = PROCESS_BYTES
            .saturating_add(render)
            .saturating_add(network)
            .saturating_add(backbone.fixed);
        // Per Gaussian: P floats of parameters, two Adam moments, the gradients (P plus the 2-D
        // means and the radius), the deformed copy of the geometry (10) and the deformation rows
        // with their gradient (at most `Layout::MAX_DIM` each: an upper bound for every layout).
        let sh = 3 * (config.sh_degree as u64 + 1).pow(2);
        let p = 3 + 3 + 4 + 1 + sh;
        let gaussian = F32 * (p + 2 * p + (p + 3) + 10 + 2 * splat_core::Layout::MAX_DIM as u64);
        // Densification statistics: 7 arrays of 4 bytes.
        let stats = 7 * 4;
        // Rasterizer: the drawn record (56 bytes), its depth rank, pair start and radius, and
        // the tile lists' two entries per touched tile.
        let raster = 56 + 4 + 8 + 4 + 8 * TILES_PER_GAUSSIAN;
        let (network_rows, evolution) = (backbone.per_row, backbone.evolution_per_row);
        // The checkpoint's tensors: the parameters with their two Adam moments and the
        // statistics (stored as they are in memory).
        let kept = F32 * 3 * p + stats;
        Self {
            images,
            fixed,
            network,
            render,
            per_gaussian: gaussian + stats + raster + network_rows + evolution,
            evolution_per_gaussian: evolution,
            checkpoint_per_gaussian: evolution.max(2 * kept),
        }
    }

    /// The estimated peak with `gaussians` Gaussians: a checkpoint write's, which holds a
    /// step's buffers and the serialised copies.
    pub fn at(&self, gaussians: usize) -> u64 {
        self.images
            .saturating_add(self.fixed)
            .saturating_add(self.peak_per_gaussian().saturating_mul(gaussians as u64))
    }

    /// Bytes per Gaussian at the peak: a step's and a checkpoint write's copies.
    pub fn peak_per_gaussian(&self) -> u64 {
        self.per_gaussian + self.checkpoint_per_gaussian
    }

    /// The most Gaussians whose estimate stays within `limit` bytes; `None` when even the
    /// images and fixed part exceed it.
    pub fn max_gaussians(&self, limit: u64) -> Option<usize> {
        let room = limit.checked_sub(self.images.saturating_add(self.fixed))?;
        Some(usize::try_from(room / self.peak_per_gaussian().max(1)).unwrap_or(usize::MAX))
    }

    /// One line: the total at `gaussians` and its parts.
    pub fn summary(&self, gaussians: usize) -> String {
        format!(
            "memory estimate: {} with {gaussians} Gaussians (images {}, network {}, other fixed {}, \
             {} per Gaussian{}; writing a checkpoint: {} more per Gaussian)",
            human_bytes(self.at(gaussians)),
            human_bytes(self.images),
            human_bytes(self.network),
            human_bytes(self.fixed - self.network),
            human_bytes(self.per_gaussian),
            if self.evolution_per_gaussian > 0 {
                format!(
                    " of which {} evolution buffer and memory",
                    human_bytes(self.evolution_per_gaussian)
                )
            } else {
                String::new()
            },
            human_bytes(self.checkpoint_per_gaussian),
        )
    }
}

/// Bytes of `params` f32 parameters held in `copies` copies (1 for evaluation; 4 for training:
/// the values, their gradient and two Adam moments), saturating.
pub fn network_bytes(params: usize, copies: u64) -> u64 {
    (params as u64).saturating_mul(4 * copies)
}

/// The memory this machine has available now (Linux: `MemAvailable` of `/proc/meminfo`, the
/// kernel's estimate of what can be allocated without swapping); `None` where it cannot be read.
pub fn available_memory() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    parse_mem_available(&meminfo)
}

/// `MemAvailable` of a `/proc/meminfo` text, in bytes.
fn parse_mem_available(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let mut words = line.split_whitespace().skip(1);
    let value: u64 = words.next()?.parse().ok()?;
    match words.next() {
        Some("kB") => value.checked_mul(1024),
        _ => None,
    }
}

/// Bytes as `12.3 MiB` (binary units).
pub fn human_bytes(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} B")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}

/// Parses a byte count with an optional binary suffix: `8G`, `512M`, `64k`, `1.5GiB`, `1000`.
pub fn parse_bytes(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, suffix) = t.split_at(split);
    let value: f64 = number
        .parse()
        .map_err(|_| format!("{text:?} is not a byte count (e.g. 8G, 512M, 1000000)"))?;
    let shift = match suffix.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 10,
        "m" | "mb" | "mib" => 20,
        "g" | "gb" | "gib" => 30,
        "t" | "tb" | "tib" => 40,
        other => {
            return Err(format!(
                "{text:?}: unknown unit {other:?} (use K, M, G or T)"
            ));
        }
    };
    let bytes = value * (1u64 << shift) as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(format!("{text:?} is not a positive byte count"));
    }
    Ok(bytes as u64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Preset;
    use crate::config::Method;
    use evogs_backbones::{HistoryMode, Storage};

    fn inputs() -> MemoryInputs {
        MemoryInputs {
            views: 50,
            pixels: 400 * 400,
            frames: 50,
            network_params: 10_000,
        }
    }

    #[test]
    fn available_memory_is_read_from_meminfo() {
        let meminfo =
            "MemTotal:       24576000 kB\nMemFree:  100 kB\nMemAvailable:   20000000 kB\n";
        assert_eq!(parse_mem_available(meminfo), Some(20_000_000 * 1024));
        assert_eq!(parse_mem_available("MemTotal: 5 kB\n"), None);
        assert_eq!(parse_mem_available("MemAvailable: many kB\n"), None);
        // This machine (Linux in CI) says how much it has.
        if cfg!(target_os = "linux") {
            assert!(available_memory().is_some_and(|b| b > 0));
        }
    }

    #[test]
    fn images_and_the_network_are_counted_exactly() {
        let e = MemoryEstimate::new(&TrainConfig::preset(Preset::Cpu), &inputs());
        assert_eq!(e.images, 50 * 400 * 400 * 12);
        assert_eq!(e.network, 10_000 * 16);
        assert_eq!(e.fixed, PROCESS_BYTES + 160_000 * BYTES_PER_PIXEL + 160_000);
        assert_eq!(e.at(0), e.images + e.fixed);
        assert_eq!(e.at(1000) - e.at(0), 1000 * e.peak_per_gaussian());
        // A random background: 1 − α per pixel beside each image, and a step's target image.
        let mut random = TrainConfig::preset(Preset::Cpu);
        random.background = Background::Random;
        let r = MemoryEstimate::new(&random, &inputs());
        assert_eq!(r.images, 50 * 400 * 400 * 16);
        assert_eq!(r.fixed - e.fixed, 160_000 * 12);
        assert_eq!(r.per_gaussian, e.per_gaussian);
    }

    #[test]
    fn a_gaussian_costs_at_least_its_parameters_and_adam_moments() {
        let e = MemoryEstimate::new(&TrainConfig::preset(Preset::Cpu), &inputs());
        // SH degree 3: 59 floats, three copies (value, m, v).
        assert!(e.per_gaussian >= 59 * 4 * 3, "{}", e.per_gaussian);
        assert_eq!(e.evolution_per_gaussian, 0);
    }

    #[test]
    fn the_evolution_buffer_and_memory_grow_with_frames_and_storage() {
        let mut c = TrainConfig::preset(Preset::Cpu);
        c.method = Method::Evogs;
        let dim = c.backbones.evogs.evo.dim() as u64;
        let e = MemoryEstimate::new(&c, &inputs());
        assert_eq!(e.evolution_per_gaussian, 2 * 50 * dim * 4);
        c.backbones.evogs.evo.storage = Storage::F16;
        assert_eq!(
            MemoryEstimate::new(&c, &inputs()).evolution_per_gaussian,
            2 * 50 * dim * 2
        );
        c.backbones.evogs.evo.history = HistoryMode::Requery;
        assert_eq!(
            MemoryEstimate::new(&c, &inputs()).evolution_per_gaussian,
            50 * dim * 2
        );
        let fewer = MemoryInputs {
            frames: 10,
            ..inputs()
        };
        assert_eq!(
            MemoryEstimate::new(&c, &fewer).evolution_per_gaussian,
            10 * dim * 2
        );
    }

    #[test]
    fn writing_a_checkpoint_holds_a_steps_buffers_and_the_serialised_copies() {
        let mut c = TrainConfig::preset(Preset::Cpu);
        let base = MemoryEstimate::new(&c, &inputs());
        // Baseline: the checkpoint's tensors (parameters, two Adam moments and 7 statistics)
        // and the file they are serialised into, two copies.
        let kept = 59 * 4 * 3 + 7 * 4;
        assert_eq!(base.checkpoint_per_gaussian, 2 * kept);
        assert_eq!(base.render, 160_000 * BYTES_PER_PIXEL);
        c.method = Method::Evogs;
        let e = MemoryEstimate::new(&c, &inputs());
        let evolution = e.evolution_per_gaussian;
        // EvoGS on lego's 50 frames: its state's one copy is the larger file.
        assert!(evolution > 2 * kept);
        assert_eq!(e.checkpoint_per_gaussian, evolution);
        // The step's buffers stay allocated while the checkpoint is written: the peak is both.
        for n in [0, 1_000, 100_000, 1_000_000] {
            let step = e.fixed + e.per_gaussian * n as u64;
            assert_eq!(e.at(n), e.images + step + evolution * n as u64, "{n}");
        }
        assert_eq!(e.peak_per_gaussian(), e.per_gaussian + evolution);
    }

    #[test]
    fn a_limit_caps_the_count_below_the_peak() {
        let mut c = TrainConfig::preset(Preset::Cpu);
        for method in [Method::Baseline, Method::Evogs] {
            c.method = method;
            let e = MemoryEstimate::new(&c, &inputs());
            for target in [0usize, 1, 777, 12_345, 250_000, 3_000_000] {
                for slack in [0, 1, e.peak_per_gaussian() / 2] {
                    let limit = e.at(target) + slack;
                    let n = e.max_gaussians(limit).unwrap();
                    assert!(e.at(n) <= limit, "{method:?} {target} {slack}");
                    assert!(e.at(n + 1) > limit, "{method:?} {target} {slack}: {n}");
                }
            }
        }
    }

    #[test]
    fn a_limit_becomes_the_largest_count_that_fits() {
        let e = MemoryEstimate::new(&TrainConfig::preset(Preset::Cpu), &inputs());
        let n = e
            .max_gaussians(e.at(12_345) + e.peak_per_gaussian() - 1)
            .unwrap();
        assert_eq!(n, 12_345);
        assert!(e.at(n) <= e.at(12_345));
        assert_eq!(e.max_gaussians(e.at(0) - 1), None);
        assert_eq!(e.max_gaussians(e.at(0)), Some(0));
    }

    #[test]
    fn byte_counts_parse_with_binary_suffixes() {
        assert_eq!(parse_bytes("1000").unwrap(), 1000);
        assert_eq!(parse_bytes("8G").unwrap(), 8 << 30);
        assert_eq!(parse_bytes("512M").unwrap(), 512 << 20);
        assert_eq!(parse_bytes("64k").unwrap(), 64 << 10);
        assert_eq!(parse_bytes("1.5GiB").unwrap(), 3 << 29);
        assert_eq!(parse_bytes("2 TB").unwrap(), 2 << 40);
        for bad in ["", "G", "-1G", "8X", "0", "1e3", "nanG"] {
            assert!(parse_bytes(bad).is_err(), "{bad}");
        }
        assert_eq!(human_bytes(512), "512 B");
        assert_eq!(human_bytes(3 << 29), "1.5 GiB");
    }
}
