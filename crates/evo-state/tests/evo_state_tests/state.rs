//! Row maintenance, persistence (bit-exact, and files of the older format), history re-query,
//! evolution off, memory accounting.

use crate::common;

use common::*;
use evo_state::{EvoConfig, EvoError, EvoState, Gain, HistoryMode, RowPlan, Storage};
use proptest::prelude::*;

fn trained(config: EvoConfig, rows: usize, frames: usize) -> EvoState {
    let mut st = state(config, uniform_frames(frames + 2), rows);
    let d = st.dim();
    for k in 0..frames {
        let z: Vec<f32> = (0..rows * d)
            .map(|e| ((e * 13 + k * 5) % 17) as f32 * 0.37 - 3.0 + k as f32)
            .collect();
        train(&mut st, k, &z);
    }
    st
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// After a plan, children carry their parent's buffer rows and memory rows (every frame),
    /// kept rows are unchanged, pruned rows are gone, and every array has the new row count.
    #[test]
    fn children_inherit_buffer_rows_and_memory(
        keep in proptest::collection::vec(any::<bool>(), 7),
        parents in proptest::collection::vec(0u32..7, 0..6),
        f16 in any::<bool>(),
    ) {
        let storage = if f16 { Storage::F16 } else { Storage::F32 };
        let before = trained(EvoConfig { storage, ..EvoConfig::default() }, 7, 4);
        let mut plan = RowPlan::prune(&keep);
        plan.parent_from_new = parents;
        let mut after = before.clone();
        after.apply_rows(&plan).unwrap();
        let d = after.dim();
        prop_assert_eq!(after.rows(), plan.new_len());
        let per_frame = plan.new_len() * d * storage.bytes() * after.frames().len();
        prop_assert_eq!(after.buffer_bytes(), per_frame);
        prop_assert_eq!(after.memory_bytes(), per_frame);
        prop_assert_eq!(after.state_bytes(), 2 * per_frame);
        let origin: Vec<u32> = plan.kept.iter().chain(&plan.parent_from_new).copied().collect();
        let (mem_after, mem_before) = (after.memory().unwrap(), before.memory().unwrap());
        for (new, &old) in origin.iter().enumerate() {
            let (new, old) = (new, old as usize);
            for k in 0..after.frames().len() {
                prop_assert_eq!(after.buffer().unwrap().row(k, new), before.buffer().unwrap().row(k, old));
                prop_assert_eq!(mem_after.row(k, new), mem_before.row(k, old));
            }
        }
        // The memory of the trained frames is not all zero, so the copies above are checks.
        prop_assert!((0..before.rows()).any(|i| mem_before.row(3, i).iter().any(|&m| m != 0.0)));
        // The next step works on the new rows.
        let z = vec![0.5f32; after.rows() * d];
        let step = after.forward(after.frames().times()[4], &z).unwrap();
        after.commit(&step).unwrap();
    }
}

#[test]
fn bad_plans_leave_the_state_unchanged() {
    let mut st = trained(EvoConfig::default(), 4, 3);
    let before = st.clone();
    let err = st
        .apply_rows(&RowPlan {
            kept: vec![0, 9],
            parent_from_new: vec![],
        })
        .unwrap_err();
    assert!(err.to_string().contains("out of range"), "{err}");
    let err = st
        .apply_rows(&RowPlan {
            kept: vec![],
            parent_from_new: vec![4],
        })
        .unwrap_err();
    assert!(err.to_string().contains("parent_from_new[0] = 4"), "{err}");
    assert_eq!(st, before);
}

#[test]
fn save_and_load_are_bit_exact() {
    let dir = tempfile::tempdir().unwrap();
    for (i, config) in [
        EvoConfig::default(),
        EvoConfig {
            storage: Storage::F16,
            gain: Gain::Fixed(0.3),
            beta: 0.85,
            ..EvoConfig::default()
        },
        EvoConfig {
            history: HistoryMode::Requery,
            motion_floor: 1.234e-7,
            extent: 3.3,
            ..EvoConfig::default()
        },
        EvoConfig {
            evolution: false,
            ..EvoConfig::default()
        },
    ]
    .into_iter()
    .enumerate()
    {
        let mut st = if config.history == HistoryMode::Requery {
            state(config, uniform_frames(5), 6)
        } else {
            trained(config, 6, 4)
        };
        if config.storage == Storage::F16 {
            let d = st.dim();
            train(&mut st, 5, &vec![1e6; 6 * d]);
            assert!(st.saturations() > 0);
        }
        st.apply_rows(&RowPlan {
            kept: vec![0, 2, 3, 4, 5],
            parent_from_new: vec![2],
        })
        .unwrap();
        let path = dir.path().join(format!("state{i}.safetensors"));
        st.save(&path).unwrap();
        // Readable as every other output: the temporary file's private 0600 does not survive.
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
            assert_eq!(mode, 0o644, "{mode:o}");
        }
        let loaded = EvoState::load(&path).unwrap();
        assert_eq!(loaded, st, "config {i}");
        // Bit-exact, including -0.0 and every float of Ψ, the memory and the input RMS.
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&loaded.psi().params()), bits(&st.psi().params()));
        if let (Some(a), Some(b)) = (loaded.memory(), st.memory()) {
            for k in 0..st.frames().len() {
                for i in 0..st.rows() {
                    assert_eq!(bits(&a.row(k, i)), bits(&b.row(k, i)));
                }
            }
        }
        assert_eq!(loaded.input_norm(), st.input_norm());
        // Saving the loaded state gives the same bytes (the metadata's keys are written in
        // sorted order, not in the order of a `HashMap`, which differs from map to map).
        let again = dir.path().join(format!("again{i}.safetensors"));
        loaded.save(&again).unwrap();
        assert!(EvoState::load(&again).unwrap() == st);
        assert!(
            std::fs::read(&again).unwrap() == std::fs::read(&path).unwrap(),
            "config {i}: the same state saved twice differs"
        );
    }
    // No temporary files left behind.
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 8, "{names:?}");
}

#[test]
fn load_errors_name_the_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.safetensors");
    let err = EvoState::load(&path).unwrap_err();
    assert!(matches!(err, EvoError::Io { .. }) && err.to_string().contains("bad.safetensors"));
    std::fs::write(&path, b"not a safetensors file").unwrap();
    let err = EvoState::load(&path).unwrap_err().to_string();
    assert!(
        err.contains("bad.safetensors") && err.contains("safetensors"),
        "{err}"
    );
    // A valid file whose memory has the wrong shape.
    let st = trained(EvoConfig::default(), 3, 2);
    st.save(&path).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let mut tampered = bytes.clone();
    let at = tampered
        .windows(10)
        .position(|w| w == b"\"rows\":\"3\"")
        .expect("rows in header");
    tampered[at + 8] = b'4';
    std::fs::write(&path, &tampered).unwrap();
    let err = EvoState::load(&path).unwrap_err().to_string();
    assert!(
        err.contains("bad.safetensors") && err.contains("memory") && err.contains("shape"),
        "{err}"
    );
}

/// "Without buffer": the history is re-queried from the observation source, here a function
/// of time, so the prior is exact for linear motion whatever was committed.
#[test]
fn history_requeried_from_the_observation_source() {
    let config = EvoConfig {
        layout: position_only(),
        history: HistoryMode::Requery,
        gain: Gain::Fixed(0.0),
        ..EvoConfig::default()
    };
    let mut st = state(config, uniform_frames(5), 2);
    assert_eq!(st.buffer_bytes(), 0);
    let linear = |t: f32| vec![1.0 + 2.0 * t, -t, 0.5, 3.0 * t, 0.0, 1.0];
    let mut calls = Vec::new();
    let mut source =
        |t: f32, out: &mut [f32]| -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
            calls.push(t);
            out.copy_from_slice(&linear(t));
            Ok(())
        };
    // Nothing committed, yet every earlier frame is available.
    let t = st.frames().times()[3];
    let step = st.forward_with(t, &[9.0; 6], &mut source).unwrap();
    assert_eq!(step.history().frames(), &[2, 1, 0]);
    for (a, b) in step.corrected().iter().zip(linear(t)) {
        assert!((a - b).abs() < 1e-5);
    }
    st.commit(&step).unwrap();
    assert_eq!(calls, vec![0.5, 0.25, 0.0]);
    assert!(matches!(
        st.forward(t, &[0.0; 6]),
        Err(EvoError::NeedsObservationSource)
    ));
    let mut failing =
        |_: f32, _: &mut [f32]| -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
            Err("network unavailable".into())
        };
    let err = st
        .forward_with(t, &[0.0; 6], &mut failing)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("network unavailable") && err.contains("0.5"),
        "{err}"
    );
    let mut nan =
        |_: f32, out: &mut [f32]| -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
            out.fill(0.0);
            out[4] = f32::NAN;
            Ok(())
        };
    let err = st
        .forward_with(t, &[0.0; 6], &mut nan)
        .unwrap_err()
        .to_string();
    assert!(err.contains("Gaussian 1"), "{err}");
}

#[test]
fn evolution_off_is_the_baseline() {
    let config = EvoConfig {
        evolution: false,
        ..EvoConfig::default()
    };
    let st = trained(config, 3, 5);
    assert_eq!(st.state_bytes(), 0);
    assert!(st.memory().is_none());
    let z = vec![0.25f32; 3 * st.dim()];
    let step = st.forward(st.frames().times()[5], &z).unwrap();
    assert_eq!(step.corrected(), &z[..]);
    assert_eq!(step.history().len, 0);
}

/// The buffer holds exactly 4·D (f32) or 2·D (f16) bytes per Gaussian per frame, as the
/// configuration predicts, and nothing without a buffer.
#[test]
fn buffer_memory_matches_the_configuration() {
    for config in [
        EvoConfig::default(),
        EvoConfig {
            storage: Storage::F16,
            ..EvoConfig::default()
        },
        EvoConfig {
            history: HistoryMode::Requery,
            ..EvoConfig::default()
        },
        EvoConfig {
            evolution: false,
            ..EvoConfig::default()
        },
    ] {
        let st = state(config, uniform_frames(7), 11);
        assert_eq!(st.buffer_bytes(), config.buffer_bytes(11, 7));
        assert_eq!(st.memory_bytes(), config.memory_bytes(11, 7));
        assert_eq!(
            st.state_bytes(),
            config.buffer_bytes(11, 7) + config.memory_bytes(11, 7)
        );
        if config.evolution {
            // M[k] beside the buffer, in the same storage, with either history mode.
            assert_eq!(
                st.memory_bytes(),
                11 * 7 * st.dim() * config.storage.bytes()
            );
        }
        if st.buffer().is_some() {
            assert_eq!(
                st.buffer_bytes(),
                11 * 7 * st.dim() * config.storage.bytes()
            );
        }
    }
}

/// Reusing one step and one backward across frames, stages and row counts gives exactly what
/// fresh ones give; a failed pass leaves a step that cannot be committed.
#[test]
fn reused_steps_match_fresh_ones() {
    let mut fresh = state(EvoConfig::default(), uniform_frames(8), 5);
    let mut reused = fresh.clone();
    let mut step = evo_state::Step::empty();
    let mut back = evo_state::Backward::default();
    for k in 0..7 {
        if k == 5 {
            let plan = RowPlan {
                kept: vec![0, 2, 3, 4],
                parent_from_new: vec![1, 1, 3],
            };
            fresh.apply_rows(&plan).unwrap();
            reused.apply_rows(&plan).unwrap();
        }
        let (n, d) = (fresh.rows(), fresh.dim());
        let z: Vec<f32> = (0..n * d)
            .map(|e| ((e * 5 + k) % 9) as f32 * 0.3 - k as f32 * 0.1)
            .collect();
        let g: Vec<f32> = (0..n * d).map(|e| (e % 4) as f32 * 0.01).collect();
        let t = fresh.frames().times()[k];
        let a = fresh.forward(t, &z).unwrap();
        reused.forward_into(t, &z, None, &mut step).unwrap();
        assert_eq!(a.corrected(), step.corrected());
        assert_eq!(a.prior(), step.prior());
        assert_eq!(a.gains(), step.gains());
        assert_eq!(a.stats(), step.stats());
        let ba = fresh.backward(&a, &z, &g, &vec![0.7; n]).unwrap();
        reused
            .backward_into(&step, &z, &g, &vec![0.7; n], &mut back)
            .unwrap();
        assert_eq!(ba, back);
        fresh.commit(&a).unwrap();
        reused.commit(&step).unwrap();
        assert_eq!(fresh, reused);
    }
    let bad = vec![f32::NAN; reused.rows() * reused.dim()];
    assert!(
        reused
            .forward_into(reused.frames().times()[7], &bad, None, &mut step)
            .is_err()
    );
    assert!(reused.commit(&step).is_err());
}

/// A file of the older format `evo-state/1` (one memory per Gaussian, Ψ inputs scaled by the
/// extent; `tests/fixtures/evo_state_v1.safetensors`, written by the previous revision from 3
/// Gaussians, 5 frames, frames 0..3 trained on `z = ((e·7 + 3k) mod 11)/10 + k/5`, extent 2)
/// still loads: buffer, valid flags and Ψ as saved, zero per-frame memory (the old memory
/// belongs to no frame), and the fixed extent scaling as Ψ's input normaliser. Saving it writes
/// the current format.
#[test]
fn older_files_without_per_frame_memory_load_as_zero_memory() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/evo_state_v1.safetensors");
    let st = EvoState::load(&path).unwrap();
    let d = st.dim();
    assert_eq!((st.rows(), d, st.frames().len()), (3, 10, 5));
    assert_eq!(st.valid(), &[true, true, true, true, false]);
    assert_eq!(st.config().extent, 2.0);
    let z = |k: usize| -> Vec<f32> {
        (0..3 * d)
            .map(|e| ((e * 7 + k * 3) % 11) as f32 * 0.1 + k as f32 * 0.2)
            .collect()
    };
    // Frames 0 and 1 were trained with h < 2: their corrected states are the observations.
    for k in 0..2 {
        for i in 0..3 {
            assert_eq!(st.buffer().unwrap().row(k, i), z(k)[i * d..(i + 1) * d]);
        }
    }
    let memory = st.memory().unwrap();
    for k in 0..5 {
        for i in 0..3 {
            assert!(memory.row(k, i).iter().all(|&m| m == 0.0));
        }
    }
    // Position memory and speeds divided by the extent, the rest as they are.
    let rms = st.input_norm().rms().unwrap();
    assert_eq!(
        rms,
        [2.0, 2.0, 2.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 2.0, 2.0]
    );
    // It trains on: the next frame reads M[3] = 0 and commits.
    let mut st = st;
    let step = train(&mut st, 4, &z(4));
    assert_eq!(step.history().frames(), &[3, 2, 1]);
    let m = step.memory_next().unwrap();
    let prior = step.prior().unwrap();
    for e in 0..3 * d {
        assert!((m[e] - 0.1 * (z(4)[e] - prior[e])).abs() < 1e-6);
    }
    let dir = tempfile::tempdir().unwrap();
    let again = dir.path().join("v2.safetensors");
    st.save(&again).unwrap();
    assert_eq!(EvoState::load(&again).unwrap(), st);
    let header = std::fs::read(&again).unwrap();
    assert!(header.windows(12).any(|w| w == b"evo-state/2\""));
}

/// The per-frame memory survives save and load exactly, and a resumed state continues as the
/// original would: the same next step, bit for bit.
#[test]
fn resumed_state_continues_identically() {
    let mut st = trained(EvoConfig::default(), 5, 4);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.safetensors");
    st.save(&path).unwrap();
    let mut resumed = EvoState::load(&path).unwrap();
    let d = st.dim();
    let z: Vec<f32> = (0..5 * d).map(|e| (e % 7) as f32 * 0.3 - 1.0).collect();
    let a = train(&mut st, 4, &z);
    let b = train(&mut resumed, 4, &z);
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(a.corrected()), bits(b.corrected()));
    assert_eq!(
        bits(a.memory_next().unwrap()),
        bits(b.memory_next().unwrap())
    );
    assert_eq!(bits(a.psi_inputs().unwrap()), bits(b.psi_inputs().unwrap()));
    assert_eq!(resumed, st);
}

/// A fixed seed gives the same state for any thread count: 20 chunks of rows, so rayon splits
/// the passes differently on 1, 2, 3 and 4 threads, and learned K reads Ψ's inputs normalised by
/// their batch RMS (a sum over every row).
#[test]
fn thread_count_changes_nothing() {
    let config = EvoConfig::default();
    assert!(matches!(config.gain, Gain::Learned));
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| trained(config, 20 * 1024 + 7, 6))
    };
    let one = run(1);
    assert!(
        one.input_norm().weight() > 0.0,
        "Ψ's inputs were never normalised"
    );
    for threads in [2, 3, 4] {
        assert!(run(threads) == one, "{threads} threads differ from one");
    }
}
