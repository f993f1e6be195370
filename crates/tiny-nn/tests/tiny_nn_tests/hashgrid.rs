//! Hash-grid encoder: level geometry, indexing, the f64 reference, f64 finite differences,
//! collisions, inputs outside the box, f16 storage and saturation, thread-count determinism.

// The f64 references index axes and corners by position, as the formulas are written.
#![allow(clippy::needless_range_loop)]

use crate::common;

use common::vals;
use proptest::prelude::*;
use tiny_nn::encoding::hashgrid::{MAX_LOG2_TABLE, PRIMES};
use tiny_nn::{HashGrid, HashGridConfig, Interpolation, Outside, Precision};

/// A small grid with dense and hashed levels (levels from 3 to 9 vertices per axis; tables of
/// at least 3^D and fewer than 9^D entries) over a box that is not the unit box.
fn small(dims: usize, interp: Interpolation, outside: Outside, seed: u64) -> HashGrid {
    let lo: Vec<f32> = (0..dims).map(|a| -1.0 + 0.5 * a as f32).collect();
    let hi: Vec<f32> = (0..dims).map(|a| 1.5 + 0.25 * a as f32).collect();
    let log2_table = [0, 3, 6, 8, 10][dims];
    let mut g = HashGridConfig::new(dims, 4, 3, log2_table, 3.0, 9.0)
        .bounds(&lo, &hi)
        .interpolation(interp)
        .outside(outside)
        .seed(seed)
        .build()
        .unwrap();
    // O(1) entries so that gradients with respect to inputs are not tiny.
    let t = vals(g.param_count(), seed + 100, 1.0);
    g.set_params(&t).unwrap();
    g
}

/// Inputs (rows × dims) inside the box, each coordinate at least `margin` (in cell units) away
/// from every cell wall of every level, so that a finite difference never crosses a wall.
fn inputs_off_walls(g: &HashGrid, rows: usize, seed: u64, margin: f32) -> Vec<f32> {
    let c = g.config();
    let d = c.dims;
    let mut out = Vec::new();
    let mut k = 0;
    while out.len() < rows * d {
        let cand = vals(d, seed * 1000 + k, 1.0);
        k += 1;
        let mut row = Vec::new();
        let mut ok = true;
        for a in 0..d {
            let u = 0.02 + 0.96 * (cand[a] + 1.0) * 0.5;
            for lv in g.levels() {
                let p = u * lv.scale[a];
                let f = p - p.floor();
                ok &= f > margin && f < 1.0 - margin;
            }
            row.push(c.box_min[a] + u * (c.box_max[a] - c.box_min[a]));
        }
        if ok {
            out.extend(row);
        }
    }
    out
}

fn table_f64(g: &HashGrid) -> Vec<f64> {
    g.params().to_vec_f32().iter().map(|&v| v as f64).collect()
}

/// `Σ c · reference(x)` over rows, in f64.
fn ref_loss(g: &HashGrid, table: &[f64], x: &[f64], c: &[f32]) -> f64 {
    let (d, w) = (g.dims(), g.output_width());
    x.chunks_exact(d)
        .enumerate()
        .map(|(i, row)| {
            g.reference_encode(table, row)
                .iter()
                .zip(&c[i * w..(i + 1) * w])
                .map(|(y, &ci)| y * ci as f64)
                .sum::<f64>()
        })
        .sum()
}

const INTERPS: [Interpolation; 2] = [Interpolation::Linear, Interpolation::Smoothstep];

#[test]
fn levels_follow_grid4d_geometry() {
    // Grid4D's D-NeRF configs (arguments/dnerf/*.py): canonical 16 levels 16 -> 2048, T = 2^19;
    // temporal xyt 32 levels [8, 8, 8] -> [32, 32, 16], T = 2^19; F = 2.
    let spatial = HashGridConfig::new(3, 16, 2, 19, 16.0, 2048.0)
        .build()
        .unwrap();
    let temporal = HashGridConfig::new(3, 32, 2, 19, 8.0, 32.0)
        .resolutions(&[8.0, 8.0, 8.0], &[32.0, 32.0, 16.0])
        .build()
        .unwrap();
    let mut text = String::new();
    for (name, g) in [("spatial", &spatial), ("temporal", &temporal)] {
        text += &format!("{name}: {} parameters\n", g.param_count());
        for (l, lv) in g.levels().iter().enumerate() {
            text += &format!(
                "  {l:2} scale {:9.3} {:9.3} {:9.3}  res {:5} {:5} {:5}  entries {:7} {}\n",
                lv.scale[0],
                lv.scale[1],
                lv.scale[2],
                lv.resolution[0],
                lv.resolution[1],
                lv.resolution[2],
                lv.entries,
                if lv.dense { "dense" } else { "hashed" }
            );
        }
    }
    insta::assert_snapshot!(text);
    let first = &spatial.levels()[0];
    assert_eq!(first.scale[..3], [15.0; 3]);
    assert_eq!(first.resolution[..3], [16; 3]);
    let last = spatial.levels().last().unwrap();
    assert!((last.scale[0] - 2047.0).abs() < 1e-2, "{}", last.scale[0]);
    let tl = temporal.levels().last().unwrap();
    assert!((tl.scale[0] - 31.0).abs() < 1e-3 && (tl.scale[2] - 15.0).abs() < 1e-3);
    // Every temporal level is dense (at most 32 · 32 · 16 vertices).
    assert!(temporal.levels().iter().all(|l| l.dense));
    let mut offset = 0;
    for lv in spatial.levels() {
        assert_eq!(lv.offset, offset);
        let vertices: u64 = lv.resolution[..3].iter().map(|&r| r as u64).product();
        assert_eq!(lv.dense, vertices <= 1 << 19);
        assert_eq!(lv.entries as u64, vertices.min(1 << 19));
        offset += lv.entries;
    }
    assert_eq!(spatial.param_count(), offset * 2);
}

#[test]
fn dense_levels_index_every_vertex_once_and_hashed_levels_use_the_primes() {
    let g = HashGridConfig::new(3, 3, 1, 9, 4.0, 12.0).build().unwrap();
    let lv = &g.levels()[0];
    assert!(lv.dense);
    let [rx, ry, rz, _] = lv.resolution;
    let mut seen = vec![false; lv.entries];
    for z in 0..rz {
        for y in 0..ry {
            for x in 0..rx {
                let i = lv.index(3, &[x, y, z]);
                assert!(!seen[i], "vertex ({x}, {y}, {z}) collides");
                seen[i] = true;
            }
        }
    }
    assert!(seen.iter().all(|&s| s));
    let hashed = g.levels().last().unwrap();
    assert!(!hashed.dense && hashed.entries == 512);
    for v in [[0u32, 0, 0], [1, 2, 3], [11, 7, 5], [12, 12, 12]] {
        let h = v[0] ^ v[1].wrapping_mul(2_654_435_761) ^ v[2].wrapping_mul(805_459_861);
        assert_eq!(hashed.index(3, &v), (h % 512) as usize);
    }
    assert_eq!(PRIMES[3], 3_674_653_429);
}

#[test]
fn forward_matches_the_f64_reference() {
    for dims in 1..=4 {
        for interp in INTERPS {
            for outside in [Outside::Clamp, Outside::Zero] {
                let g = small(dims, interp, outside, dims as u64);
                let rows = 300;
                // Inside and outside the box (the box spans about [-1, 2.5]).
                let x: Vec<f32> = vals(rows * dims, 11, 2.5).iter().map(|v| v + 0.5).collect();
                let (y, _) = g.forward(&x, rows).unwrap();
                let table = table_f64(&g);
                let w = g.output_width();
                for (i, row) in x.chunks_exact(dims).enumerate() {
                    let xr: Vec<f64> = row.iter().map(|&v| v as f64).collect();
                    let want = g.reference_encode(&table, &xr);
                    for (a, b) in y[i * w..(i + 1) * w].iter().zip(&want) {
                        assert!(
                            (*a as f64 - b).abs() < 1e-5,
                            "{dims}D {interp:?} {outside:?} row {i}: {a} vs {b}"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn gradients_match_f64_finite_differences() {
    for dims in [2, 3, 4] {
        for interp in INTERPS {
            let g = small(dims, interp, Outside::Clamp, 7 + dims as u64);
            assert!(g.levels().iter().any(|l| l.dense) && g.levels().iter().any(|l| !l.dense));
            let rows = 12;
            let x = inputs_off_walls(&g, rows, dims as u64, 0.02);
            let c = vals(rows * g.output_width(), 5, 1.0);
            let (_, cache) = g.forward(&x, rows).unwrap();
            let grads = g.backward(&cache, &c, true).unwrap();
            let x64: Vec<f64> = x.iter().map(|&v| v as f64).collect();
            let mut table = table_f64(&g);
            // Parameters: the loss is linear in them, so a large step is exact.
            for j in 0..table.len() {
                let t0 = table[j];
                table[j] = t0 + 0.5;
                let lp = ref_loss(&g, &table, &x64, &c);
                table[j] = t0 - 0.5;
                let lm = ref_loss(&g, &table, &x64, &c);
                table[j] = t0;
                let fd = (lp - lm) / 1.0;
                let an = grads.params[j] as f64;
                assert!(
                    (an - fd).abs() <= 1e-5 * (1.0 + fd.abs()),
                    "{dims}D {interp:?} table {j}: {an} vs {fd}"
                );
            }
            // Inputs: central differences in f64, off the cell walls.
            let gi = grads.inputs.unwrap();
            let h = 1e-6;
            let mut xx = x64.clone();
            for j in 0..xx.len() {
                xx[j] = x64[j] + h;
                let lp = ref_loss(&g, &table, &xx, &c);
                xx[j] = x64[j] - h;
                let lm = ref_loss(&g, &table, &xx, &c);
                xx[j] = x64[j];
                let fd = (lp - lm) / (2.0 * h);
                let an = gi[j] as f64;
                assert!(
                    (an - fd).abs() <= 1e-4 * (1.0 + fd.abs()),
                    "{dims}D {interp:?} input {j}: {an} vs {fd}"
                );
            }
        }
    }
}

#[test]
fn collisions_in_tiny_tables_sum_their_gradients() {
    // Two entries per level: almost every corner collides with another.
    for log2_table in 1..=2 {
        let mut g = HashGridConfig::new(3, 3, 2, log2_table, 2.0, 6.0)
            .interpolation(Interpolation::Smoothstep)
            .seed(3)
            .build()
            .unwrap();
        assert!(g.levels().iter().all(|l| !l.dense));
        g.set_params(&vals(g.param_count(), 4, 1.0)).unwrap();
        let rows = 9;
        let x = inputs_off_walls(&g, rows, 9, 0.02);
        let ones = vec![1.0f32; rows * g.output_width()];
        let (_, cache) = g.forward(&x, rows).unwrap();
        let grads = g.backward(&cache, &ones, false).unwrap();
        // With dL/dy = 1 the weights of each row sum to 1 per level and feature.
        for lv in g.levels() {
            for f in 0..2 {
                let s: f32 = (0..lv.entries)
                    .map(|e| grads.params[(lv.offset + e) * 2 + f])
                    .sum();
                assert!((s - rows as f32).abs() < 1e-4, "{s}");
            }
        }
        let c = vals(rows * g.output_width(), 6, 1.0);
        let grads = g.backward(&cache, &c, false).unwrap();
        let x64: Vec<f64> = x.iter().map(|&v| v as f64).collect();
        let mut table = table_f64(&g);
        for j in 0..table.len() {
            let t0 = table[j];
            table[j] = t0 + 1.0;
            let lp = ref_loss(&g, &table, &x64, &c);
            table[j] = t0;
            let fd = lp - ref_loss(&g, &table, &x64, &c);
            assert!((grads.params[j] as f64 - fd).abs() < 1e-5, "table {j}");
        }
    }
}

#[test]
fn partition_of_unity_inside_the_box() {
    for interp in INTERPS {
        let mut g = HashGridConfig::new(3, 5, 2, 8, 2.0, 40.0)
            .interpolation(interp)
            .build()
            .unwrap();
        g.set_params(&vec![1.0; g.param_count()]).unwrap();
        let x: Vec<f32> = vals(600, 2, 0.5).iter().map(|v| v + 0.5).collect();
        let (y, _) = g.forward(&x, 200).unwrap();
        assert!(y.iter().all(|v| (v - 1.0).abs() < 1e-6));
    }
}

#[test]
fn outside_the_box_zero_gives_zeros_and_clamp_gives_the_clamped_value() {
    // An xyt grid as Grid4D builds it: box [-1.6, 1.6] in x and y, t in [-1/18, 1 + 1/18].
    let (lo, hi) = (
        [-1.6f32, -1.6, -1.0 / 18.0],
        [1.6f32, 1.6, 1.0 + 1.0 / 18.0],
    );
    let rows = [
        [0.3f32, -0.2, 0.5], // inside
        [0.3, -0.2, 1.2],    // t past the end
        [0.3, -0.2, -0.4],   // t before the start
        [2.0, -0.2, 0.5],    // x outside
        [-5.0, 9.0, 3.0],    // everything outside
        [1.5, -1.5, 1.0],    // inside
    ];
    let x: Vec<f32> = rows.concat();
    let n = rows.len();
    for interp in INTERPS {
        let mk = |o| {
            let mut g = HashGridConfig::new(3, 4, 2, 10, 8.0, 32.0)
                .bounds(&lo, &hi)
                .interpolation(interp)
                .outside(o)
                .seed(1)
                .build()
                .unwrap();
            g.set_params(&vals(g.param_count(), 8, 1.0)).unwrap();
            g
        };
        let (zero, clamp) = (mk(Outside::Zero), mk(Outside::Clamp));
        let w = zero.output_width();
        let c = vals(n * w, 3, 1.0);
        let (yz, cz) = zero.forward(&x, n).unwrap();
        let (yc, cc) = clamp.forward(&x, n).unwrap();
        let gz = zero.backward(&cz, &c, true).unwrap();
        let gc = clamp.backward(&cc, &c, true).unwrap();
        let (gzi, gci) = (gz.inputs.unwrap(), gc.inputs.unwrap());
        for (i, r) in rows.iter().enumerate() {
            let inside = (0..3).all(|a| r[a] >= lo[a] && r[a] <= hi[a]);
            let yzr = &yz[i * w..(i + 1) * w];
            let ycr = &yc[i * w..(i + 1) * w];
            if inside {
                assert_eq!(yzr, ycr, "row {i}");
            } else {
                assert!(yzr.iter().all(|&v| v == 0.0), "row {i}");
                assert!(gzi[i * 3..i * 3 + 3].iter().all(|&v| v == 0.0), "row {i}");
                let cl: Vec<f32> = (0..3).map(|a| r[a].clamp(lo[a], hi[a])).collect();
                let (ycl, _) = clamp.forward(&cl, 1).unwrap();
                assert_eq!(ycr, &ycl[..], "row {i}");
                for a in 0..3 {
                    if r[a] < lo[a] || r[a] > hi[a] {
                        assert_eq!(gci[i * 3 + a], 0.0, "row {i} axis {a}");
                    }
                }
            }
        }
        // The rows outside contribute nothing to the table under Zero.
        let (_, c_in) = zero.forward(&x[..3], 1).unwrap();
        let g_in = zero.backward(&c_in, &c[..w], false).unwrap();
        let g_on = {
            let (_, c_on) = zero.forward(&x[15..18], 1).unwrap();
            zero.backward(&c_on, &c[5 * w..6 * w], false).unwrap()
        };
        let sum: Vec<f32> = g_in
            .params
            .iter()
            .zip(&g_on.params)
            .map(|(a, b)| a + b)
            .collect();
        assert_eq!(gz.params, sum);
    }
}

#[test]
fn f16_tables_agree_with_f32_and_saturate() {
    let cfg = HashGridConfig::new(3, 6, 2, 10, 4.0, 64.0).seed(2);
    let mut a = cfg.clone().build().unwrap();
    let mut b = cfg.precision(Precision::F16).build().unwrap();
    let t: Vec<f32> = vals(a.param_count(), 5, 3.0)
        .iter()
        .map(|&v| tiny_nn::precision::round_to_f16(v))
        .collect();
    a.set_params(&t).unwrap();
    assert_eq!(b.set_params(&t).unwrap(), 0);
    let rows = 2000;
    let x: Vec<f32> = vals(rows * 3, 6, 0.6).iter().map(|v| v + 0.5).collect();
    let (ya, ca) = a.forward(&x, rows).unwrap();
    let (yb, cb) = b.forward(&x, rows).unwrap();
    assert_eq!(
        ya, yb,
        "same f16-representable table, f32 arithmetic in both"
    );
    let c = vals(rows * a.output_width(), 7, 1.0);
    assert_eq!(
        a.backward(&ca, &c, true).unwrap(),
        b.backward(&cb, &c, true).unwrap()
    );
    // Saturation: values beyond ±65504 are clamped and counted; outputs stay finite.
    let big: Vec<f32> = (0..b.param_count())
        .map(|i| if i % 2 == 0 { 1e6 } else { -f32::INFINITY })
        .collect();
    assert_eq!(b.set_params(&big).unwrap(), b.param_count() as u64);
    let back = b.params().to_vec_f32();
    assert!(back.iter().step_by(2).all(|&v| v == 65504.0));
    assert!(back.iter().skip(1).step_by(2).all(|&v| v == -65504.0));
    let (y, _) = b.forward(&x, rows).unwrap();
    for (i, v) in y.iter().enumerate() {
        let want = if i % 2 == 0 { 65504.0 } else { -65504.0 };
        assert!((v - want).abs() <= 0.1, "{i}: {v}");
    }
}

#[test]
fn backward_is_bit_identical_for_any_thread_count() {
    let mut g = HashGridConfig::new(3, 8, 2, 12, 4.0, 200.0)
        .interpolation(Interpolation::Smoothstep)
        .seed(5)
        .build()
        .unwrap();
    g.set_params(&vals(g.param_count(), 1, 1.0)).unwrap();
    // More rows than one backward chunk (2^15), so that chunks are crossed too.
    let rows = 40_000;
    let x: Vec<f32> = vals(rows * 3, 2, 0.55).iter().map(|v| v + 0.5).collect();
    let c = vals(rows * g.output_width(), 3, 1.0);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let (y, cache) = g.forward(&x, rows).unwrap();
            (y, g.backward(&cache, &c, true).unwrap())
        })
    };
    let one = run(1);
    for threads in [2, 3, 5] {
        let other = run(threads);
        assert!(one.0 == other.0, "outputs differ with {threads} threads");
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(
            bits(&one.1.params),
            bits(&other.1.params),
            "{threads} threads"
        );
        assert_eq!(
            bits(one.1.inputs.as_ref().unwrap()),
            bits(other.1.inputs.as_ref().unwrap())
        );
    }
}

#[test]
fn bad_configurations_and_inputs_are_errors() {
    let ok = HashGridConfig::new(3, 2, 2, 8, 4.0, 8.0);
    assert!(ok.clone().build().is_ok());
    let bad = [
        HashGridConfig::new(0, 2, 2, 8, 4.0, 8.0),
        HashGridConfig::new(5, 2, 2, 8, 4.0, 8.0),
        HashGridConfig::new(3, 0, 2, 8, 4.0, 8.0),
        HashGridConfig::new(3, 2, 0, 8, 4.0, 8.0),
        HashGridConfig::new(3, 2, 2, 0, 4.0, 8.0),
        HashGridConfig::new(3, 2, 2, MAX_LOG2_TABLE + 1, 4.0, 8.0),
        HashGridConfig::new(3, 2, 2, 8, 1.5, 8.0),
        HashGridConfig::new(3, 2, 2, 8, 8.0, 4.0),
        HashGridConfig::new(3, 2, 2, 8, f32::NAN, 8.0),
        ok.clone().bounds(&[0.0, 0.0, 1.0], &[1.0, 1.0, 1.0]),
        ok.clone().bounds(&[0.0, 0.0], &[1.0, 1.0]),
        ok.clone().resolutions(&[4.0; 2], &[8.0; 3]),
    ];
    for (i, cfg) in bad.into_iter().enumerate() {
        let e = cfg.build().unwrap_err().to_string();
        assert!(e.contains("hash grid"), "case {i}: {e}");
    }
    let g = ok.build().unwrap();
    assert!(g.forward(&[0.5; 5], 2).is_err());
    let e = g
        .forward(&[0.5, 0.5, 0.5, 0.1, f32::NAN, 0.2], 2)
        .unwrap_err();
    assert!(e.to_string().contains("row 1"), "{e}");
    let (_, cache) = g.forward(&[0.5; 6], 2).unwrap();
    assert!(g.backward(&cache, &[0.0; 3], false).is_err());
    let (y, cache) = g.forward(&[], 0).unwrap();
    assert!(y.is_empty());
    let grads = g.backward(&cache, &[], true).unwrap();
    assert!(grads.params.iter().all(|&v| v == 0.0) && grads.inputs.unwrap().is_empty());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Under Clamp, any input encodes like its clamped copy; under Zero, any input outside the
    /// box encodes to zeros and inside it equals Clamp.
    #[test]
    fn clamp_and_zero_agree_with_their_definitions(
        x in proptest::collection::vec(-4.0f32..4.0, 3),
        smooth in any::<bool>(),
    ) {
        let interp = if smooth { Interpolation::Smoothstep } else { Interpolation::Linear };
        let clamp = small(3, interp, Outside::Clamp, 21);
        let zero = small(3, interp, Outside::Zero, 21);
        let c = clamp.config();
        let inside = (0..3).all(|a| x[a] >= c.box_min[a] && x[a] <= c.box_max[a]);
        let cl: Vec<f32> = (0..3).map(|a| x[a].clamp(c.box_min[a], c.box_max[a])).collect();
        let (y, _) = clamp.forward(&x, 1).unwrap();
        let (ycl, _) = clamp.forward(&cl, 1).unwrap();
        prop_assert_eq!(&y, &ycl);
        let (yz, _) = zero.forward(&x, 1).unwrap();
        if inside {
            prop_assert_eq!(&yz, &y);
        } else {
            prop_assert!(yz.iter().all(|&v| v == 0.0));
        }
    }
}
