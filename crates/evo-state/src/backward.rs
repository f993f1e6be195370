//! The backward pass: gradients of `L_render + λ1 L_sup + λ2 L_prior` with respect to the
//! observation z and to Ψ's parameters.

use rayon::prelude::*;

use crate::error::EvoError;
use crate::kernel::fin;
use crate::state::{CHUNK, EvoState};
use crate::step::{Backward, Gains, HistoryGrads, Losses, Step};

impl EvoState {
    /// Backward pass: from dL_render/dd̃ (`dl_dd`, N × D) and the (stop-gradient) opacities
    /// (N, activated), the gradients of `L_render + λ1 L_sup + λ2 L_prior` with respect to z
    /// and to Ψ's parameters, and, with history re-queried from Φ, to the observations at the
    /// history times ([`Backward::history`]). Ψ's inputs are constants; d̂ is a constant with
    /// the buffer and inside L_prior (stop-gradient).
    ///
    /// With g = dL_render/dd̃ + λ1·2/N·(d̃ - z):
    /// `dL/dz = K g - λ1·2/N·(d̃ - z) + λ2·2/N·sg(o)·(z - d̂)`, `dL/dK = Σ_j g_j (z_j - d̂_j)`,
    /// and re-queried `dL/dd̂ = (1 - K) g`, `dL/dz_k1 = (1 + s) dL/dd̂`, `dL/dz_k2 = -s dL/dd̂`.
    pub fn backward(
        &self,
        step: &Step,
        z: &[f32],
        dl_dd: &[f32],
        opacity: &[f32],
    ) -> Result<Backward, EvoError> {
        let mut out = Backward::default();
        self.backward_into(step, z, dl_dd, opacity, &mut out)?;
        Ok(out)
    }

    /// [`EvoState::backward`] into an existing [`Backward`], reusing its dz buffer.
    pub fn backward_into(
        &self,
        step: &Step,
        z: &[f32],
        dl_dd: &[f32],
        opacity: &[f32],
        out: &mut Backward,
    ) -> Result<(), EvoError> {
        let dim = self.dim();
        let n = step.rows;
        Self::check_len("observation z", z, n * dim)?;
        Self::check_len("render gradient dL/dd", dl_dd, n * dim)?;
        Self::check_len("opacity", opacity, n)?;
        Self::check_finite("observation z", z, dim)?;
        Self::check_finite("render gradient dL/dd", dl_dd, dim)?;
        Self::check_finite("opacity", opacity, 1)?;
        let Some(prior) = step.prior.as_deref() else {
            // d̃ = z: no EvoGS loss, identity Jacobian.
            out.dz.clear();
            out.dz.extend_from_slice(dl_dd);
            out.dpsi = None;
            out.history.clear();
            out.losses = Losses::default();
            return Ok(());
        };
        let inv_n = 1.0 / n.max(1) as f64;
        let l1 = self.config.lambda_sup as f64;
        let l2 = self.config.lambda_prior as f64;
        let learned = matches!(step.gains, Gains::Learned(_));
        let mut dz = std::mem::take(&mut out.dz);
        // Every element is written below.
        dz.resize(n * dim, 0.0);
        // dL/dK per Gaussian (used only with the learned gain).
        let mut dk = vec![0.0f32; n];
        // dL/dd̂ (re-queried history only; empty otherwise).
        let mut dprior = vec![0.0f64; if step.requeried { n * dim } else { 0 }];
        let prior_chunk = if step.requeried { CHUNK * dim } else { 1 };
        let mut dprior_chunks: Vec<&mut [f64]> = dprior.chunks_mut(prior_chunk).collect();
        dprior_chunks.resize_with(n.div_ceil(CHUNK), Default::default);
        let partial: Vec<(f64, f64)> = dz
            .par_chunks_mut(CHUNK * dim)
            .zip(dk.par_chunks_mut(CHUNK))
            .zip(dprior_chunks.into_par_iter())
            .enumerate()
            .map(|(c, ((dz, dk), dp))| {
                let (mut sup, mut pri) = (0.0f64, 0.0f64);
                for r in 0..dz.len() / dim {
                    let i = c * CHUNK + r;
                    let k = step.gains.at(i) as f64;
                    let op = opacity[i] as f64;
                    let mut dki = 0.0f64;
                    for j in 0..dim {
                        let e = i * dim + j;
                        let (zv, pv, dv) = (z[e] as f64, prior[e] as f64, step.corrected[e] as f64);
                        let res = dv - zv;
                        sup += res * res;
                        pri += op * (pv - zv) * (pv - zv);
                        let g = dl_dd[e] as f64 + l1 * 2.0 * inv_n * res;
                        dz[r * dim + j] =
                            fin(g * k - l1 * 2.0 * inv_n * res + l2 * 2.0 * inv_n * op * (zv - pv));
                        dki += g * (zv - pv);
                        if let Some(slot) = dp.get_mut(r * dim + j) {
                            *slot = (1.0 - k) * g;
                        }
                    }
                    dk[r] = fin(dki);
                }
                (sup, pri)
            })
            .collect();
        let (sup, pri) = partial
            .iter()
            .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        let losses = Losses {
            sup: sup * inv_n,
            prior: pri * inv_n,
        };
        let dpsi = match (learned, &step.psi_cache) {
            (true, Some(cache)) => Some(self.psi.backward(cache, &dk)?),
            _ => None,
        };
        let mut history = std::mem::take(&mut out.history);
        history.clear();
        if step.requeried {
            let s = step.prior_scale;
            let times = self.frames.times();
            for (&k, factor) in step.history.frames().iter().zip([1.0 + s, -s]) {
                let mut g = Vec::with_capacity(n * dim);
                g.par_extend(dprior.par_iter().map(|&v| fin(factor * v)));
                history.push(HistoryGrads {
                    time: times[k],
                    dz: g,
                });
            }
        }
        *out = Backward {
            dz,
            dpsi,
            history,
            losses,
        };
        Ok(())
    }
}
