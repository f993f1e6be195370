//! The choice of backbone: the method and backbone a run names (`--method`, `--backbone`, in
//! `config.json`) and the one function that builds it ([`make_backbone`]) from what a run hands
//! every backbone ([`BackboneRun`]).
//!
//! A new backbone is a [`BackboneKind`] variant (its one-word spelling is what the command line
//! parses), its module in this crate and its arm in [`make_backbone`]; nothing in the trainer
//! names a backbone (ARCHITECTURE.md §5).

use serde::{Deserialize, Serialize};
use strum::{Display, EnumString, IntoStaticStr, VariantNames};

use crate::backbone::Backbone;
use crate::d3dgs::{D3dgsBackbone, NetSettings};
use crate::error::BackboneError;
use crate::evo_backbone::{EvoBackbone, observation_config, unsized_state};
use crate::evo_settings::EvoSettings;
use crate::grid4d_backbone::{Grid4dBackbone, Grid4dLr, Grid4dRun};
use crate::grid4d_phi::Grid4dPhi;
use crate::hex_backbone::HexBackbone;
use crate::hex_phi::HexPhi;
use crate::one_word::{OneWord, unknown};
use crate::scgs::control_evo::ScgsControlEvo;
use crate::scgs::phi::ScgsPhi;
use crate::scgs::{EvolutionOn, ScgsBackbone, ScgsSettings};

/// Every backbone's own settings, as a run records them (`TrainConfig` flattens them into
/// `config.json`, so each is a top-level key there: `evogs`, `scgs`). A backbone with settings of
/// its own adds its field here; the trainer only carries this struct.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BackboneSettings {
    /// EvoGS's switches and Φ's shape (read when the method is EvoGS; recorded for every run).
    #[serde(default)]
    pub evogs: EvoSettings,
    /// SC-GS's control points and their network (read when the backbone is SC-GS; recorded for
    /// every run; runs written before it existed read SC-GS's defaults).
    #[serde(default)]
    pub scgs: ScgsSettings,
}

impl BackboneSettings {
    /// Checks the settings the run of `method` on `kind` reads (the others are recorded, not
    /// used, so not checked).
    pub fn validate(&self, method: Method, kind: BackboneKind) -> Result<(), BackboneError> {
        if method == Method::Evogs {
            self.evogs.validate()?;
        }
        if kind == BackboneKind::Scgs {
            self.scgs.validate()?;
        }
        Ok(())
    }
}

/// The deformation method (`--method`).
#[derive(EnumString, Display, IntoStaticStr, VariantNames)]
#[strum(serialize_all = "lowercase", parse_err_ty = BackboneError, parse_err_fn = unknown::<Self>)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// The backbone's own deformation network alone (D-3DGS, 4DGaussians, Grid4D, SC-GS); the
    /// default.
    #[default]
    Baseline,
    /// EvoGS(backbone): Φ + evolution state + Ψ (settings in [`EvoSettings`]; Φ is the tri-plane
    /// network for d3dgs, the backbone's own field at half width for 4dgs and grid4d).
    Evogs,
}

impl OneWord for Method {
    const FIELD: &'static str = "method";
}

/// The deformation backbone (`--backbone`).
#[derive(EnumString, Display, IntoStaticStr, VariantNames)]
#[strum(serialize_all = "lowercase", parse_err_ty = BackboneError, parse_err_fn = unknown::<Self>)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum BackboneKind {
    /// Deformable-3D-Gaussians' deformation MLP ([`D3dgsBackbone`]).
    #[default]
    #[serde(rename = "d3dgs")]
    D3dgs,
    /// 4DGaussians' HexPlane field ([`HexBackbone`]).
    #[serde(rename = "4dgs")]
    #[strum(serialize = "4dgs")]
    FourDgs,
    /// Grid4D's 4D decomposed hash-grid field ([`Grid4dBackbone`]).
    #[serde(rename = "grid4d")]
    Grid4d,
    /// SC-GS's sparse control points with linear blend skinning ([`ScgsBackbone`]).
    #[serde(rename = "scgs")]
    Scgs,
}

impl OneWord for BackboneKind {
    const FIELD: &'static str = "backbone";
}

impl BackboneKind {
    /// The method the backbone comes from, as its paper names it (`D-3DGS`, `4DGaussians`,
    /// `Grid4D`, `SC-GS`).
    pub fn paper_name(self) -> &'static str {
        match self {
            BackboneKind::D3dgs => "D-3DGS",
            BackboneKind::FourDgs => "4DGaussians",
            BackboneKind::Grid4d => "Grid4D",
            BackboneKind::Scgs => "SC-GS",
        }
    }
}

impl Method {
    /// What a run of this method on `backbone` is called in tables and captions: the backbone's
    /// paper name for the baseline (`SC-GS`), `EvoGS(SC-GS)` for EvoGS on it.
    pub fn label(self, backbone: BackboneKind) -> String {
        match self {
            Method::Baseline => backbone.paper_name().to_string(),
            Method::Evogs => format!("EvoGS({})", backbone.paper_name()),
        }
    }
}

/// What a run hands the backbone it builds: the choice, every backbone's settings, the initial
/// cube, the seed, and Grid4D's table size and schedules (the trainer's `TrainConfig::backbone_run`
/// fills it from the run's config).
#[derive(Clone, Copy, Debug)]
pub struct BackboneRun<'a> {
    /// Baseline or EvoGS.
    pub method: Method,
    /// The backbone.
    pub kind: BackboneKind,
    /// The D-3DGS network's shape (its width also sizes Grid4D's decoder and EvoGS's Φ).
    pub net: &'a NetSettings,
    /// Every backbone's own settings (each reads its own).
    pub settings: &'a BackboneSettings,
    /// Half extent `h` of the initial cube `[-h, h]³` (the fields' boxes).
    pub half_extent: f32,
    /// The run's seed.
    pub seed: u64,
    /// `log2` of the most entries of a Grid4D table level ([`Grid4dRun::log2_table`]).
    pub grid4d_log2_table: u32,
    /// Grid4D's learning rates.
    pub grid4d_lr: Grid4dLr,
}

impl BackboneRun<'_> {
    /// What the Grid4D backbone (and EvoGS(Grid4D)'s Φ) takes of the run.
    pub fn grid4d(&self) -> Grid4dRun {
        Grid4dRun {
            width: self.net.width,
            log2_table: self.grid4d_log2_table,
            half_extent: self.half_extent,
            lr: self.grid4d_lr,
            seed: self.seed,
        }
    }
}

/// The floats in the parameters of the backbone `run` asks for (what [`Backbone::params`] of
/// [`make_backbone`]'s result holds), computed from the settings without allocating the
/// networks, with checked arithmetic: what a memory estimate reads before anything is
/// allocated. (Ψ, a few hundred values whatever the settings, is built to be counted.)
pub fn parameter_count(run: &BackboneRun<'_>) -> Result<usize, BackboneError> {
    let (evogs, h, seed) = (&run.settings.evogs, run.half_extent, run.seed);
    let own = match (run.method, run.kind) {
        (Method::Baseline, BackboneKind::D3dgs) => {
            D3dgsBackbone::config(run.net, seed).param_count(tiny_nn::DeformNet::OUTPUT)?
        }
        (Method::Baseline, BackboneKind::FourDgs) => HexBackbone::config(h, seed).param_count()?,
        (Method::Baseline, BackboneKind::Grid4d) => {
            Grid4dBackbone::config(&run.grid4d()).param_count()?
        }
        (_, BackboneKind::Scgs) => crate::scgs::ScgsParams::param_count(&run.settings.scgs, seed)?,
        (Method::Evogs, BackboneKind::D3dgs) => {
            observation_config(evogs, run.net.width, h, seed).param_count()?
        }
        (Method::Evogs, BackboneKind::FourDgs) => HexPhi::config(evogs, h, seed).param_count()?,
        (Method::Evogs, BackboneKind::Grid4d) => {
            Grid4dPhi::config(&run.grid4d(), evogs).param_count()?
        }
    };
    let psi = match run.method {
        Method::Baseline => 0,
        Method::Evogs => {
            evogs.validate()?;
            unsized_state(evogs.evo, seed)?.psi().mlp().param_count()
        }
    };
    own.checked_add(psi)
        .ok_or_else(|| BackboneError::config("net", "too many parameters"))
}

/// The backbone a run asks for, initialised from its seed.
pub fn make_backbone(run: &BackboneRun<'_>) -> Result<Box<dyn Backbone>, BackboneError> {
    let (evogs, h, seed) = (&run.settings.evogs, run.half_extent, run.seed);
    Ok(match (run.method, run.kind) {
        (Method::Baseline, BackboneKind::D3dgs) => {
            Box::new(D3dgsBackbone::new(run.net, seed ^ 0xD3D6_5000)?)
        }
        (Method::Baseline, BackboneKind::FourDgs) => Box::new(HexBackbone::new(h, seed)?),
        (Method::Baseline, BackboneKind::Grid4d) => Box::new(Grid4dBackbone::new(&run.grid4d())?),
        (Method::Baseline, BackboneKind::Scgs) => {
            Box::new(ScgsBackbone::new(&run.settings.scgs, h, seed)?)
        }
        (Method::Evogs, BackboneKind::D3dgs) => {
            Box::new(EvoBackbone::new(evogs, run.net.width, h, seed)?)
        }
        (Method::Evogs, BackboneKind::FourDgs) => Box::new(EvoBackbone::with_phi(
            evogs,
            seed,
            HexPhi::new(evogs, h, seed)?,
        )?),
        (Method::Evogs, BackboneKind::Grid4d) => Box::new(EvoBackbone::with_phi(
            evogs,
            seed,
            Grid4dPhi::new(&run.grid4d(), evogs)?,
        )?),
        (Method::Evogs, BackboneKind::Scgs) => match run.settings.scgs.evolution_on {
            EvolutionOn::Gaussians => Box::new(EvoBackbone::with_phi(
                evogs,
                seed,
                ScgsPhi::new(&run.settings.scgs, evogs, h, seed)?,
            )?),
            EvolutionOn::Controls => {
                Box::new(ScgsControlEvo::new(&run.settings.scgs, evogs, h, seed)?)
            }
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use splat_core::Layout;

    /// The tests' small SC-GS settings beside `evogs`.
    fn settings(evogs: EvoSettings) -> BackboneSettings {
        BackboneSettings { evogs, scgs: SCGS }
    }

    const SCGS: ScgsSettings = ScgsSettings {
        control_points: 8,
        neighbours: 3,
        width: 16,
        depth: 2,
        xyz_freqs: 2,
        t_freqs: 2,
        arap_weight: 1e-4,
        position_lr_scale: 0.0,
        follow_densify: false,
        placement: crate::scgs::Placement::Canonical,
        evolution_on: EvolutionOn::Gaussians,
    };

    fn run<'a>(
        method: Method,
        kind: BackboneKind,
        net: &'a NetSettings,
        settings: &'a BackboneSettings,
    ) -> BackboneRun<'a> {
        BackboneRun {
            method,
            kind,
            net,
            settings,
            half_extent: 1.3,
            seed: 7,
            grid4d_log2_table: 8,
            grid4d_lr: Grid4dLr {
                position_init: 1.6e-4,
                position_final: 1.6e-6,
                delay_mult: 0.01,
                max_steps: 100,
                scale: 1.0,
            },
        }
    }

    /// Every method with every backbone builds, with the name and row layout it stands for: a
    /// baseline deforms geometry only, EvoGS the components of its settings (all five but with
    /// 4DGaussians' and SC-GS's Φ, which deform geometry only and refuse the others).
    #[test]
    fn every_choice_builds_its_backbone() {
        let net = NetSettings {
            width: 16,
            depth: 2,
            skip_after: None,
            xyz_freqs: 2,
            t_freqs: 2,
            init: crate::NetInit::Torch,
        };
        for name in BackboneKind::VARIANTS {
            let kind: BackboneKind = name.parse().unwrap();
            let plain = settings(EvoSettings::default());
            let b = make_backbone(&run(Method::Baseline, kind, &net, &plain)).unwrap();
            assert_eq!(b.name(), kind.to_string());
            assert_eq!(b.layout(), Layout::GEOMETRY, "{kind}");
            assert!(b.state().is_none(), "{kind}");
            for layout in [Layout::GEOMETRY, Layout::ALL] {
                let mut evogs = EvoSettings::default();
                evogs.evo.layout = layout;
                match make_backbone(&run(Method::Evogs, kind, &net, &settings(evogs))) {
                    Ok(e) => {
                        assert_eq!(e.name(), "evogs");
                        assert_eq!(e.layout(), layout, "{kind}");
                        assert!(e.state().is_some(), "{kind}");
                    }
                    Err(e) => {
                        assert_eq!(layout, Layout::ALL, "{kind}");
                        assert!(
                            matches!(kind, BackboneKind::FourDgs | BackboneKind::Scgs),
                            "{kind}"
                        );
                        assert!(e.to_string().contains("scale only"), "{e}");
                    }
                }
            }
        }
    }

    /// [`parameter_count`] (read before anything is allocated) is the parameter count of the
    /// backbone [`make_backbone`] builds, for every method, backbone and SC-GS state placement,
    /// at two network shapes; sizes that overflow are errors.
    #[test]
    fn the_parameter_count_is_the_built_backbones() {
        for (width, depth, skip_after) in [(16, 2, None), (24, 6, Some(3))] {
            let net = NetSettings {
                width,
                depth,
                skip_after,
                xyz_freqs: 2,
                t_freqs: 2,
                init: crate::NetInit::Torch,
            };
            for name in BackboneKind::VARIANTS {
                let kind: BackboneKind = name.parse().unwrap();
                for method in [Method::Baseline, Method::Evogs] {
                    for evolution_on in [EvolutionOn::Gaussians, EvolutionOn::Controls] {
                        let both = BackboneSettings {
                            evogs: EvoSettings::default(),
                            scgs: ScgsSettings {
                                width,
                                depth,
                                evolution_on,
                                ..SCGS
                            },
                        };
                        let r = run(method, kind, &net, &both);
                        let built: usize = make_backbone(&r)
                            .unwrap()
                            .params()
                            .iter()
                            .map(|(_, p)| p.len())
                            .sum();
                        assert_eq!(parameter_count(&r).unwrap(), built, "{method} {kind}");
                    }
                }
            }
        }
        let huge = NetSettings {
            width: usize::MAX / 4,
            depth: 2,
            skip_after: None,
            xyz_freqs: 2,
            t_freqs: 2,
            init: crate::NetInit::Torch,
        };
        let plain = settings(EvoSettings::default());
        let r = run(Method::Baseline, BackboneKind::D3dgs, &huge, &plain);
        assert!(parameter_count(&r).is_err());
    }

    /// Captions name the method as the papers do, so that EvoGS on D-3DGS does not read like
    /// the D-3DGS baseline.
    #[test]
    fn labels_name_the_method_on_its_backbone() {
        assert_eq!(Method::Baseline.label(BackboneKind::D3dgs), "D-3DGS");
        assert_eq!(Method::Evogs.label(BackboneKind::D3dgs), "EvoGS(D-3DGS)");
        assert_eq!(Method::Evogs.label(BackboneKind::Scgs), "EvoGS(SC-GS)");
        assert_eq!(Method::Baseline.label(BackboneKind::FourDgs), "4DGaussians");
    }

    /// The one-word spellings, and the one message for a word that spells none.
    #[test]
    fn methods_and_backbones_parse_from_one_word() {
        assert_eq!(
            "4dgs".parse::<BackboneKind>().unwrap(),
            BackboneKind::FourDgs
        );
        assert_eq!("evogs".parse::<Method>().unwrap(), Method::Evogs);
        let e = "nope".parse::<BackboneKind>().unwrap_err().to_string();
        assert_eq!(
            e,
            "invalid setting `backbone`: unknown backbone `nope`; expected d3dgs, 4dgs, grid4d or scgs"
        );
        let e = "x".parse::<Method>().unwrap_err().to_string();
        assert_eq!(
            e,
            "invalid setting `method`: unknown method `x`; expected baseline or evogs"
        );
    }
}
