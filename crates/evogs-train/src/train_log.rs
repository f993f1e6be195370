//! `train_log.jsonl`: one JSON line every `log_every` iterations (and at the end of each
//! process) with the interval's mean loss and PSNR, the Gaussian count, iterations/s, the
//! process's peak resident memory and, for EvoGS, statistics of the gain K of the interval's
//! last step. A resumed run keeps the lines up to its checkpoint and continues after them.
//!
//! A process that stops between two lines (`--stop-after`, a budget) writes an interim line
//! for the iterations so far, and its checkpoint keeps the interval's sums ([`LogInterval`]):
//! resumed from it, the run drops the interim line and adds the rest of the interval to those
//! sums, so its lines (iterations, loss, PSNR, Gaussians) are those of the same run made in one
//! process, bit for bit. The times (`seconds`, iterations/s, peak memory) are each process's.
//!
//! Written whole through a temporary file and a rename at every line (the file is small: one
//! line per interval), so a kill never leaves half a line. Not a metrics store: evaluation
//! scores are in `eval_<split>.json`.

use std::path::Path;
use std::time::Instant;

use serde::{Deserialize, Serialize};

use evogs_backbones::GainStats;

use crate::error::TrainError;
use crate::run_files::write_text;

/// One line of `train_log.jsonl`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LogLine {
    /// Iterations completed.
    pub iteration: u64,
    /// Training seconds up to this line, summed over the processes of the run.
    pub seconds: f64,
    /// Mean loss over the iterations since the previous line.
    pub loss: f64,
    /// Mean training-view PSNR (dB) over the same iterations.
    pub psnr: f64,
    /// Gaussians after `iteration`.
    pub gaussians: usize,
    /// Iterations per second over the interval.
    pub iterations_per_second: f64,
    /// Peak resident memory of the process so far (Linux `VmHWM`; `None` where unknown).
    pub peak_rss_bytes: Option<u64>,
    /// K of the interval's last step (EvoGS only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gain: Option<GainStats>,
}

/// The peak resident memory of this process (Linux `/proc/self/status` `VmHWM`).
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Reads `train_log.jsonl`; every problem names the file and the line.
pub fn read_log(path: &Path) -> Result<Vec<LogLine>, TrainError> {
    let text = std::fs::read_to_string(path).map_err(|e| TrainError::io(path, e))?;
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            serde_json::from_str(l)
                .map_err(|e| TrainError::file(path, format!("line {}: invalid JSON: {e}", i + 1)))
        })
        .collect()
}

/// The sums of the iterations since the last regular line, kept in a checkpoint
/// (`CheckpointMeta::log`) so that a resumed run's next line covers the whole interval.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LogInterval {
    /// Sum of the losses.
    pub loss_sum: f64,
    /// Sum of the training-view PSNRs.
    pub psnr_sum: f64,
    /// Iterations summed.
    pub count: u64,
}

/// The log of a run being trained: the lines so far and the current interval.
pub struct TrainLog {
    lines: Vec<LogLine>,
    every: u64,
    interval: LogInterval,
    /// Iterations of this process in the interval, and when it started for this process (the
    /// speed is this process's).
    timed: u64,
    interval_start: Instant,
    seconds_before: f64,
}

impl TrainLog {
    /// A log writing a line every `every` iterations, continuing the lines of `path` up to
    /// `iteration` (a resumed run; lines past its checkpoint are dropped) or starting empty.
    /// `carried` is the interval the checkpoint kept: with it, an interim line (one not at a
    /// multiple of `every`) at the end of the kept lines is dropped and the interval continues
    /// from those sums. Without it (a checkpoint written before it was kept) the interval starts
    /// empty.
    pub fn open(
        path: &Path,
        every: u64,
        iteration: u64,
        carried: Option<LogInterval>,
    ) -> Result<Self, TrainError> {
        let every = every.max(1);
        let mut lines = if iteration > 0 && path.is_file() {
            read_log(path)?
        } else {
            Vec::new()
        };
        lines.retain(|l| l.iteration <= iteration);
        // The run's time counts the interim line's process too.
        let seconds_before = lines.last().map_or(0.0, |l| l.seconds);
        if carried.is_some()
            && lines
                .last()
                .is_some_and(|l| !l.iteration.is_multiple_of(every))
        {
            lines.pop();
        }
        Ok(Self {
            lines,
            every,
            interval: carried.unwrap_or_default(),
            timed: 0,
            interval_start: Instant::now(),
            seconds_before,
        })
    }

    /// The sums of the interval since the last regular line (for the checkpoint).
    pub fn interval(&self) -> LogInterval {
        self.interval
    }

    /// The lines so far.
    pub fn lines(&self) -> &[LogLine] {
        &self.lines
    }

    /// Adds one iteration; at a multiple of `every` writes the line (the whole file,
    /// atomically) to `path` and starts the next interval; when `last` (the process's last
    /// iteration) and not at such a multiple, writes an interim line and keeps the interval's
    /// sums (module docs).
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &mut self,
        path: &Path,
        iteration: u64,
        loss: f64,
        psnr: f64,
        gaussians: usize,
        gain: Option<GainStats>,
        last: bool,
    ) -> Result<(), TrainError> {
        self.interval.loss_sum += loss;
        self.interval.psnr_sum += psnr;
        self.interval.count += 1;
        self.timed += 1;
        let regular = iteration.is_multiple_of(self.every);
        if !(regular || last) {
            return Ok(());
        }
        let elapsed = self.interval_start.elapsed().as_secs_f64();
        let seconds = self.seconds_before + elapsed;
        let n = self.interval.count as f64;
        self.lines.push(LogLine {
            iteration,
            seconds,
            loss: self.interval.loss_sum / n,
            psnr: self.interval.psnr_sum / n,
            gaussians,
            iterations_per_second: self.timed as f64 / elapsed.max(1e-9),
            peak_rss_bytes: peak_rss_bytes(),
            gain,
        });
        if regular {
            self.interval = LogInterval::default();
            self.timed = 0;
            self.interval_start = Instant::now();
            self.seconds_before = seconds;
        }
        let mut text = String::new();
        for line in &self.lines {
            let json = serde_json::to_string(line)
                .map_err(|e| TrainError::file(path, format!("cannot encode JSON: {e}")))?;
            text.push_str(&json);
            text.push('\n');
        }
        write_text(path, &text)
    }
}

#[cfg(test)]
mod tests {
    use super::LogInterval;

    /// A checkpoint keeps the interval's sums as JSON: each must come back bit for bit, or a
    /// resumed run's next line (and its final checkpoint) differs in its last bits from the
    /// run made in one process (serde_json's default parser can be 1 ulp off; the workspace
    /// turns on its `float_roundtrip`).
    #[test]
    fn interval_sums_survive_json_bit_for_bit() {
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        for _ in 0..20_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            // Sums of losses and PSNRs: positive, from tiny to thousands.
            let v = f64::from_bits(x).abs() % 5_000.0;
            if !v.is_finite() {
                continue;
            }
            let i = LogInterval {
                loss_sum: v,
                psnr_sum: v * 37.0 + 1e-9,
                count: x % 1000,
            };
            let back: LogInterval =
                serde_json::from_str(&serde_json::to_string(&i).unwrap()).unwrap();
            assert_eq!(back.loss_sum.to_bits(), i.loss_sum.to_bits(), "{i:?}");
            assert_eq!(back.psnr_sum.to_bits(), i.psnr_sum.to_bits(), "{i:?}");
        }
    }
}
