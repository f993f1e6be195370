//! Time budgets through [`train_with_clock`], on a clock of made-up readings (each reading
//! 0.5 s after the last): the run ends its schedule when the budget is spent, records the
//! budget, and a resumed budget run continues from its checkpoint's progress bit for bit.

use crate::common;

use evogs_train::budget::{BudgetClock, Clock, TimeBudget};
use evogs_train::run::{RunPaths, train_with_clock};
use evogs_train::{Preset, StepReport, TrainConfig, TrainError, TrainRequest, TrainSummary};

/// A clock that moves on by `step` seconds at every reading (exact in binary: 0.5).
struct Ticks {
    now: f64,
    step: f64,
}

impl Clock for Ticks {
    fn seconds(&mut self) -> Result<f64, TrainError> {
        self.now += self.step;
        Ok(self.now)
    }
}

fn ticks() -> Ticks {
    Ticks {
        now: 100.0,
        step: 0.5,
    }
}

const BUDGET: f64 = 30.0;

fn config() -> TrainConfig {
    let mut c = TrainConfig::preset(Preset::Tiny).with_iterations(40);
    c.init_points = 400;
    c.checkpoint_every = 7;
    c.budget = Some(TimeBudget {
        seconds: BUDGET,
        clock: BudgetClock::Cpu,
    });
    c
}

fn run(
    dir: &std::path::Path,
    out: &str,
    resume: bool,
    stop_after: Option<u64>,
) -> (TrainSummary, Vec<StepReport>) {
    let request = TrainRequest {
        data: dir.join("scene"),
        out: dir.join(out),
        config: config(),
        resume,
        stop_after,
        resume_backend: None,
        resume_net_backend: None,
    };
    let mut reports = Vec::new();
    let mut clock = ticks();
    let summary =
        train_with_clock(&request, Some(&mut clock), &mut |r, _| reports.push(*r)).unwrap();
    (summary, reports)
}

#[test]
fn a_budget_run_ends_its_schedule_when_the_budget_is_spent() {
    let dir = tempfile::tempdir().unwrap();
    common::write_scene(&dir.path().join("scene"));
    let (summary, reports) = run(dir.path(), "run", false, None);
    let c = config();
    // Each step costs 1 s on this clock (two readings; the callback's one is not counted), so
    // about 30 steps for a schedule of 40: each step spans ~1.3 schedule iterations.
    let budget = summary.budget.unwrap();
    assert_eq!(budget.budget, c.budget.unwrap());
    assert!(budget.spent_seconds <= BUDGET, "{}", budget.spent_seconds);
    assert!(
        budget.spent_seconds > BUDGET - 2.0,
        "{}",
        budget.spent_seconds
    );
    assert_eq!(summary.iteration, reports.len() as u64);
    assert!((25..=30).contains(&reports.len()), "{}", reports.len());
    // The schedule ends with the budget: the last step is at the schedule's end, past the lr
    // decays and the densification window, and only it.
    assert_eq!(budget.schedule_iteration, c.iterations);
    let last = reports.last().unwrap();
    assert!(last.last && last.schedule_iteration == c.iterations);
    assert!(c.iterations >= c.lr.position_max_steps && c.iterations >= c.densify.schedule.until);
    let before: Vec<&StepReport> = reports[..reports.len() - 1].iter().collect();
    assert!(
        before
            .iter()
            .all(|r| !r.last && r.schedule_iteration < c.iterations)
    );
    assert!(
        reports
            .windows(2)
            .all(|w| w[0].schedule_iteration < w[1].schedule_iteration)
    );
    // The schedule's steps and densification happened: the SH degree is up to the maximum and
    // the Gaussian count changed.
    let straight = TrainConfig {
        budget: None,
        ..config()
    };
    let (state, _, _) = evogs_train::run::read_checkpoint(
        &RunPaths::new(dir.path().join("run")).checkpoint(),
        &straight,
    )
    .unwrap();
    assert_eq!(state.active_sh(), c.sh_degree);
    assert!(reports.iter().any(|r| r.densified));
    // Recorded: the budget in config.json, budget spent and schedule reached in
    // train_metrics.json.
    let paths = RunPaths::new(dir.path().join("run"));
    let cfg: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(paths.config()).unwrap()).unwrap();
    assert_eq!(cfg["train"]["budget"]["seconds"], 30.0);
    assert_eq!(cfg["train"]["budget"]["clock"], "cpu");
    let metrics: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(paths.train_metrics()).unwrap()).unwrap();
    assert_eq!(metrics["budget"]["schedule_iteration"], 40);
    assert_eq!(metrics["budget"]["lagged"], 0);
    assert_eq!(metrics["budget"]["clock"], "cpu");
    assert_eq!(metrics["iteration"], reports.len());
}

#[test]
fn a_resumed_budget_run_continues_from_its_progress_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    common::write_scene(&dir.path().join("scene"));
    let (whole, all) = run(dir.path(), "straight", false, None);
    let (half, first) = run(dir.path(), "resumed", false, Some(12));
    assert_eq!(half.iteration, 12);
    assert!(half.budget.unwrap().spent_seconds < BUDGET / 2.0);
    let (rest, second) = run(dir.path(), "resumed", true, None);
    assert_eq!(second.first().unwrap().iteration, 13);
    assert_eq!(rest.iteration, whole.iteration);
    assert_eq!(rest.budget, whole.budget);
    let mut steps: Vec<(u64, u64, bool)> = first
        .iter()
        .chain(&second)
        .map(|r| (r.iteration, r.schedule_iteration, r.last))
        .collect();
    // The interruption's last step is marked last (its process ended there); nothing else is.
    steps[11].2 = false;
    let straight: Vec<(u64, u64, bool)> = all
        .iter()
        .map(|r| (r.iteration, r.schedule_iteration, r.last))
        .collect();
    assert_eq!(steps, straight);
    for file in [
        "checkpoint.safetensors",
        "deform.safetensors",
        "canonical.ply",
    ] {
        let a = std::fs::read(dir.path().join("straight").join(file)).unwrap();
        let b = std::fs::read(dir.path().join("resumed").join(file)).unwrap();
        assert!(a == b, "{file} differs");
    }
    // A finished budget run resumed does nothing more.
    let (again, none) = run(dir.path(), "resumed", true, None);
    assert!(none.is_empty());
    assert_eq!(again.iteration, whole.iteration);
    assert_eq!(again.budget, whole.budget);
}
