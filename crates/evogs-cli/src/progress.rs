//! Progress of long work on stderr. [`Counted`]: a step with a known count (views evaluated,
//! frames rendered), a bar with its rate and time left on a terminal (`indicatif`), one line
//! every tenth of the way otherwise (a log or CI reads those). [`Spinner`]: a step of unknown
//! length (a COLMAP stage), a spinner with the time spent on a terminal, its line printed once
//! elsewhere. [`Steps`]: a run's schedule (bench), a bar on a terminal
//! only, beside the caller's lines.

use std::io::IsTerminal;

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};

/// A count of `total` things called `unit`, shown on stderr.
pub struct Counted {
    bar: ProgressBar,
    terminal: bool,
    done: u64,
    total: u64,
    unit: &'static str,
}

impl Counted {
    /// A bar (on a terminal) or tenth-of-the-way lines (elsewhere) for `total` `unit`s.
    pub fn new(total: usize, unit: &'static str) -> Result<Self> {
        let terminal = std::io::stderr().is_terminal();
        let total = total as u64;
        let bar = if terminal {
            ProgressBar::new(total)
        } else {
            ProgressBar::hidden()
        };
        bar.set_style(
            ProgressStyle::with_template(&format!(
                "{{bar:30}} {{pos}}/{{len}} {unit}s {{per_sec}} ETA {{eta}}"
            ))
            .context("progress bar template")?,
        );
        Ok(Self {
            bar,
            terminal,
            done: 0,
            total,
            unit,
        })
    }

    /// One more done.
    pub fn inc(&mut self) {
        self.done += 1;
        self.bar.inc(1);
        let every = (self.total / 10).max(1);
        if !self.terminal && (self.done.is_multiple_of(every) || self.done == self.total) {
            eprintln!("{} {}/{}", self.unit, self.done, self.total);
        }
    }

    /// Clears the bar.
    pub fn finish(self) {
        self.bar.finish_and_clear();
    }
}

/// A spinner with the time spent, for a step of unknown length: on a terminal the spinner shows
/// the step's line, elsewhere the line is printed once.
pub struct Spinner {
    bar: ProgressBar,
}

impl Spinner {
    /// A spinner showing `message` (off a terminal: `message` printed as a line).
    pub fn new(message: String) -> Self {
        let bar = if std::io::stderr().is_terminal() {
            let bar = ProgressBar::new_spinner();
            if let Ok(style) = ProgressStyle::with_template("{spinner} {msg} {elapsed}") {
                bar.set_style(style);
            }
            bar.enable_steady_tick(std::time::Duration::from_millis(120));
            bar
        } else {
            eprintln!("{message}");
            ProgressBar::hidden()
        };
        bar.set_message(message);
        Self { bar }
    }

    /// Clears the spinner.
    pub fn finish(self) {
        self.bar.finish_and_clear();
    }
}

/// A bar over a run's schedule (`schedule` iterations), with rate and time left; on a terminal
/// only, so that logs keep the caller's own lines.
pub struct Steps {
    bar: ProgressBar,
}

impl Steps {
    /// A bar of `schedule` steps labelled `label` (hidden off a terminal).
    pub fn new(schedule: u64, label: String) -> Result<Self> {
        let bar = if std::io::stderr().is_terminal() {
            ProgressBar::new(schedule)
        } else {
            ProgressBar::hidden()
        };
        bar.set_style(
            ProgressStyle::with_template(
                "{msg} {bar:30} {pos}/{len} schedule steps, {elapsed} spent, ETA {eta}",
            )
            .context("progress bar template")?,
        );
        bar.set_message(label);
        Ok(Self { bar })
    }

    /// The schedule iteration reached.
    pub fn set(&self, schedule_iteration: u64) {
        self.bar.set_position(schedule_iteration);
    }

    /// Prints `line` above the bar (or plainly off a terminal).
    pub fn println(&self, line: &str) {
        if self.bar.is_hidden() {
            eprintln!("{line}");
        } else {
            self.bar.println(line);
        }
    }

    /// Clears the bar.
    pub fn finish(self) {
        self.bar.finish_and_clear();
    }
}
