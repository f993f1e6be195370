//! The backward pass: gradients of `L_render + λ1 L_sup + λ2 L_prior` with respect to the
//! observation z and to Ψ's parameters.

use rayon::prelude::*;

use crate::error::EvoError;
use crate::kernel::fin;
use crate::state::{CHUNK, EvoState};
use crate::step::{Backward, Gains, Losses, Step};

impl EvoState {
    /// Backward pass: from dL_render/dd̃ (`dl_dd`, N × D) and the (stop-gradient) opacities
    /// (N, activated), the gradients of `L_render + λ1 L_sup + λ2 L_prior` with respect to z
    /// and to Ψ's parameters. d̂ and Ψ's inputs are constants.
    pub fn backward(
        &self,
        step: &Step,
        z: &[f32],
        dl_dd: &[f32],
        opacity: &[f32],
    ) -> Result<Backward, EvoError> {
        let mut out = Backward {
            dz: Vec::new(),
            dpsi: None,
            losses: Losses::default(),
        };
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
        let partial: Vec<(f64, f64)> = dz
            .par_chunks_mut(CHUNK * dim)
            .zip(dk.par_chunks_mut(CHUNK))
            .enumerate()
            .map(|(c, (dz, dk))| {
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
        *out = Backward { dz, dpsi, losses };
        Ok(())
    }
}
