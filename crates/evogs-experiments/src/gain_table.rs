//! The table of K's distribution that `evogs train --gain-report` prints: the run's
//! [`GainSummary`] (accumulated by the training core, saved in `train_metrics.json`) as text.

use std::fmt::Write as _;

use evogs_train::gain_report::{GainStats, GainSummary};

/// A plain-text table: all, moving, still, then one line per frame with samples.
pub fn gain_table(summary: &GainSummary) -> String {
    let mut out = String::from("gain K (gain-stage steps):\n");
    let _ = writeln!(
        out,
        "  {:>8} {:>10} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7}",
        "set", "samples", "mean", "std", "p5", "p25", "p50", "p75", "p95"
    );
    let mut line = |name: &str, s: &Option<GainStats>| {
        if let Some(s) = s {
            let _ = write!(
                out,
                "  {name:>8} {:>10} {:>7.4} {:>7.4}",
                s.samples, s.mean, s.std
            );
            for p in &s.percentiles {
                let _ = write!(out, " {p:>7.4}");
            }
            out.push('\n');
        }
    };
    line("all", &summary.all);
    line("moving", &summary.moving);
    line("still", &summary.still);
    for (k, s) in summary.per_frame.iter().enumerate() {
        line(&format!("frame {k}"), s);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stats(samples: u64, mean: f64) -> Option<GainStats> {
        Some(GainStats {
            samples,
            mean,
            std: 0.25,
            percentiles: vec![0.1, 0.2, 0.3, 0.4, 0.5],
        })
    }

    #[test]
    fn a_line_per_set_with_samples() {
        let summary = GainSummary {
            all: stats(3, 0.5),
            moving: stats(2, 0.75),
            still: None,
            per_frame: vec![None, stats(3, 0.5)],
        };
        let want = "gain K (gain-stage steps):\n\
            \x20      set    samples    mean     std      p5     p25     p50     p75     p95\n\
            \x20      all          3  0.5000  0.2500  0.1000  0.2000  0.3000  0.4000  0.5000\n\
            \x20   moving          2  0.7500  0.2500  0.1000  0.2000  0.3000  0.4000  0.5000\n\
            \x20  frame 1          3  0.5000  0.2500  0.1000  0.2000  0.3000  0.4000  0.5000\n";
        assert_eq!(gain_table(&summary), want);
    }
}
