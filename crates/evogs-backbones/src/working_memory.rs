//! What a backbone holds in a training step besides its parameters, for the trainer's memory
//! estimate (`evogs_train::memory`): the network's activations kept for the backward, its
//! inputs' gradients, and EvoGS's evolution state, per Gaussian row and whatever the Gaussians.
//!
//! What it is not: a measurement. Each figure models the buffers a backbone keeps from its
//! settings (layer widths, encodings, K neighbours, frames); `results/memory.md` compares the
//! whole estimate with measured peaks. It lives here so that the trainer names no backbone: a new
//! backbone adds its arm below.

use crate::choice::{BackboneKind, BackboneRun, Method};
use crate::scgs::EvolutionOn;

/// Bytes of an f32.
const F32: u64 = 4;

/// The working memory of a backbone in a training step (bytes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WorkingBytes {
    /// Per Gaussian: the network's activations kept for the backward and its inputs' gradients.
    pub per_row: u64,
    /// Per Gaussian: EvoGS's buffer and per-frame memory (0 for a baseline, and for EvoGS(SC-GS)
    /// with its state on the control points).
    pub evolution_per_row: u64,
    /// Whatever the Gaussians: SC-GS's control-point network activations (two evaluations per
    /// step: the step's time and ARAP's partner), and EvoGS(SC-GS)'s state on its control points.
    pub fixed: u64,
}

impl BackboneRun<'_> {
    /// The working memory of the backbone this run asks for over `frames` training times.
    pub fn working_bytes(&self, frames: usize) -> WorkingBytes {
        let net = self.net;
        let per_row = |values: usize| F32.saturating_mul(values as u64);
        let scgs = &self.settings.scgs;
        // SC-GS: the canonical mean kept for the backward, K neighbours (index and distance), the
        // skinned row and its gradient; and the control points' network, twice a step. Counted
        // only for SC-GS, whose settings are range-checked only when it is the backbone
        // (saturating besides: a `config.json` edited by hand reaches here).
        let skinning = || 3usize.saturating_add(scgs.neighbours.saturating_mul(2)) + 2 * 10;
        let controls = || {
            let input = 3 * (1 + 2 * scgs.xyz_freqs.min(64)) + (1 + 2 * scgs.t_freqs.min(64));
            let row = scgs
                .width
                .saturating_mul(scgs.depth)
                .saturating_add(2 * input + 14);
            per_row(scgs.control_points.saturating_mul(row)).saturating_mul(2)
        };
        match (self.method, self.kind) {
            (Method::Baseline, BackboneKind::D3dgs) => {
                // Encoded position and time, every hidden layer, the output; the positions and
                // the input gradient.
                let input = 3 * (1 + 2 * net.xyz_freqs) + (1 + 2 * net.t_freqs);
                let layers = net.width * net.depth + 10;
                WorkingBytes {
                    per_row: per_row(2 * input + layers + 3),
                    ..WorkingBytes::default()
                }
            }
            (Method::Baseline, BackboneKind::FourDgs) => WorkingBytes {
                // Plane features and the small decoder's layers.
                per_row: per_row(2 * 64 + net.width * 2 + 10),
                ..WorkingBytes::default()
            },
            (Method::Baseline, BackboneKind::Grid4d) => WorkingBytes {
                per_row: per_row(grid4d_row(net.width, 10)),
                ..WorkingBytes::default()
            },
            (Method::Baseline, BackboneKind::Scgs) => WorkingBytes {
                per_row: per_row(skinning()),
                evolution_per_row: 0,
                fixed: controls(),
            },
            (Method::Evogs, kind) => {
                let s = &self.settings.evogs;
                let dim = s.evo.dim();
                let width = (net.width / 2).max(1);
                // The step (prediction, observation, gain, corrected state and their gradients).
                let step = 8 * dim;
                // The buffer (history `buffer` only) and the per-frame memory, as evo-state counts
                // them, for `rows` rows.
                let evolution = |rows: usize| {
                    (s.evo.buffer_bytes(rows, frames) as u64)
                        .saturating_add(s.evo.memory_bytes(rows, frames) as u64)
                };
                match kind {
                    BackboneKind::Scgs if scgs.evolution_on == EvolutionOn::Controls => {
                        WorkingBytes {
                            per_row: per_row(skinning()),
                            evolution_per_row: 0,
                            fixed: controls()
                                .saturating_add(per_row(scgs.control_points.saturating_mul(step)))
                                .saturating_add(evolution(scgs.control_points)),
                        }
                    }
                    BackboneKind::Scgs => WorkingBytes {
                        per_row: per_row(skinning() + step),
                        evolution_per_row: evolution(1),
                        fixed: controls(),
                    },
                    BackboneKind::Grid4d => WorkingBytes {
                        per_row: per_row(grid4d_row(width, dim) + step),
                        evolution_per_row: evolution(1),
                        fixed: 0,
                    },
                    BackboneKind::FourDgs => WorkingBytes {
                        per_row: per_row(2 * 64 + width * 2 + dim + step),
                        evolution_per_row: evolution(1),
                        fixed: 0,
                    },
                    BackboneKind::D3dgs => {
                        let planes = 3 * s.triplane_channels * s.triplane_resolutions.len();
                        let input = planes + s.bspline_width;
                        WorkingBytes {
                            per_row: per_row(2 * input + width * s.hidden_layers + dim + step),
                            evolution_per_row: evolution(1),
                            fixed: 0,
                        }
                    }
                }
            }
        }
    }
}

/// f32 values per Gaussian a Grid4D field of decoder `width` and `output` values keeps for its
/// backward: the hash features (16 · 2 spatial, 3 · 32 · 2 temporal) and their gradients, the
/// attention and temporal activations and their product's gradient, inputs, warp and output.
fn grid4d_row(width: usize, output: usize) -> usize {
    let features = 16 * 2 + 3 * 32 * 2;
    2 * features + 4 * width + 3 + 4 + 7 + output
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{EvoSettings, Grid4dLr, NetSettings, ScgsSettings};

    /// EvoGS(SC-GS)'s evolution state costs per Gaussian where it lives on the Gaussians, and
    /// a fixed M rows where it lives on the control points; a baseline keeps none.
    #[test]
    fn the_evolution_state_is_counted_where_it_lives() {
        let net = NetSettings {
            width: 64,
            depth: 8,
            skip_after: Some(4),
            xyz_freqs: 10,
            t_freqs: 6,
            init: crate::NetInit::Torch,
        };
        let run = |method, evolution_on, scgs: &ScgsSettings| {
            let settings = crate::BackboneSettings {
                evogs: EvoSettings::default(),
                scgs: ScgsSettings {
                    evolution_on,
                    ..*scgs
                },
            };
            BackboneRun {
                method,
                kind: BackboneKind::Scgs,
                net: &net,
                settings: &settings,
                half_extent: 1.3,
                seed: 0,
                grid4d_log2_table: 8,
                grid4d_lr: Grid4dLr {
                    position_init: 1.6e-4,
                    position_final: 1.6e-6,
                    delay_mult: 0.01,
                    max_steps: 100,
                    scale: 1.0,
                },
            }
            .working_bytes(150)
        };
        let s = ScgsSettings::default();
        let on_gaussians = run(Method::Evogs, EvolutionOn::Gaussians, &s);
        let on_controls = run(Method::Evogs, EvolutionOn::Controls, &s);
        let baseline = run(Method::Baseline, EvolutionOn::Controls, &s);
        let evo = EvoSettings::default().evo;
        let per_row = evo.buffer_bytes(1, 150) + evo.memory_bytes(1, 150);
        assert_eq!(on_gaussians.evolution_per_row, per_row as u64);
        assert_eq!(on_controls.evolution_per_row, 0);
        assert!(
            on_controls.fixed >= baseline.fixed + (s.control_points * per_row) as u64,
            "{on_controls:?} {baseline:?}"
        );
        assert_eq!(baseline.evolution_per_row, 0);
        assert_eq!(on_controls.per_row, baseline.per_row);
    }
}
