//! Progress of a long step with a known count (views evaluated, frames rendered): a bar with its
//! rate and time left on a terminal (`indicatif`), one line every tenth of the way otherwise (a
//! log or CI reads those).

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
