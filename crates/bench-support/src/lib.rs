//! `bench-support`: what the workspace's criterion benches share.
//!
//! What it is: [`CpuTime`], a criterion measurement of the process's CPU time, which is much less
//! disturbed than wall time when other jobs share a small machine, and [`clock_prefix`] to name
//! benchmark groups by the clock that measured them.
//!
//! What it is not: a benchmark itself, or anything a library links: benches take it as a
//! dev-dependency.

use std::time::Instant;

use criterion::measurement::{Measurement, ValueFormatter, WallTime};

static WALL: WallTime = WallTime;

/// CPU time of the whole process, summed over its threads (`/proc/self/task/*/schedstat`, ns),
/// optionally divided by rayon's thread count. Where `/proc` is absent it falls back to wall time.
#[derive(Clone, Copy, Debug)]
pub struct CpuTime {
    per_thread: bool,
}

impl CpuTime {
    /// CPU time divided by rayon's thread count: what the wall time would be on idle cores with
    /// perfect scaling. Comparable with wall-time figures.
    pub fn wall_equivalent() -> Self {
        Self { per_thread: true }
    }

    /// CPU time of all threads together (CPU-seconds of work).
    pub fn total() -> Self {
        Self { per_thread: false }
    }
}

fn process_cpu_ns() -> Option<u64> {
    let mut total = 0u64;
    for entry in std::fs::read_dir("/proc/self/task").ok()? {
        let path = entry.ok()?.path().join("schedstat");
        let text = std::fs::read_to_string(path).ok()?;
        total += text.split_whitespace().next()?.parse::<u64>().ok()?;
    }
    Some(total)
}

impl Measurement for CpuTime {
    type Intermediate = (Option<u64>, Instant);
    type Value = f64;

    fn start(&self) -> Self::Intermediate {
        (process_cpu_ns(), Instant::now())
    }

    fn end(&self, (cpu, wall): Self::Intermediate) -> f64 {
        match (cpu, process_cpu_ns()) {
            (Some(a), Some(b)) => {
                let ns = b.saturating_sub(a) as f64;
                if self.per_thread {
                    ns / rayon::current_num_threads() as f64
                } else {
                    ns
                }
            }
            _ => wall.elapsed().as_nanos() as f64,
        }
    }

    fn add(&self, a: &f64, b: &f64) -> f64 {
        a + b
    }

    fn zero(&self) -> f64 {
        0.0
    }

    fn to_f64(&self, v: &f64) -> f64 {
        *v
    }

    fn formatter(&self) -> &dyn ValueFormatter {
        WALL.formatter()
    }
}

/// Group-name prefix for a measurement: `"cpu/"` for [`CpuTime`], `""` for anything else.
pub fn clock_prefix<M: Measurement>() -> &'static str {
    if std::any::type_name::<M>() == std::any::type_name::<CpuTime>() {
        "cpu/"
    } else {
        ""
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cpu_time_counts_work_and_prefix_names_the_clock() {
        let m = CpuTime::total();
        let start = m.start();
        let mut x = 0u64;
        for i in 0..20_000_000u64 {
            x = std::hint::black_box(x.wrapping_mul(31).wrapping_add(i));
        }
        std::hint::black_box(x);
        assert!(m.end(start) > 0.0);
        assert_eq!(clock_prefix::<CpuTime>(), "cpu/");
        assert_eq!(clock_prefix::<WallTime>(), "");
    }
}
