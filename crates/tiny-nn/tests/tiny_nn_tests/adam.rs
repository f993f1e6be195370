//! Adam: update against a hand-written f64 reference, the 3DGS schedule, row edits.

use tiny_nn::{Adam, ExponentialLr, LrSchedule, NnError, Precision, Store};

#[test]
fn updates_match_pytorch_adam_in_f64() -> Result<(), NnError> {
    let mut adam = Adam::new();
    adam.eps = 1e-8;
    let id = adam.add_group("w", 3, 1, LrSchedule::Constant(0.1))?;
    let mut p = Store::F32(vec![1.0, -2.0, 0.5]);
    let grads = [[0.3f32, -1.0, 0.0], [0.1, 2.0, -0.5], [-0.2, 0.5, 1e-3]];
    let (mut pr, mut m, mut v) = ([1.0f64, -2.0, 0.5], [0.0f64; 3], [0.0f64; 3]);
    for (t, g) in grads.iter().enumerate() {
        adam.step(id, t as i64, p.as_mut(), g)?;
        let t = (t + 1) as i32;
        for i in 0..3 {
            let gi = g[i] as f64;
            m[i] = 0.9 * m[i] + 0.1 * gi;
            v[i] = 0.999 * v[i] + 0.001 * gi * gi;
            let mh = m[i] / (1.0 - 0.9f64.powi(t));
            let vh = v[i] / (1.0 - 0.999f64.powi(t));
            pr[i] -= 0.1 * mh / (vh.sqrt() + 1e-8);
        }
    }
    for (a, b) in p.to_f32_vec().iter().zip(&pr) {
        assert!((*a as f64 - b).abs() < 1e-6, "{a} vs {b}");
    }
    assert_eq!(adam.group(id).step, 3);
    Ok(())
}

#[test]
fn exponential_schedule_matches_3dgs() {
    // 3DGS position lr: 1.6e-4 → 1.6e-6 over 30000 steps, delay_mult 0.01 (no delay steps).
    let e = ExponentialLr {
        lr_init: 1.6e-4,
        lr_final: 1.6e-6,
        delay_steps: 0,
        delay_mult: 0.01,
        max_steps: 30000,
    };
    assert!((e.at(0) - 1.6e-4).abs() < 1e-10);
    assert!((e.at(15000) - 1.6e-5).abs() < 1e-10); // geometric midpoint
    assert!((e.at(30000) - 1.6e-6).abs() < 1e-12);
    assert!((e.at(90000) - 1.6e-6).abs() < 1e-12);
    assert_eq!(e.at(-1), 0.0);
    let d = ExponentialLr {
        delay_steps: 100,
        ..e
    };
    assert!((d.at(0) - 0.01 * 1.6e-4).abs() < 1e-12);
    let mid = 0.01 + 0.99 * (std::f64::consts::FRAC_PI_4).sin();
    let want =
        mid * (1.6e-4f64.ln() * (1.0 - 50.0 / 30000.0) + 1.6e-6f64.ln() * 50.0 / 30000.0).exp();
    assert!((d.at(50) as f64 - want).abs() < 1e-10);
}

#[test]
fn reset_and_remap_rows() -> Result<(), NnError> {
    let mut adam = Adam::new();
    let id = adam.add_group("xyz", 9, 3, LrSchedule::Constant(1e-2))?;
    let mut p = Store::F32(vec![0.0; 9]);
    adam.step(
        id,
        0,
        p.as_mut(),
        &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0],
    )?;
    adam.reset_rows(id, &[1])?;
    let g = adam.group(id);
    assert_eq!(&g.m[3..6], &[0.0; 3]);
    assert_eq!(&g.v[3..6], &[0.0; 3]);
    assert!(g.m[0] != 0.0 && g.m[6] != 0.0);
    let m_row2 = g.m[6..9].to_vec();
    adam.remap_rows(id, &[Some(2), None, Some(0), Some(2)])?;
    let g = adam.group(id);
    assert_eq!(g.m.len(), 12);
    assert_eq!(&g.m[0..3], &m_row2[..]);
    assert_eq!(&g.m[3..6], &[0.0; 3]);
    assert_eq!(&g.m[9..12], &m_row2[..]);
    assert!(adam.reset_rows(id, &[4]).is_err());
    assert!(adam.remap_rows(id, &[Some(4)]).is_err());
    assert!(
        adam.add_group("bad", 10, 3, LrSchedule::Constant(1.0))
            .is_err()
    );
    let mut short = Store::F32(vec![0.0; 2]);
    assert!(adam.step(id, 1, short.as_mut(), &[0.0; 2]).is_err());
    Ok(())
}

#[test]
fn f16_parameters_saturate_and_count() -> Result<(), NnError> {
    let mut adam = Adam::new();
    let id = adam.add_group("h", 2, 1, LrSchedule::Constant(100.0))?;
    let (mut p, _) = Store::from_f32(Precision::F16, &[65500.0, 0.0]);
    let sat = adam.step(id, 0, p.as_mut(), &[-1.0, 1.0])?;
    assert_eq!(sat, 1);
    let v = p.to_f32_vec();
    assert_eq!(v[0], 65504.0);
    assert_eq!(v[1], -100.0);
    Ok(())
}

#[test]
fn adam_trains_the_gain_network_towards_a_target() -> Result<(), NnError> {
    use tiny_nn::{Activation, MlpConfig};
    let (d, n) = (10, 64);
    let mut psi = MlpConfig::new(d + 3, 32, 2, 1)
        .output_activation(Activation::Sigmoid)
        .seed(3)
        .build()?;
    let x: Vec<f32> = (0..n * (d + 3))
        .map(|i| ((i * 37 % 101) as f32 / 50.0) - 1.0)
        .collect();
    // Target K = 0.9 for rows with x[0] > 0, 0.1 otherwise.
    let target: Vec<f32> = (0..n)
        .map(|r| if x[r * (d + 3)] > 0.0 { 0.9 } else { 0.1 })
        .collect();
    let loss = |k: &[f32]| -> f32 {
        k.iter()
            .zip(&target)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f32>()
            / n as f32
    };
    let mut adam = Adam::new();
    let g = adam.add_group("psi", psi.param_count(), 1, LrSchedule::Constant(1e-2))?;
    let (k0, _) = psi.forward(&x, n)?;
    let l0 = loss(&k0);
    for it in 0..300 {
        let (k, cache) = psi.forward(&x, n)?;
        let dk: Vec<f32> = k
            .iter()
            .zip(&target)
            .map(|(a, b)| 2.0 * (a - b) / n as f32)
            .collect();
        let grads = psi.backward(&cache, &dk, false)?;
        adam.step(g, it, psi.params_mut(), &grads.params)?;
    }
    let (k1, _) = psi.forward(&x, n)?;
    let l1 = loss(&k1);
    assert!(l1 < 0.05 * l0, "loss {l0} -> {l1}");
    Ok(())
}
