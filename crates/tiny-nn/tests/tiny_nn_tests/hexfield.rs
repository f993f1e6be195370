//! The 4DGaussians deformation field: composition, finite differences through every part,
//! regularisers added to the plane gradients, weights round trip, bad configurations.

use crate::common;

use common::{check_fd, dot, vals};
use tiny_nn::weights::{load, save};
use tiny_nn::{
    HEX_OUTPUT, HexDeformConfig, HexDeformNet, Parameters, PlaneCombine, PlaneRegulariser,
    Precision, TimeAxis, TriPlaneConfig,
};

fn small() -> HexDeformNet {
    let mut net = HexDeformNet::new(HexDeformConfig {
        hexplane: TriPlaneConfig::new(3, &[3, 5], PlaneCombine::Product)
            .bounds([-1.0, -1.0, 0.0], [1.0, 2.0, 1.0])
            .time(TimeAxis::new(4, -1.0, 1.0))
            .seed(4),
        width: 5,
        precision: Precision::F32,
        seed: 9,
    })
    .unwrap();
    // Planes away from 1 so that every plane's gradient is visible in the product.
    let n = net.hexplane.param_count();
    let planes: Vec<f32> = vals(n, 12, 0.4).iter().map(|v| 0.9 + v).collect();
    net.hexplane.set_params(&planes).unwrap();
    net
}

fn inputs(rows: usize) -> (Vec<f32>, Vec<f32>) {
    let p = vals(rows * 3, 30, 0.9)
        .chunks(3)
        .flat_map(|c| [c[0], 0.5 + 1.5 * c[1], 0.5 + 0.5 * c[2]])
        .collect();
    let t = vals(rows, 31, 0.5).iter().map(|v| 0.5 + v).collect();
    (p, t)
}

#[test]
fn output_is_the_heads_on_the_relu_of_the_feature_layer() {
    let net = small();
    let rows = 7;
    let (p, t) = inputs(rows);
    let (y, _) = net.forward(&p, &t, rows).unwrap();
    assert_eq!(y.len(), rows * HEX_OUTPUT);
    let x: Vec<f32> = p
        .chunks(3)
        .zip(&t)
        .flat_map(|(p, &t)| [p[0], p[1], p[2], t])
        .collect();
    let (f, _) = net.hexplane.forward(&x, rows).unwrap();
    let (h, _) = net.trunk.forward(&f, rows).unwrap();
    assert!(h.iter().all(|&v| v >= 0.0), "the shared ReLU");
    assert!(h.iter().any(|&v| v > 0.0));
    let mut col = 0;
    for (head, width) in net.heads.iter().zip([3, 4, 3]) {
        let (yh, _) = head.forward(&h, rows).unwrap();
        for r in 0..rows {
            assert_eq!(
                &y[r * HEX_OUTPUT + col..r * HEX_OUTPUT + col + width],
                &yh[r * width..(r + 1) * width]
            );
        }
        col += width;
    }
}

#[test]
fn gradients_match_finite_differences() {
    let net = small();
    let rows = 6;
    let (p, t) = inputs(rows);
    let c = vals(rows * HEX_OUTPUT, 41, 1.0);
    let (_, cache) = net.forward(&p, &t, rows).unwrap();
    let g = net.backward(&cache, &c).unwrap();
    let loss = |n: &HexDeformNet| dot(&n.forward(&p, &t, rows).unwrap().0, &c);
    let mut n2 = net.clone();
    let hp = net.hexplane.params().to_vec_f32();
    check_fd("HexPlane", &hp, &g.hexplane, 1e-2, 3e-3, |pp| {
        n2.hexplane.set_params(pp).unwrap();
        loss(&n2)
    });
    let mut n2 = net.clone();
    let tp = net.trunk.params().to_vec_f32();
    check_fd("feature layer", &tp, &g.trunk, 1e-3, 5e-3, |pp| {
        n2.trunk.set_params(pp).unwrap();
        loss(&n2)
    });
    for i in 0..3 {
        let mut n2 = net.clone();
        let hp = net.heads[i].params().to_vec_f32();
        check_fd(&format!("head {i}"), &hp, &g.heads[i], 1e-3, 5e-3, |pp| {
            n2.heads[i].set_params(pp).unwrap();
            loss(&n2)
        });
    }
    // The gradient of every part is non-trivial (the test could fail).
    for (name, v) in [("planes", &g.hexplane), ("trunk", &g.trunk)] {
        assert!(v.iter().any(|&x| x.abs() > 1e-4), "{name}: all zero");
    }
}

#[test]
fn regularise_adds_the_three_plane_terms() {
    let net = small();
    let rows = 3;
    let (p, t) = inputs(rows);
    let (_, cache) = net.forward(&p, &t, rows).unwrap();
    let c = vals(rows * HEX_OUTPUT, 5, 1.0);
    let g0 = net.backward(&cache, &c).unwrap();
    let mut g = g0.clone();
    let value = net.regularise(1e-4, 1e-2, 1e-4, &mut g).unwrap();
    let mut expect = g0.hexplane.clone();
    let mut total = 0.0;
    for (which, w) in [
        (PlaneRegulariser::SpaceSmoothness, 1e-4),
        (PlaneRegulariser::TimeSmoothness, 1e-2),
        (PlaneRegulariser::TimeL1, 1e-4),
    ] {
        total += net.hexplane.regularise(which, w, &mut expect).unwrap();
    }
    assert!(value > 0.0);
    assert_eq!(value, total);
    assert_eq!(g.hexplane, expect);
    assert_ne!(g.hexplane, g0.hexplane);
    assert_eq!(g.trunk, g0.trunk);
    let mut gz = g0.clone();
    assert_eq!(net.regularise(0.0, 0.0, 0.0, &mut gz).unwrap(), 0.0);
    assert_eq!(gz, g0);
}

#[test]
fn weights_round_trip_and_bad_configurations_are_errors() {
    let net = small();
    let names: Vec<String> = net.named_params().into_iter().map(|(n, _)| n).collect();
    assert_eq!(
        names,
        [
            "hexplane",
            "trunk",
            "head_position",
            "head_rotation",
            "head_scale"
        ]
    );
    let dir = std::env::temp_dir().join(format!("hexfield-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("w.safetensors");
    save(&path, &net).unwrap();
    let mut other = HexDeformNet::new(HexDeformConfig {
        hexplane: net.hexplane.config().clone().seed(77),
        width: 5,
        precision: Precision::F32,
        seed: 78,
    })
    .unwrap();
    load(&path, &mut other).unwrap();
    let (p, t) = inputs(4);
    assert_eq!(
        net.forward(&p, &t, 4).unwrap().0,
        other.forward(&p, &t, 4).unwrap().0
    );
    std::fs::remove_dir_all(&dir).unwrap();

    let base = HexDeformConfig::dnerf([-1.0; 3], [1.0; 3], 0);
    assert_eq!(base.hexplane.channels, 32);
    assert_eq!(base.hexplane.resolutions, [64, 128]);
    assert_eq!(base.hexplane.time.as_ref().unwrap().resolution, 25);
    for bad in [
        HexDeformConfig {
            hexplane: TriPlaneConfig::new(2, &[3], PlaneCombine::Product),
            ..base.clone()
        },
        HexDeformConfig {
            hexplane: TriPlaneConfig::new(2, &[3], PlaneCombine::Concat)
                .time(TimeAxis::new(3, 0.0, 1.0)),
            ..base.clone()
        },
        HexDeformConfig {
            width: 0,
            ..base.clone()
        },
    ] {
        assert!(HexDeformNet::new(bad).is_err());
    }
    let net = HexDeformNet::new(base).unwrap();
    assert!(net.forward(&[0.0; 3], &[0.5, 0.5], 1).is_err());
}
