//! Synthetic scenes: determinism, effects in isolation, the D-NeRF round trip, the jump, the
//! ground-truth file, and a summary snapshot.

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};
use std::path::Path;

use evogs_io::{Split, load_image, read_dnerf_split};
use evogs_synth::{
    CaptureNoise, FIXED_DIR, GROUND_TRUTH_FILE, MONOCULAR_ARC, Part, Preset, Protocol, RIG_OFFSET,
    SceneSpec, SceneSummary, SyntheticScene, embedded_scene, generate, read_ground_truth,
    write_dnerf,
};
use glam::{Quat, Vec3};

/// A small, fast version of a preset.
fn small(preset: Preset) -> SceneSpec {
    SceneSpec::preset(preset)
        .with_size(32)
        .with_frames(10)
        .with_gaussian_scale(0.15)
}

fn hash_scene(scene: &SyntheticScene) -> u64 {
    let mut h = DefaultHasher::new();
    let bits = |v: &[f32], h: &mut DefaultHasher| v.iter().for_each(|x| x.to_bits().hash(h));
    bits(scene.canonical.means.as_flattened(), &mut h);
    bits(&scene.canonical.sh, &mut h);
    for split in Split::ALL {
        for f in scene.split(split) {
            bits(&[f.time], &mut h);
            bits(f.color.as_flattened(), &mut h);
            bits(&f.alpha, &mut h);
            bits(&f.camera.translation.to_array(), &mut h);
        }
    }
    for m in &scene.trajectories.means {
        bits(m.as_flattened(), &mut h);
    }
    h.finish()
}

fn hash_dir(dir: &Path) -> u64 {
    let mut files: Vec<_> = walk(dir);
    files.sort();
    let mut h = DefaultHasher::new();
    for f in files {
        f.strip_prefix(dir).unwrap().hash(&mut h);
        std::fs::read(&f).unwrap().hash(&mut h);
    }
    h.finish()
}

fn walk(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else {
            out.push(p);
        }
    }
    out
}

#[test]
fn generation_and_files_are_deterministic_for_a_seed() {
    let spec = small(Preset::Mixed);
    let a = generate(&spec, 3).unwrap();
    let b = generate(&spec, 3).unwrap();
    assert_eq!(hash_scene(&a), hash_scene(&b));
    assert_eq!(a, b);
    let c = generate(&spec, 4).unwrap();
    assert_ne!(hash_scene(&a), hash_scene(&c));

    let (d1, d2) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    write_dnerf(&a, d1.path()).unwrap();
    write_dnerf(&b, d2.path()).unwrap();
    assert_eq!(hash_dir(d1.path()), hash_dir(d2.path()));
    // No temporary files are left behind.
    assert!(walk(d1.path()).iter().all(|p| {
        !p.file_name()
            .unwrap()
            .to_string_lossy()
            .starts_with(".evogs-tmp")
    }));
}

#[test]
fn rigid_preset_moves_rigidly_and_stores_no_other_effect() {
    let scene = generate(&small(Preset::Rigid), 1).unwrap();
    let motion = scene.motion();
    assert!(motion.wave.is_none() && motion.jump.is_none() && motion.large_motion.is_none());
    assert!(motion.appearance.is_none() && motion.occlusion.is_none());
    assert!(scene.parts.iter().all(|&p| p != Part::Occluder));
    let traj = &scene.trajectories;
    assert!(traj.rotations.is_some(), "rigid rotation is stored");
    assert!(traj.sh_dc.is_none(), "no appearance change, no colour data");
    // Every position is exactly R(t)·p + T(t): no per-Gaussian non-rigid term.
    for (k, &t) in traj.times.iter().enumerate() {
        let (q, tr) = motion.rigid_at(t);
        for (i, p) in scene.canonical.means.iter().enumerate() {
            let want = q * Vec3::from_array(*p) + tr;
            let got = Vec3::from_array(traj.means[k][i]);
            assert!((got - want).length() < 1e-5, "t={t} i={i}");
        }
    }
    // And the motion is not trivial.
    let last = traj.means.last().unwrap();
    let moved = Vec3::from_array(last[0]).distance(Vec3::from_array(scene.canonical.means[0]));
    assert!(moved > 0.2, "{moved}");
}

#[test]
fn wave_preset_is_non_rigid_and_stores_only_positions() {
    let scene = generate(&small(Preset::Wave), 1).unwrap();
    let traj = &scene.trajectories;
    assert!(traj.rotations.is_none() && traj.sh_dc.is_none());
    assert!(scene.parts.iter().all(|&p| p != Part::Occluder));
    // Satellite is still; body points move only along z, by different amounts.
    let mut dz: Vec<f32> = Vec::new();
    for (i, part) in scene.parts.iter().enumerate() {
        let p0 = Vec3::from_array(scene.canonical.means[i]);
        let p = Vec3::from_array(traj.means[3][i]);
        let d = p - p0;
        assert!(d.x == 0.0 && d.y == 0.0);
        match part {
            Part::Satellite => assert_eq!(d.z, 0.0),
            _ => dz.push(d.z),
        }
    }
    let (lo, hi) = dz
        .iter()
        .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    assert!(hi - lo > 0.1, "a wave bends the body: dz spans {lo}..{hi}");
}

#[test]
fn mixed_preset_stores_everything_and_only_it_has_an_occluder() {
    let spec = small(Preset::Mixed);
    let scene = generate(&spec, 1).unwrap();
    let traj = &scene.trajectories;
    assert!(traj.rotations.is_some() && traj.sh_dc.is_some());
    let occluders = scene.parts.iter().filter(|&&p| p == Part::Occluder).count();
    assert!(occluders >= spec.occluder_gaussians * 9 / 10, "{occluders}");
    // Colours change with time on the body only.
    let mid = traj.times.len() / 2;
    let dc = traj.sh_dc.as_ref().unwrap();
    for (i, part) in scene.parts.iter().enumerate() {
        let base = &scene.canonical.sh[3 * i..3 * i + 3];
        let changed = dc[mid][i]
            .iter()
            .zip(base)
            .any(|(a, b)| (a - b).abs() > 1e-3);
        assert_eq!(changed, *part == Part::Body, "Gaussian {i} ({part:?})");
    }
    // The occluder's rotation follows its orbit.
    let (k, t) = (mid, traj.times[mid]);
    let i = scene
        .parts
        .iter()
        .position(|&p| p == Part::Occluder)
        .unwrap();
    let r = scene.canonical.rotations[i];
    let want = scene.motion().orbit_at(t) * Quat::from_xyzw(r[1], r[2], r[3], r[0]);
    let got = traj.rotations.as_ref().unwrap()[k][i];
    assert!((Quat::from_xyzw(got[1], got[2], got[3], got[0]).dot(want) - 1.0).abs() < 1e-5);
}

#[test]
fn jump_is_a_discontinuity_between_two_consecutive_training_times() {
    let spec = SceneSpec::preset(Preset::Jump)
        .with_size(32)
        .with_gaussian_scale(0.15);
    let scene = generate(&spec, 2).unwrap();
    let jump = spec.jump.unwrap();
    let times: Vec<f32> = scene.train.iter().map(|f| f.time).collect();
    let k = times
        .windows(2)
        .position(|w| w[0] < jump.time && jump.time < w[1])
        .unwrap();
    let sat: Vec<usize> = (0..scene.parts.len())
        .filter(|&i| scene.parts[i] == Part::Satellite)
        .collect();
    let step = |a: f32, b: f32| {
        let (ga, gb) = (scene.gaussians_at(a), scene.gaussians_at(b));
        sat.iter()
            .map(|&i| Vec3::from_array(ga.means[i]).distance(Vec3::from_array(gb.means[i])))
            .fold(0f32, f32::max)
    };
    let across = step(times[k], times[k + 1]);
    let others = (0..times.len() - 1)
        .filter(|&j| j != k)
        .map(|j| step(times[j], times[j + 1]))
        .fold(0f32, f32::max);
    assert!(across > 0.9, "the satellite jumps: {across}");
    assert!(
        across > 20.0 * others,
        "jump {across} vs largest ordinary step {others}"
    );
    // The body never moves.
    let g = scene.gaussians_at(1.0);
    for (i, part) in scene.parts.iter().enumerate() {
        if *part == Part::Body {
            assert_eq!(g.means[i], scene.canonical.means[i]);
        }
    }
}

#[test]
fn written_dataset_round_trips_through_the_dnerf_reader() {
    let scene = generate(&small(Preset::Rigid), 5).unwrap();
    let dir = tempfile::tempdir().unwrap();
    write_dnerf(&scene, dir.path()).unwrap();
    let background = [1.0, 1.0, 1.0];
    for split in Split::ALL {
        let frames = read_dnerf_split(dir.path(), split).unwrap();
        let ours = scene.split(split);
        assert_eq!(frames.len(), ours.len());
        for (read, mine) in frames.iter().zip(ours) {
            assert_eq!(read.time, mine.time);
            let (a, b) = (&read.camera, &mine.camera);
            assert_eq!((a.width, a.height), (b.width, b.height));
            for (x, y) in [(a.fx, b.fx), (a.fy, b.fy), (a.cx, b.cx), (a.cy, b.cy)] {
                assert!((x - y).abs() < 1e-3 * y.abs().max(1.0), "{x} vs {y}");
            }
            assert!(a.rotation.abs_diff_eq(b.rotation, 1e-6));
            assert!(a.translation.abs_diff_eq(b.translation, 1e-5));
            let image = load_image(&read.image_path, background).unwrap();
            let want = mine.image_over(background);
            let worst = image
                .pixels
                .iter()
                .zip(&want)
                .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs()))
                .fold(0f32, f32::max);
            assert!(worst <= 1.5 / 255.0, "{split}: worst pixel error {worst}");
        }
    }
    // The canonical PLY reads back to the same Gaussians.
    let ply = evogs_io::read_ply(&dir.path().join("canonical.ply")).unwrap();
    assert_eq!(ply.gaussians, scene.canonical);
}

#[test]
fn ground_truth_file_holds_the_trajectories() {
    let scene = generate(&small(Preset::Mixed), 6).unwrap();
    let dir = tempfile::tempdir().unwrap();
    write_dnerf(&scene, dir.path()).unwrap();
    let bytes = std::fs::read(dir.path().join(GROUND_TRUTH_FILE)).unwrap();
    let st = safetensors::SafeTensors::deserialize(&bytes).unwrap();
    let (t, n) = (scene.trajectories.times.len(), scene.canonical.len());
    let f32s = |name: &str| -> (Vec<usize>, Vec<f32>) {
        let v = st.tensor(name).unwrap();
        let data = v
            .data()
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect();
        (v.shape().to_vec(), data)
    };
    let (shape, times) = f32s("times");
    assert_eq!((shape, times), (vec![t], scene.trajectories.times.clone()));
    let (shape, means) = f32s("means");
    assert_eq!(shape, vec![t, n, 3]);
    assert_eq!(means[3 * n + 3..3 * n + 6], scene.trajectories.means[1][1]);
    assert_eq!(f32s("rotations").0, vec![t, n, 4]);
    assert_eq!(f32s("sh_dc").0, vec![t, n, 3]);
    assert_eq!(st.tensor("parts").unwrap().shape(), [n]);
    // The reader gives back exactly what was generated.
    let (read, parts) = read_ground_truth(&dir.path().join(GROUND_TRUTH_FILE)).unwrap();
    assert_eq!(read, scene.trajectories);
    assert_eq!(parts, scene.parts);
    // Truncated and mis-shaped files are errors naming the file and the tensor.
    let cut = dir.path().join("cut.safetensors");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let err = read_ground_truth(&cut).unwrap_err().to_string();
    assert!(
        err.contains("cut.safetensors") && err.contains("tensor `header`"),
        "{err}"
    );
    let bad = dir.path().join("bad.safetensors");
    let two = vec![0u8; t * n * 2 * 4];
    let parts_bytes = vec![0u8; n];
    let times_bytes: Vec<u8> = (0..t).flat_map(|k| (k as f32).to_le_bytes()).collect();
    let views = vec![
        (
            "times",
            safetensors::tensor::TensorView::new(safetensors::Dtype::F32, vec![t], &times_bytes)
                .unwrap(),
        ),
        (
            "means",
            safetensors::tensor::TensorView::new(safetensors::Dtype::F32, vec![t, n, 2], &two)
                .unwrap(),
        ),
        (
            "parts",
            safetensors::tensor::TensorView::new(safetensors::Dtype::U8, vec![n], &parts_bytes)
                .unwrap(),
        ),
    ];
    std::fs::write(&bad, safetensors::tensor::serialize(views, None).unwrap()).unwrap();
    let err = read_ground_truth(&bad).unwrap_err().to_string();
    assert!(
        err.contains("bad.safetensors: tensor `means`: shape"),
        "{err}"
    );
    // Trajectories agree with the motion model at their times.
    let g = scene.gaussians_at(scene.trajectories.times[2]);
    assert_eq!(g.means, scene.trajectories.means[2]);

    // Without rotation or appearance change, those tensors are absent.
    let wave = generate(&small(Preset::Wave), 6).unwrap();
    let dir = tempfile::tempdir().unwrap();
    write_dnerf(&wave, dir.path()).unwrap();
    let bytes = std::fs::read(dir.path().join(GROUND_TRUTH_FILE)).unwrap();
    let st = safetensors::SafeTensors::deserialize(&bytes).unwrap();
    let mut names: Vec<String> = st.names().into_iter().map(String::from).collect();
    names.sort();
    assert_eq!(names, ["means", "parts", "times"]);
}

#[test]
fn bad_spec_is_an_error_naming_the_field() {
    let mut spec = small(Preset::Wave);
    spec.test_frames = 0;
    let err = generate(&spec, 0).unwrap_err();
    assert_eq!(
        err.to_string(),
        "scene spec field `test_frames`: 0 is outside 1..=10000"
    );
}

#[test]
fn embedded_scene_summary_snapshot() {
    let scene = embedded_scene().unwrap();
    insta::assert_snapshot!(
        "embedded_scene_summary",
        SceneSummary::of(&scene).to_string()
    );
}

#[test]
fn small_mixed_scene_summary_snapshot() {
    let scene = generate(&small(Preset::Mixed), 11).unwrap();
    insta::assert_snapshot!("small_mixed_summary", SceneSummary::of(&scene).to_string());
}

fn azimuth(c: Vec3) -> f32 {
    c.y.atan2(c.x)
}

/// Angle difference wrapped to (−π, π].
fn wrap(a: f32) -> f32 {
    let t = std::f32::consts::TAU;
    a - t * ((a + 0.5 * t) / t).floor()
}

#[test]
fn monocular_protocol_places_one_arc_rig_cameras_at_training_times_and_a_fixed_camera() {
    let spec = small(Preset::Wave).with_protocol(Protocol::Monocular);
    let scene = generate(&spec, 4).unwrap();
    let train_times: Vec<f32> = scene.train.iter().map(|f| f.time).collect();
    assert_eq!(train_times, spec.train_times());
    // One camera moving smoothly: every centre at the same distance, azimuth growing linearly
    // by the arc over the sequence, consecutive steps equal.
    let centres: Vec<Vec3> = scene.train.iter().map(|f| f.camera.center()).collect();
    let d = centres[0].length();
    assert!(centres.iter().all(|c| (c.length() - d).abs() < 1e-3 * d));
    let steps: Vec<f32> = centres
        .windows(2)
        .map(|w| wrap(azimuth(w[1]) - azimuth(w[0])))
        .collect();
    let step = MONOCULAR_ARC / (spec.train_frames - 1) as f32;
    assert!(steps.iter().all(|s| (s - step).abs() < 1e-4), "{steps:?}");
    // Test (+offset) and val (−offset) at training timestamps, different ones.
    for (frames, offset) in [(&scene.test, RIG_OFFSET), (&scene.val, -RIG_OFFSET)] {
        assert_eq!(frames.len(), 2);
        for f in frames {
            let k = train_times
                .iter()
                .position(|&t| t == f.time)
                .expect("a training time");
            let train = scene.train[k].camera.center();
            let got = wrap(azimuth(f.camera.center()) - azimuth(train));
            assert!((got - offset).abs() < 1e-4, "{got} vs {offset}");
            assert!((f.camera.center().z - train.z).abs() < 1e-4);
        }
    }
    let test_times: Vec<f32> = scene.test.iter().map(|f| f.time).collect();
    assert!(scene.val.iter().all(|f| !test_times.contains(&f.time)));
    // Ground truth only at the training times (test and val add none).
    assert_eq!(scene.trajectories.times, train_times);
    // The fixed-camera sequence: every training time, one camera, exact images.
    assert_eq!(scene.fixed.len(), spec.train_frames);
    assert!(
        scene
            .fixed
            .iter()
            .all(|f| f.camera == scene.fixed[0].camera)
    );
    let fixed_times: Vec<f32> = scene.fixed.iter().map(|f| f.time).collect();
    assert_eq!(fixed_times, train_times);
    // The object moves in the fixed view (a wave), so ground-truth flicker is not zero.
    assert_ne!(scene.fixed[0].color, scene.fixed[5].color);
    // The D-NeRF protocol has none.
    assert!(generate(&small(Preset::Wave), 4).unwrap().fixed.is_empty());
}

#[test]
fn monocular_scene_and_files_are_deterministic_for_a_seed() {
    let spec = small(Preset::Jump).with_protocol(Protocol::Monocular);
    let (a, b) = (generate(&spec, 8).unwrap(), generate(&spec, 8).unwrap());
    assert_eq!(a, b);
    let c = generate(&spec, 9).unwrap();
    assert_ne!(
        a.train[0].camera, c.train[0].camera,
        "the seed places the arc"
    );
    let (d1, d2) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    write_dnerf(&a, d1.path()).unwrap();
    write_dnerf(&b, d2.path()).unwrap();
    assert_eq!(hash_dir(d1.path()), hash_dir(d2.path()));
}

#[test]
fn monocular_scene_is_written_with_its_fixed_sequence_and_recorded_protocol() {
    let spec = small(Preset::Jump).with_protocol(Protocol::Monocular);
    let scene = generate(&spec, 2).unwrap();
    let dir = tempfile::tempdir().unwrap();
    write_dnerf(&scene, dir.path()).unwrap();
    let test = read_dnerf_split(dir.path(), Split::Test).unwrap();
    let train = read_dnerf_split(dir.path(), Split::Train).unwrap();
    assert!(
        test.iter()
            .all(|f| train.iter().any(|t| (t.time - f.time).abs() < 1e-6))
    );
    let fixed: serde_json::Value = serde_json::from_slice(
        &std::fs::read(dir.path().join(FIXED_DIR).join("transforms_train.json")).unwrap(),
    )
    .unwrap();
    let frames = fixed["frames"].as_array().unwrap();
    assert_eq!(frames.len(), spec.train_frames);
    assert_eq!(frames[3]["file_path"], "./train/r_003");
    assert!(dir.path().join("fixed/train/r_003.png").is_file());
    let read = read_dnerf_split(&dir.path().join(FIXED_DIR), Split::Train).unwrap();
    assert_eq!(read.len(), spec.train_frames);
    let index: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("scene.json")).unwrap()).unwrap();
    assert_eq!(index["spec"]["protocol"], "monocular");
    assert_eq!(index["summary"]["protocol"], "monocular");
    assert_eq!(index["summary"]["fixed_camera_frames"], spec.train_frames);
    assert!(
        index["spec"].get("noise").is_none(),
        "noise off is not recorded"
    );

    // A D-NeRF scene records neither, and writes no fixed sequence (its files are unchanged).
    let dnerf = tempfile::tempdir().unwrap();
    write_dnerf(&generate(&small(Preset::Jump), 2).unwrap(), dnerf.path()).unwrap();
    let index: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dnerf.path().join("scene.json")).unwrap()).unwrap();
    for key in ["protocol", "noise"] {
        assert!(index["spec"].get(key).is_none(), "{key}");
        assert!(index["summary"].get(key).is_none(), "{key}");
    }
    assert!(index["summary"].get("fixed_camera_frames").is_none());
    assert!(!dnerf.path().join("fixed").exists());
}

#[test]
fn capture_noise_is_seeded_reproducible_and_touches_only_the_training_captures() {
    for protocol in Protocol::ALL {
        let clean_spec = small(Preset::Rigid).with_protocol(protocol);
        let clean = generate(&clean_spec, 6).unwrap();
        let pose = clean_spec.clone().with_noise(CaptureNoise {
            pose: 0.01,
            image: 0.0,
        });
        let image = clean_spec.clone().with_noise(CaptureNoise {
            pose: 0.0,
            image: 0.05,
        });
        let (p, i) = (generate(&pose, 6).unwrap(), generate(&image, 6).unwrap());
        // Reproducible for a seed, different for another.
        assert_eq!(p, generate(&pose, 6).unwrap());
        assert_eq!(i, generate(&image, 6).unwrap());
        assert_ne!(
            i.train[0].color,
            generate(&image, 7).unwrap().train[0].color
        );
        // Test, val and the fixed sequence stay exact.
        for scene in [&p, &i] {
            assert_eq!(scene.test, clean.test);
            assert_eq!(scene.val, clean.val);
            assert_eq!(scene.fixed, clean.fixed);
            assert_eq!(scene.trajectories, clean.trajectories);
        }
        // Pose noise: same images (rendered from the true cameras), recorded cameras moved by
        // about σ·distance.
        let distance = clean.train[0].camera.center().length();
        let mut moved = 0.0f32;
        for (a, b) in p.train.iter().zip(&clean.train) {
            assert_eq!((&a.color, &a.alpha), (&b.color, &b.alpha));
            moved = moved.max(a.camera.center().distance(b.camera.center()));
        }
        assert!(
            moved > 0.002 * distance && moved < 0.1 * distance,
            "{moved} of {distance}"
        );
        // Image noise: same cameras, colours changed by about σ on the object only, never
        // outside [0, α].
        let (mut sq, mut count) = (0.0f64, 0usize);
        for (a, b) in i.train.iter().zip(&clean.train) {
            assert_eq!(a.camera, b.camera);
            assert_eq!(a.alpha, b.alpha);
            for ((ca, cb), &alpha) in a.color.iter().zip(&b.color).zip(&b.alpha) {
                for k in 0..3 {
                    assert!(ca[k] >= 0.0 && ca[k] <= alpha, "{ca:?} {alpha}");
                    if alpha == 0.0 {
                        assert_eq!(ca[k], cb[k]);
                    } else if alpha > 0.99 && cb[k] > 0.2 && cb[k] < 0.8 {
                        sq += f64::from((ca[k] - cb[k]) / alpha).powi(2);
                        count += 1;
                    }
                }
            }
        }
        let rms = (sq / count as f64).sqrt();
        assert!((rms - 0.05).abs() < 0.01, "{rms} over {count}");
    }
}

#[test]
fn noise_levels_out_of_range_are_errors_naming_the_field() {
    for (noise, field) in [
        (
            CaptureNoise {
                pose: -0.1,
                image: 0.0,
            },
            "noise.pose",
        ),
        (
            CaptureNoise {
                pose: f32::NAN,
                image: 0.0,
            },
            "noise.pose",
        ),
        (
            CaptureNoise {
                pose: 0.0,
                image: 1.5,
            },
            "noise.image",
        ),
    ] {
        let err = generate(&small(Preset::Wave).with_noise(noise), 0).unwrap_err();
        let text = err.to_string();
        assert!(
            text.starts_with(&format!("scene spec field `{field}`")),
            "{text}"
        );
        assert_eq!(text.lines().count(), 1);
    }
}

mod varied {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]

        /// Any preset, seed, frame count and size: a valid scene with sane images and times.
        #[test]
        fn any_small_scene_is_well_formed(
            preset in prop::sample::select(Preset::ALL.to_vec()),
            seed in any::<u64>(),
            frames in 3usize..14,
            size in 8u32..24,
        ) {
            let spec = SceneSpec::preset(preset)
                .with_size(size)
                .with_frames(frames)
                .with_gaussian_scale(0.05);
            let scene = generate(&spec, seed).unwrap();
            prop_assert_eq!(scene.train.len(), frames);
            let traj = &scene.trajectories;
            prop_assert!(traj.times.windows(2).all(|w| w[0] < w[1]));
            prop_assert_eq!(traj.means.len(), traj.times.len());
            for split in Split::ALL {
                for f in scene.split(split) {
                    prop_assert!((0.0..=1.0).contains(&f.time));
                    prop_assert!(traj.times.contains(&f.time));
                    prop_assert_eq!(f.color.len(), (size * size) as usize);
                    for (c, &a) in f.color.iter().zip(&f.alpha) {
                        prop_assert!((0.0..=1.0).contains(&a));
                        prop_assert!(c.iter().all(|v| v.is_finite() && *v >= 0.0 && *v <= a + 1e-4));
                    }
                }
            }
            // The object is in view in every training frame.
            prop_assert!(scene.train.iter().all(|f| f.alpha.iter().any(|&a| a > 0.5)));
        }
    }
}
