//! Per-phase wall-clock timers of the training loop, printed at the end of a run and saved in
//! its metrics file.

use std::fmt;
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

/// The phases of one training iteration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// Frame choice and building the deformed Gaussians.
    Data,
    /// Deformation network forward.
    NetForward,
    /// Rasterizer forward.
    RasterForward,
    /// Loss and its image gradient (and the PSNR for the progress line).
    Loss,
    /// Rasterizer backward.
    RasterBackward,
    /// Deformation network backward.
    NetBackward,
    /// Densification statistics, plans and their application.
    Densify,
    /// Adam steps.
    Optimizer,
}

/// Accumulated seconds per phase.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PhaseTimes {
    /// [`Phase::Data`].
    pub data: f64,
    /// [`Phase::NetForward`].
    pub net_forward: f64,
    /// [`Phase::RasterForward`].
    pub raster_forward: f64,
    /// [`Phase::Loss`].
    pub loss: f64,
    /// [`Phase::RasterBackward`].
    pub raster_backward: f64,
    /// [`Phase::NetBackward`].
    pub net_backward: f64,
    /// [`Phase::Densify`].
    pub densify: f64,
    /// [`Phase::Optimizer`].
    pub optimizer: f64,
}

impl PhaseTimes {
    /// Adds the time since `start` to `phase` and returns now.
    pub fn lap(&mut self, phase: Phase, start: Instant) -> Instant {
        let now = Instant::now();
        *self.slot(phase) += now.duration_since(start).as_secs_f64();
        now
    }

    /// Adds a duration to `phase`.
    pub fn add(&mut self, phase: Phase, d: Duration) {
        *self.slot(phase) += d.as_secs_f64();
    }

    fn slot(&mut self, phase: Phase) -> &mut f64 {
        match phase {
            Phase::Data => &mut self.data,
            Phase::NetForward => &mut self.net_forward,
            Phase::RasterForward => &mut self.raster_forward,
            Phase::Loss => &mut self.loss,
            Phase::RasterBackward => &mut self.raster_backward,
            Phase::NetBackward => &mut self.net_backward,
            Phase::Densify => &mut self.densify,
            Phase::Optimizer => &mut self.optimizer,
        }
    }

    /// (name, seconds) of every phase.
    pub fn entries(&self) -> [(&'static str, f64); 8] {
        [
            ("data", self.data),
            ("network forward", self.net_forward),
            ("rasterizer forward", self.raster_forward),
            ("loss", self.loss),
            ("rasterizer backward", self.raster_backward),
            ("network backward", self.net_backward),
            ("densification", self.densify),
            ("optimizer", self.optimizer),
        ]
    }

    /// Sum over phases.
    pub fn total(&self) -> f64 {
        self.entries().iter().map(|e| e.1).sum()
    }
}

impl fmt::Display for PhaseTimes {
    /// One line per phase: seconds and share of the total.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let total = self.total().max(1e-12);
        for (name, s) in self.entries() {
            writeln!(f, "{name:>20}: {s:9.2} s  {:5.1} %", 100.0 * s / total)?;
        }
        write!(f, "{:>20}: {total:9.2} s", "total")
    }
}
