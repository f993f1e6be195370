//! Every network config's `param_count` (what a memory estimate reads before anything is
//! allocated) equals the parameters of the network it builds, and a size that overflows is an
//! error instead of a wrapped count.

use tiny_nn::{
    BSplineConfig, DeformConfig, DeformNet, Grid4dConfig, HashGridConfig, HexDeformConfig,
    HexDeformNet, Init, MlpConfig, ObservationConfig, ObservationNet, Parameters, PlaneCombine,
    Precision, TimeAxis, TriPlaneConfig,
};

/// Floats in every parameter buffer of `module`.
fn built(module: &impl Parameters) -> usize {
    module.named_params().iter().map(|(_, p)| p.len()).sum()
}

#[test]
fn mlps_with_and_without_a_skip() {
    for config in [
        MlpConfig::new(7, 16, 0, 3),
        MlpConfig::new(7, 16, 3, 3).skip_after(1),
        MlpConfig::new(63, 64, 8, 14).skip_after(4),
    ] {
        assert_eq!(
            config.param_count().unwrap(),
            config.clone().build().unwrap().param_count()
        );
    }
}

#[test]
fn encoders() {
    for t in [
        TriPlaneConfig::new(4, &[8, 16], PlaneCombine::Concat),
        TriPlaneConfig::new(3, &[5], PlaneCombine::Product).time(TimeAxis::new(7, -1.0, 1.0)),
    ] {
        assert_eq!(
            t.param_count().unwrap(),
            t.clone().build().unwrap().param_count()
        );
        assert_eq!(t.output_width(), t.clone().build().unwrap().output_width());
    }
    let b = BSplineConfig::new(9, 5);
    assert_eq!(
        b.param_count().unwrap(),
        b.clone().build().unwrap().param_count()
    );
    for log2_table in [4, 12] {
        let g = HashGridConfig::new(3, 5, 2, log2_table, 4.0, 40.0);
        assert_eq!(
            g.param_count().unwrap(),
            g.clone().build().unwrap().param_count()
        );
    }
}

#[test]
fn composite_networks() {
    let observation = ObservationConfig {
        triplane: TriPlaneConfig::new(4, &[8, 16], PlaneCombine::Concat),
        bspline: BSplineConfig::new(8, 6),
        width: 16,
        hidden_layers: 2,
        output: 10,
        precision: Precision::F16,
        seed: 3,
    };
    assert_eq!(
        observation.param_count().unwrap(),
        built(&ObservationNet::new(observation).unwrap())
    );
    let deform = DeformConfig {
        width: 32,
        depth: 4,
        skip_after: Some(2),
        xyz_freqs: 4,
        t_freqs: 3,
        init: Init::Torch,
        zero_heads: false,
        precision: Precision::F32,
        seed: 1,
    };
    for outputs in [DeformNet::OUTPUT, 14] {
        assert_eq!(
            deform.param_count(outputs).unwrap(),
            DeformNet::with_outputs(deform, outputs)
                .unwrap()
                .mlp
                .param_count()
        );
    }
    let hex = HexDeformConfig::dnerf([-1.0; 3], [1.0; 3], 5);
    assert_eq!(
        hex.param_count().unwrap(),
        built(&HexDeformNet::new(hex).unwrap())
    );
    let mut grid4d = Grid4dConfig::dnerf(1.6, 2);
    grid4d.spatial.log2_table = 10;
    grid4d.temporal.log2_table = 10;
    grid4d.depth = 2;
    assert_eq!(
        grid4d.param_count().unwrap(),
        built(&tiny_nn::Grid4dNet::new(grid4d).unwrap())
    );
}

#[test]
fn sizes_that_overflow_are_errors() {
    assert!(
        MlpConfig::new(3, usize::MAX / 2, 2, 3)
            .param_count()
            .is_err()
    );
    assert!(
        TriPlaneConfig::new(usize::MAX / 4, &[1 << 20], PlaneCombine::Concat)
            .param_count()
            .is_err()
    );
    assert!(BSplineConfig::new(usize::MAX / 2, 3).param_count().is_err());
}
