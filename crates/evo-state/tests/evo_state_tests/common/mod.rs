//! Helpers shared by the integration tests.
#![allow(dead_code)]

use evo_state::{EvoConfig, EvoState, Frames, Layout, Step};
use std::fmt::Write;

/// Position-only layout (D = 3).
pub fn position_only() -> Layout {
    Layout {
        position: true,
        rotation: false,
        scale: false,
        opacity: false,
        colour: false,
    }
}

pub fn uniform_frames(count: usize) -> Frames {
    Frames::new(
        (0..count)
            .map(|k| k as f32 / (count - 1).max(1) as f32)
            .collect(),
    )
    .unwrap()
}

pub fn state(config: EvoConfig, frames: Frames, rows: usize) -> EvoState {
    EvoState::new(config, frames, rows, 7).unwrap()
}

/// Runs a training step (forward + commit) at frame `k` and returns the step.
pub fn train(state: &mut EvoState, k: usize, z: &[f32]) -> Step {
    let t = state.frames().times()[k];
    let step = state.forward(t, z).unwrap();
    state.commit(&step).unwrap();
    step
}

fn list(v: &[f32]) -> String {
    // Values that round to zero print without a sign, so rounding noise cannot flip "-0".
    let items: Vec<String> = v
        .iter()
        .map(|&x| {
            if x.abs() < 5e-5 {
                "0.0000".into()
            } else {
                format!("{x:.4}")
            }
        })
        .collect();
    format!("[{}]", items.join(", "))
}

/// A human-readable trace line block of a step, for snapshots.
pub fn trace(state: &EvoState, step: &Step, z: &[f32]) -> String {
    let d = state.dim();
    let mut out = String::new();
    let h = step.history();
    let _ = writeln!(
        out,
        "t={:.4} frame={:?} h={} history={:?} gain={:?}",
        step.time(),
        step.frame(),
        h.len,
        h.frames(),
        match step.gains() {
            evo_state::Gains::Observation => "d=z".to_string(),
            evo_state::Gains::Uniform(k) => format!("uniform {k:.4}"),
            evo_state::Gains::Learned(_) => "learned".to_string(),
        }
    );
    for i in 0..step.rows() {
        let row = i * d..(i + 1) * d;
        let _ = write!(
            out,
            "  row {i}: z={} d~={}",
            list(&z[row.clone()]),
            list(&step.corrected()[row.clone()])
        );
        if let Some(p) = step.prior() {
            let _ = write!(out, " prior={}", list(&p[row.clone()]));
        }
        if let Some(m) = step.memory_next() {
            let _ = write!(out, " m={}", list(&m[row.clone()]));
        }
        if let Some(s) = step.stats() {
            let _ = write!(
                out,
                " |v2|={:.4} |v1|={:.4} theta={:.4}",
                s[i].speed_prev, s[i].speed_last, s[i].theta
            );
        }
        if let evo_state::Gains::Learned(k) = step.gains() {
            let _ = write!(out, " K={:.4}", k[i]);
        }
        let _ = writeln!(out);
    }
    out
}
