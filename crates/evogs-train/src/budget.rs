//! Time budgets: a run that trains for a given number of seconds instead of a given number of
//! iterations, its whole schedule following the budget (DESIGN §7.7).
//!
//! A run's schedule is written in iterations (`TrainConfig`: warm-up, SH steps, lr decays,
//! densification window and interval, opacity resets), scaled to the run's nominal length `N`
//! by [`TrainConfig::with_iterations`](crate::TrainConfig::with_iterations). Under a budget of `B` seconds a step does not advance
//! the schedule by one iteration: it is placed at the **schedule iteration** `⌈N · s / B⌉`,
//! where `s` is the budget spent when the step is predicted to end (spent so far plus the
//! estimated cost of a step). The trainer runs every schedule event between the previous step's
//! schedule iteration and this one ([`crate::Trainer::step_to`]), so nothing is skipped when a
//! step spans several schedule iterations and nothing repeats when several steps share one.
//! A step advances the schedule by at most [`MAX_PACE`] schedule iterations: a run's first
//! steps can cost ~9× its later ones (the `dnerf` preset's 10 000 initial Gaussians at their
//! initial size), and mapped by time alone they passed the warm-up in 37 steps of a 180 CPU-s
//! jumpingjacks run (against 160 in a run of the same length by iterations), after which the
//! baseline never densified (DESIGN §7.7). `N` is therefore best near the number of steps the
//! budget allows (at least half of it); where the schedule still lags when the budget ends,
//! the last step takes the rest (all its events happen; recorded as `lagged`).
//! The last step is the one after which another would not fit in the budget; it is placed at
//! `N`, so the schedule ends (lr fully decayed, densification window closed) when the budget is
//! spent, whatever the machine's speed. Steps before it stay below `N` (the last iteration does
//! no optimiser step, as in 3DGS).
//!
//! [`Pacer`] is that mapping, a pure function of the readings it is given (tested with made-up
//! readings); [`BudgetClock`] says which clock the run reads: the process's CPU time (the
//! default: on a machine shared with other jobs it is what the run itself used) or wall time.
//! The budget counts the training loop — steps, densification, the log and the periodic
//! checkpoints — and not the data loading, the final outputs, or what a caller does between
//! steps (`evogs bench`'s curve evaluations).

use serde::{Deserialize, Serialize};
use strum::{Display, EnumString, IntoStaticStr, VariantNames};

use evogs_backbones::OneWord;

use crate::error::{TrainError, unknown};

/// The clock a time budget is measured on (`--budget-clock`).
#[derive(EnumString, Display, IntoStaticStr, VariantNames)]
#[strum(serialize_all = "lowercase", parse_err_ty = TrainError, parse_err_fn = unknown::<Self>)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BudgetClock {
    /// CPU time of the whole process (user + system, summed over its threads): the work the run
    /// did, whatever else shares the machine. With T threads a budget of B CPU-seconds lasts
    /// about B / T seconds of wall time.
    #[default]
    Cpu,
    /// Wall-clock time: what a user waits, but on a shared machine it depends on the load.
    Wall,
}

impl OneWord for BudgetClock {
    const FIELD: &'static str = "budget.clock";
    const NOUN: &'static str = "budget clock";
}

/// A run's time budget (`--time-budget`, `--budget-clock`), recorded in `config.json`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TimeBudget {
    /// Seconds of training on [`TimeBudget::clock`].
    pub seconds: f64,
    /// The clock.
    pub clock: BudgetClock,
}

impl TimeBudget {
    /// Checks the budget's range.
    pub fn validate(&self) -> Result<(), TrainError> {
        if !(self.seconds.is_finite() && self.seconds > 0.0) {
            return Err(TrainError::config(
                "budget.seconds",
                format!("{}: must be finite and positive", self.seconds),
            ));
        }
        Ok(())
    }

    /// "180 CPU-seconds" / "180 wall-clock seconds".
    pub fn describe(&self) -> String {
        match self.clock {
            BudgetClock::Cpu => format!("{} CPU-seconds", self.seconds),
            BudgetClock::Wall => format!("{} wall-clock seconds", self.seconds),
        }
    }
}

/// Parses a duration: seconds as a number with an optional unit `s`, `m` or `h`, or a sum of
/// such parts (`180`, `180s`, `2.5m`, `1h`, `2m30s`). Positive and finite.
pub fn parse_duration(text: &str) -> Result<f64, String> {
    let bad = || format!("`{text}`: expected a positive duration such as 180s, 3m, 2m30s or 1h");
    let t = text.trim();
    if t.is_empty() {
        return Err(bad());
    }
    let mut total = 0.0;
    let mut rest = t;
    while !rest.is_empty() {
        let end = rest
            .find(|c: char| !(c.is_ascii_digit() || c == '.'))
            .unwrap_or(rest.len());
        let number: f64 = rest[..end].parse().map_err(|_| bad())?;
        rest = &rest[end..];
        let unit = rest.chars().next();
        let factor = match unit {
            None => 1.0,
            Some('s') => 1.0,
            Some('m') => 60.0,
            Some('h') => 3600.0,
            Some(_) => return Err(bad()),
        };
        if unit.is_none() && total > 0.0 {
            // "2m30": a unitless part only alone.
            return Err(bad());
        }
        rest = unit.map_or(rest, |u| &rest[u.len_utf8()..]);
        total += number * factor;
    }
    if total.is_finite() && total > 0.0 {
        Ok(total)
    } else {
        Err(bad())
    }
}

/// Where a budget run stands: [`Pacer`]'s state, recorded in each checkpoint so that a resumed
/// run continues from it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BudgetProgress {
    /// The schedule iteration of the last step (0 before the first).
    pub schedule_iteration: u64,
    /// Seconds of the budget spent.
    pub spent_seconds: f64,
    /// The budget spent when the last step started (`None` before the run's first step).
    pub step_started: Option<f64>,
    /// The estimated cost of a step, seconds (an exponential average of the steps' costs).
    pub step_seconds: f64,
    /// Whether the last step was the run's last.
    pub finished: bool,
    /// Schedule iterations the run's last step took beyond [`MAX_PACE`] (0 unless the schedule
    /// lagged behind the budget: more than `MAX_PACE` schedule iterations per step were needed).
    #[serde(default)]
    pub lagged: u64,
}

impl BudgetProgress {
    /// A run that has not started.
    pub const START: BudgetProgress = BudgetProgress {
        schedule_iteration: 0,
        spent_seconds: 0.0,
        step_started: None,
        step_seconds: 0.0,
        finished: false,
        lagged: 0,
    };
}

/// What the next step of a budget run is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Pace {
    /// Its schedule iteration (1..=N).
    pub schedule_iteration: u64,
    /// Whether it is the run's last (then its schedule iteration is N).
    pub last: bool,
}

/// The most schedule iterations one step advances the schedule by.
pub const MAX_PACE: u64 = 2;

/// Weight of the latest step in the estimated cost of a step.
const STEP_COST_WEIGHT: f64 = 0.2;

/// Maps the budget spent to schedule iterations (module doc).
#[derive(Clone, Debug)]
pub struct Pacer {
    budget: f64,
    iterations: u64,
    progress: BudgetProgress,
}

impl Pacer {
    /// A pacer for a budget of `budget` seconds over a schedule of `iterations` iterations,
    /// continuing from `progress` ([`BudgetProgress::START`] for a new run).
    pub fn new(budget: f64, iterations: u64, progress: BudgetProgress) -> Self {
        Self {
            budget,
            iterations: iterations.max(1),
            progress,
        }
    }

    /// The next step, given the budget `spent` (seconds) before it; `None` when the run's last
    /// step has been taken.
    pub fn next(&mut self, spent: f64) -> Option<Pace> {
        let p = &mut self.progress;
        if p.finished || p.schedule_iteration >= self.iterations {
            p.finished = true;
            return None;
        }
        if let Some(started) = p.step_started {
            let cost = (spent - started).max(0.0);
            p.step_seconds = if p.step_seconds > 0.0 {
                (1.0 - STEP_COST_WEIGHT) * p.step_seconds + STEP_COST_WEIGHT * cost
            } else {
                cost
            };
        }
        p.step_started = Some(spent);
        p.spent_seconds = spent;
        let n = self.iterations;
        // Last when a step after this one would end beyond the budget (or it is spent).
        let last = spent >= self.budget || spent + 2.0 * p.step_seconds > self.budget || n == 1;
        let schedule_iteration = if last {
            p.lagged = n.saturating_sub(p.schedule_iteration + MAX_PACE);
            n
        } else {
            let at_end = (n as f64 * (spent + p.step_seconds) / self.budget).ceil();
            // Saturating float-to-int: negative or NaN readings give 0.
            (at_end as u64)
                .min(p.schedule_iteration + MAX_PACE)
                .clamp(p.schedule_iteration.max(1), n - 1)
        };
        p.schedule_iteration = schedule_iteration;
        p.finished = last;
        Some(Pace {
            schedule_iteration,
            last,
        })
    }

    /// Records the budget spent so far (after a step, before its checkpoint).
    pub fn record(&mut self, spent: f64) {
        self.progress.spent_seconds = spent;
    }

    /// The state to record (and to continue from).
    pub fn progress(&self) -> BudgetProgress {
        self.progress
    }

    /// The budget, seconds.
    pub fn budget(&self) -> f64 {
        self.budget
    }
}

/// A source of budget readings, seconds since an arbitrary origin. The run reads it before
/// each step and around its progress callback (whose time is not counted).
pub trait Clock {
    /// Seconds now.
    fn seconds(&mut self) -> Result<f64, TrainError>;
}

/// Wall-clock time ([`BudgetClock::Wall`]).
#[derive(Debug)]
pub struct WallClock(std::time::Instant);

impl Default for WallClock {
    fn default() -> Self {
        Self(std::time::Instant::now())
    }
}

impl Clock for WallClock {
    fn seconds(&mut self) -> Result<f64, TrainError> {
        Ok(self.0.elapsed().as_secs_f64())
    }
}

/// The process's CPU time ([`BudgetClock::Cpu`]): `CLOCK_PROCESS_CPUTIME_ID`, user + system of
/// every thread the process ran, exited ones included.
#[derive(Debug, Default)]
pub struct CpuClock;

impl Clock for CpuClock {
    #[cfg(unix)]
    fn seconds(&mut self) -> Result<f64, TrainError> {
        let mut t = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: clock_gettime writes one `timespec` through the pointer, which points to a
        // live, aligned, writable `timespec` on this stack frame; it keeps no reference to it.
        let rc = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut t) };
        if rc != 0 {
            return Err(TrainError::config(
                "budget.clock",
                format!(
                    "cpu: the process CPU clock is unreadable ({}); use wall",
                    std::io::Error::last_os_error()
                ),
            ));
        }
        Ok(t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9)
    }

    #[cfg(not(unix))]
    fn seconds(&mut self) -> Result<f64, TrainError> {
        Err(TrainError::config(
            "budget.clock",
            "cpu: no process CPU clock on this platform; use wall",
        ))
    }
}

/// The clock `kind` names.
pub fn clock_of(kind: BudgetClock) -> Box<dyn Clock> {
    match kind {
        BudgetClock::Cpu => Box::new(CpuClock),
        BudgetClock::Wall => Box::new(WallClock::default()),
    }
}

/// What `train_metrics.json` records of a budget run.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BudgetSummary {
    /// The budget and its clock.
    #[serde(flatten)]
    pub budget: TimeBudget,
    /// Seconds of the budget the run spent (all its processes).
    pub spent_seconds: f64,
    /// The schedule iteration reached (N when the run finished its budget).
    pub schedule_iteration: u64,
    /// Schedule iterations the last step took beyond [`MAX_PACE`] ([`BudgetProgress::lagged`]).
    #[serde(default)]
    pub lagged: u64,
}

impl BudgetSummary {
    /// The summary of a run with `budget` at `progress`.
    pub fn new(budget: TimeBudget, progress: &BudgetProgress) -> Self {
        Self {
            budget,
            spent_seconds: progress.spent_seconds,
            schedule_iteration: progress.schedule_iteration,
            lagged: progress.lagged,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Steps of `cost` seconds each from `progress`: the paces handed out.
    fn run(pacer: &mut Pacer, mut spent: f64, cost: impl Fn(usize) -> f64) -> Vec<Pace> {
        let mut paces = Vec::new();
        while let Some(p) = pacer.next(spent) {
            spent += cost(paces.len());
            paces.push(p);
            assert!(paces.len() < 1_000_000);
        }
        paces
    }

    #[test]
    fn steps_of_equal_cost_fill_the_budget_and_end_the_schedule() {
        // 1 s steps, 100 s budget, schedule of 150: 100 steps ending at 100 s.
        let mut pacer = Pacer::new(100.0, 150, BudgetProgress::START);
        let paces = run(&mut pacer, 0.0, |_| 1.0);
        assert_eq!(paces.len(), 100, "the 100th step ends at 100 s");
        let last = paces.last().unwrap();
        assert_eq!(
            *last,
            Pace {
                schedule_iteration: 150,
                last: true
            }
        );
        assert!(
            paces[..99]
                .iter()
                .all(|p| !p.last && p.schedule_iteration < 150)
        );
        // Positions rise at 1.5 per step: step k (from 0) ends at k + 1 s of 100.
        for (k, p) in paces[1..99].iter().enumerate() {
            let want = (1.5 * (k as f64 + 2.0)).ceil() as u64;
            assert_eq!(p.schedule_iteration, want, "step {}", k + 1);
        }
        assert!(
            paces
                .windows(2)
                .all(|w| w[0].schedule_iteration <= w[1].schedule_iteration)
        );
        assert_eq!(pacer.next(1e9), None);
        assert!(pacer.progress().finished);
        assert_eq!(pacer.progress().lagged, 0);
    }

    #[test]
    fn fast_steps_share_schedule_iterations_and_slow_ones_advance_at_most_max_pace() {
        // 1 000 steps of 0.01 s in a 10 s budget over a schedule of 100: positions repeat.
        let mut fast = Pacer::new(10.0, 100, BudgetProgress::START);
        let paces = run(&mut fast, 0.0, |_| 0.01);
        assert!((995..=1_000).contains(&paces.len()), "{}", paces.len());
        assert_eq!(paces.last().unwrap().schedule_iteration, 100);
        let distinct: std::collections::BTreeSet<u64> =
            paces.iter().map(|p| p.schedule_iteration).collect();
        assert_eq!(distinct, (1..=100).collect());
        // 10 steps of 1 s in a 10 s budget over a schedule of 12 000: time alone would place
        // step 2 at 2 400; a step advances at most MAX_PACE, and the last takes the rest.
        let mut slow = Pacer::new(10.0, 12_000, BudgetProgress::START);
        let paces = run(&mut slow, 0.0, |_| 1.0);
        let at: Vec<u64> = paces.iter().map(|p| p.schedule_iteration).collect();
        assert_eq!(at, [1, 3, 5, 7, 9, 11, 13, 15, 17, 12_000]);
        assert_eq!(slow.progress().lagged, 12_000 - 17 - MAX_PACE);
        // An expensive start (10 steps of 1 s, then 0.1 s) is held to MAX_PACE, then the
        // schedule follows the budget again and ends with it, without lag.
        let mut start = Pacer::new(100.0, 1_000, BudgetProgress::START);
        let cost = |k: usize| if k < 10 { 1.0 } else { 0.1 };
        let paces = run(&mut start, 0.0, cost);
        assert_eq!(paces[9].schedule_iteration, 19);
        let advances = paces
            .windows(2)
            .map(|w| w[1].schedule_iteration - w[0].schedule_iteration);
        assert!(
            advances
                .clone()
                .take(paces.len() - 2)
                .all(|a| a <= MAX_PACE)
        );
        assert_eq!(paces.last().unwrap().schedule_iteration, 1_000);
        assert_eq!(start.progress().lagged, 0);
    }

    #[test]
    fn a_run_ends_within_the_budget_when_step_costs_vary() {
        for seed in 0..20u64 {
            let budget = 50.0;
            let mut pacer = Pacer::new(budget, 600, BudgetProgress::START);
            // Costs between 0.05 and 0.15 s, a fixed pseudo-random sequence.
            let cost = |k: usize| {
                let x = (k as u64 + 1)
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(seed);
                0.05 + 0.1 * ((x >> 33) as f64 / (1u64 << 31) as f64)
            };
            let paces = run(&mut pacer, 0.0, cost);
            let spent: f64 = (0..paces.len()).map(cost).sum();
            // Within two of the largest steps of the budget, either way.
            assert!((spent - budget).abs() <= 0.3, "seed {seed}: {spent}");
            assert_eq!(paces.last().unwrap().schedule_iteration, 600);
            assert_eq!(pacer.progress().lagged, 0);
        }
    }

    #[test]
    fn a_spent_budget_takes_one_last_step() {
        let mut pacer = Pacer::new(5.0, 300, BudgetProgress::START);
        assert_eq!(
            pacer.next(7.0),
            Some(Pace {
                schedule_iteration: 300,
                last: true
            })
        );
        assert_eq!(pacer.next(8.0), None);
        let mut one = Pacer::new(5.0, 1, BudgetProgress::START);
        assert_eq!(
            one.next(0.0),
            Some(Pace {
                schedule_iteration: 1,
                last: true
            })
        );
    }

    #[test]
    fn a_pacer_continued_from_its_progress_hands_out_the_same_steps() {
        let cost = |k: usize| 0.1 + 0.01 * (k % 7) as f64;
        let mut whole = Pacer::new(20.0, 200, BudgetProgress::START);
        let all = run(&mut whole, 0.0, cost);
        let mut first = Pacer::new(20.0, 200, BudgetProgress::START);
        let mut spent = 0.0;
        let mut head = Vec::new();
        for k in 0..40 {
            head.push(first.next(spent).unwrap());
            spent += cost(k);
        }
        let saved = first.progress();
        let mut second = Pacer::new(20.0, 200, saved);
        let mut tail = Vec::new();
        while let Some(p) = second.next(spent) {
            spent += cost(40 + tail.len());
            tail.push(p);
        }
        head.extend(tail);
        assert_eq!(head, all);
    }

    #[test]
    fn durations_parse_and_bad_ones_say_what_is_expected() {
        for (text, s) in [
            ("180", 180.0),
            ("180s", 180.0),
            ("3m", 180.0),
            ("2m30s", 150.0),
            ("1h", 3600.0),
            ("0.5s", 0.5),
        ] {
            assert_eq!(parse_duration(text), Ok(s), "{text}");
        }
        for text in ["", "0", "0s", "-5s", "abc", "3x", "2m30", "s", "1e400"] {
            let e = parse_duration(text).unwrap_err();
            assert!(e.contains("expected a positive duration"), "{text}: {e}");
        }
    }

    #[test]
    fn budgets_validate_and_clocks_spell_alike() {
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = TimeBudget {
                seconds: bad,
                clock: BudgetClock::Cpu,
            }
            .validate()
            .unwrap_err()
            .to_string();
            assert!(e.contains("budget.seconds"), "{e}");
        }
        assert_eq!("wall".parse::<BudgetClock>().unwrap(), BudgetClock::Wall);
        let e = "moon".parse::<BudgetClock>().unwrap_err().to_string();
        assert_eq!(
            e,
            "invalid setting `budget.clock`: unknown budget clock `moon`; expected cpu or wall"
        );
        assert_eq!(serde_json::to_string(&BudgetClock::Cpu).unwrap(), "\"cpu\"");
    }

    #[test]
    fn the_cpu_clock_counts_this_process_work() {
        let mut c = CpuClock;
        let a = c.seconds().unwrap();
        let mut x = 0u64;
        for i in 0..2_000_000u64 {
            x = x.wrapping_add(std::hint::black_box(i * i));
        }
        std::hint::black_box(x);
        assert!(c.seconds().unwrap() > a);
    }
}
