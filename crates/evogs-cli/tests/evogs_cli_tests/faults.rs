//! Nothing lost under faults, through the `evogs` binary on a small synthetic scene:
//! - SIGKILL at random moments (seeded), with a checkpoint written at every iteration so that
//!   kills land while one is being written, resumed after every kill: the run ends bit for bit
//!   where an uninterrupted run ends, every checkpoint and evolution state found on disk after a
//!   kill is readable, and a checkpoint never goes back to an earlier iteration;
//! - a full disk (a file-size limit, `ulimit -f`, with SIGXFSZ ignored so that writes fail with
//!   EFBIG as they fail with ENOSPC): a one-line error naming the file, the previous checkpoint
//!   intact, and a resume once space is back ends bit for bit like the uninterrupted run.

use crate::support;

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Instant;

use evogs_train::checkpoint::load_checkpoint;
use evogs_train::run::{RunFile, RunPaths};
use evogs_train::state::SceneState;
use evogs_train::trainer::make_backbone;
use rand::{RngExt, SeedableRng};
use support::{one_line_error, rigid_scene, s, stderr};

/// The files of a finished run that must match the uninterrupted run's byte for byte.
const FINAL_FILES: [&str; 4] = [
    "checkpoint.safetensors",
    "evo_state.safetensors",
    "canonical.ply",
    "deform.safetensors",
];

/// A small dynamic scene (rigid motion, 8 training frames of 24×24) in `dir/scene`.
fn scene(dir: &Path) -> PathBuf {
    rigid_scene(dir, 24, 8)
}

/// `evogs train` of an EvoGS run of the tiny preset (warm-up, network, evolution and
/// densification all happen within `iterations`), or its resume.
fn train_args(data: &Path, out: &Path, iterations: u64, checkpoint_every: u64) -> Vec<String> {
    [
        "train",
        "--out",
        s(out),
        "--data",
        s(data),
        "--preset",
        "tiny",
        "--method",
        "evogs",
        "--iterations",
        &iterations.to_string(),
        "--checkpoint-every",
        &checkpoint_every.to_string(),
    ]
    .map(String::from)
    .to_vec()
}

fn resume_args(out: &Path) -> Vec<String> {
    ["train", "--out", s(out), "--resume"]
        .map(String::from)
        .to_vec()
}

fn command(args: &[String]) -> Command {
    let mut c = support::command();
    c.args(args).stdout(Stdio::null()).stderr(Stdio::piped());
    c
}

/// Runs `args` to the end; panics when it fails.
fn finish(args: &[String]) {
    let o = command(args).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A tensor of a safetensors file: name, dtype, shape, bytes.
type Tensor = (String, String, Vec<usize>, Vec<u8>);

/// The tensors of a safetensors file (name, dtype, shape, bytes) and its metadata, sorted: what
/// the file holds, whatever order its writer's hash map put the metadata in (evo-state's state
/// has many metadata keys, so two equal states can differ in their header's byte order).
fn safetensors_content(bytes: &[u8]) -> (Vec<Tensor>, Vec<(String, String)>) {
    let (_, metadata) = safetensors::SafeTensors::read_metadata(bytes).unwrap();
    let mut meta: Vec<(String, String)> = metadata
        .metadata()
        .clone()
        .unwrap_or_default()
        .into_iter()
        .collect();
    meta.sort();
    let file = safetensors::SafeTensors::deserialize(bytes).unwrap();
    let mut tensors: Vec<_> = file
        .tensors()
        .into_iter()
        .map(|(name, t)| {
            (
                name,
                format!("{:?}", t.dtype()),
                t.shape().to_vec(),
                t.data().to_vec(),
            )
        })
        .collect();
    tensors.sort();
    (tensors, meta)
}

/// The finished run `run` has the same final files as `straight`, bit for bit (safetensors
/// files: every tensor's bytes and the metadata), and nothing an interrupted write left behind.
fn assert_same_end(straight: &Path, run: &Path) {
    for name in FINAL_FILES {
        let a = std::fs::read(straight.join(name)).unwrap();
        let b = std::fs::read(run.join(name)).unwrap();
        if name.ends_with(".safetensors") {
            let (ta, ma) = safetensors_content(&a);
            let (tb, mb) = safetensors_content(&b);
            assert_eq!(
                ma, mb,
                "{name}'s metadata differs from the uninterrupted run's"
            );
            for (x, y) in ta.iter().zip(&tb) {
                assert!(
                    x == y,
                    "{name}: tensor `{}` differs from the uninterrupted run's",
                    x.0
                );
            }
            assert_eq!(ta.len(), tb.len(), "{name}'s tensors");
        } else {
            assert!(a == b, "{name} differs from the uninterrupted run's");
        }
    }
    let leftovers: Vec<String> = std::fs::read_dir(run)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| interrupted_write(n))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

/// A temporary file of an atomic write, or an evolution state still pending.
fn interrupted_write(name: &str) -> bool {
    name.starts_with(evogs_io::atomic::TEMP_PREFIX)
        || (name.starts_with("evo_state.") && name != "evo_state.safetensors")
}

/// Loads the checkpoint of `run` and every evolution state file in it (committed or pending);
/// returns the checkpoint's iteration, `None` when the run has no checkpoint yet. Panics when a
/// file is unreadable.
fn read_back(run: &Path) -> Option<u64> {
    let paths = RunPaths::new(run);
    if !paths.config().is_file() || !paths.checkpoint().is_file() {
        return None;
    }
    let file: RunFile =
        serde_json::from_str(&std::fs::read_to_string(paths.config()).unwrap()).unwrap();
    let config = file.train;
    let mut backbone = make_backbone(&config).unwrap();
    let init = evogs_train::init::random_gaussians(1, 1.0, config.sh_degree, 0);
    let mut state = SceneState::new(init, backbone.as_ref(), &config.lr).unwrap();
    let meta = load_checkpoint(&paths.checkpoint(), &mut state, backbone.as_mut())
        .unwrap_or_else(|e| panic!("unreadable checkpoint: {e}"));
    for entry in std::fs::read_dir(run).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if name.starts_with("evo_state.") && name.ends_with(".safetensors") {
            backbone
                .load_state(&path)
                .unwrap_or_else(|e| panic!("unreadable evolution state: {e}"));
        }
    }
    Some(meta.iteration)
}

#[test]
fn sigkill_at_random_moments_then_resume_ends_bit_for_bit_like_an_uninterrupted_run() {
    /// Kills to survive before the run may finish, and of them how many at least must have
    /// landed while a checkpoint was being written (a temporary or pending file left behind).
    const KILLS: usize = 8;
    const KILLS_MID_WRITE: usize = 2;
    const ITERATIONS: u64 = 60;
    let dir = tempfile::tempdir().unwrap();
    let data = scene(dir.path());
    let straight = dir.path().join("straight");
    let started = Instant::now();
    finish(&train_args(&data, &straight, ITERATIONS, 1));
    let whole = started.elapsed();

    let run = dir.path().join("killed");
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
    let (mut kills, mut mid_write, mut last_checkpoint) = (0, 0, 0);
    let mut attempts = 0;
    while kills < KILLS || mid_write < KILLS_MID_WRITE {
        attempts += 1;
        assert!(
            attempts <= 80,
            "only {kills} kills, {mid_write} while writing, in {attempts} attempts"
        );
        // Resume when there is a checkpoint, else start (again): what a user does.
        let args = if RunPaths::new(&run).checkpoint().is_file() {
            resume_args(&run)
        } else {
            train_args(&data, &run, ITERATIONS, 1)
        };
        let mut child = command(&args).spawn().unwrap();
        // A moment within what is left of the run, its start-up included.
        let left = 1.0 - last_checkpoint as f64 / ITERATIONS as f64;
        let fraction = rng.random_range(0.0..1.0) * (0.15 + 0.85 * left);
        std::thread::sleep(whole.mul_f64(fraction));
        if child.try_wait().unwrap().is_some() {
            // It finished first: train again from nothing to keep killing.
            let o = child.wait_with_output().unwrap();
            assert!(o.status.success(), "{}", stderr(&o));
            std::fs::remove_dir_all(&run).unwrap();
            last_checkpoint = 0;
            continue;
        }
        child.kill().unwrap();
        child.wait().unwrap();
        kills += 1;
        mid_write += usize::from(
            std::fs::read_dir(&run)
                .unwrap()
                .any(|e| interrupted_write(&e.unwrap().file_name().to_string_lossy())),
        );
        if let Some(iteration) = read_back(&run) {
            assert!(
                iteration >= last_checkpoint,
                "the checkpoint went back from iteration {last_checkpoint} to {iteration}"
            );
            last_checkpoint = iteration;
        }
    }
    finish(&resume_args(&run));
    eprintln!(
        "{kills} kills survived ({mid_write} while a checkpoint was being written) in \
         {attempts} attempts"
    );
    assert_same_end(&straight, &run);
}

/// Runs `args` with files limited to `kib` KiB (`ulimit -f`; SIGXFSZ ignored, so a write past
/// the limit fails with EFBIG instead of killing the process).
fn with_file_limit(kib: u64, args: &[String]) -> Output {
    Command::new("bash")
        .arg("-c")
        .arg(r#"trap "" XFSZ; ulimit -f "$1"; shift; exec "$@""#)
        .arg("bash")
        .arg(kib.to_string())
        .arg(support::BIN)
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn a_full_disk_names_the_file_keeps_the_previous_checkpoint_and_resumes_once_space_is_back() {
    const ITERATIONS: u64 = 40;
    let dir = tempfile::tempdir().unwrap();
    let data = scene(dir.path());
    let straight = dir.path().join("straight");
    finish(&train_args(&data, &straight, ITERATIONS, 10));

    let run = dir.path().join("full");
    let mut first = train_args(&data, &run, ITERATIONS, 10);
    first.extend(["--stop-after".into(), "20".into()]);
    finish(&first);
    let paths = RunPaths::new(&run);
    let checkpoint = std::fs::read(paths.checkpoint()).unwrap();
    let state = std::fs::read(paths.evo_state()).unwrap();
    // Room for the small files (config, log), not for a checkpoint.
    let limit_kib = (checkpoint.len() as u64 / 1024) / 2;
    assert!(limit_kib > 8, "the checkpoint is too small for this test");
    let o = with_file_limit(limit_kib, &resume_args(&run));
    let all = stderr(&o);
    assert!(!o.status.success(), "training went through a full disk");
    // Besides the progress lines, one error line.
    let errors: Vec<&str> = all.lines().filter(|l| l.contains("error")).collect();
    assert_eq!(errors.len(), 1, "{all}");
    let err = errors[0];
    assert!(err.starts_with("evogs: error: "), "{all}");
    assert!(
        err.contains("checkpoint.safetensors") || err.contains("evo_state."),
        "the error names no file: {err}"
    );
    assert!(err.contains("too large"), "{err}");
    // The previous checkpoint and its evolution state are intact.
    assert_eq!(std::fs::read(paths.checkpoint()).unwrap(), checkpoint);
    assert_eq!(std::fs::read(paths.evo_state()).unwrap(), state);
    assert_eq!(read_back(&run), Some(20));
    // Space is back: the run resumes and ends as if nothing happened.
    finish(&resume_args(&run));
    assert_same_end(&straight, &run);
}

/// The number after `prefix` in `text`.
fn number_after(text: &str, prefix: &str) -> Option<usize> {
    let rest = &text[text.find(prefix)? + prefix.len()..];
    let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
    digits.parse().ok()
}

/// Runs `args` with the address space limited to `kib` KiB (`ulimit -v`): an allocation past it
/// fails, and Rust aborts the process on a failed allocation.
fn with_address_space_limit(kib: u64, args: &[&str]) -> Output {
    Command::new("bash")
        .arg("-c")
        .arg(r#"ulimit -v "$1"; shift; exec "$@""#)
        .arg("bash")
        .arg(kib.to_string())
        .arg(support::BIN)
        .args(args)
        .output()
        .unwrap()
}

/// The memory limit is checked before anything is allocated (issue F2: the networks were
/// allocated first, `--net-width 99999 --memory-limit 1G` aborted allocating 120 GB): networks of
/// 1 to 24 GiB, asked for by flags or by an edited `config.json`, are refused in one line naming
/// the setting, by a process whose address space (800 MiB) could not have held the two larger; a
/// network
/// larger than the memory this machine has is refused without a limit too, naming the flag.
#[test]
fn the_memory_limit_refuses_large_networks_before_allocating_them() {
    let dir = tempfile::tempdir().unwrap();
    let data = scene(dir.path());
    let huge: [&[&str]; 3] = [
        &["--net-width", "2048"], // 197 MiB at the tiny preset's depth
        &[
            "--backbone",
            "scgs",
            "--control-width",
            "2048",
            "--control-depth",
            "64",
        ],
        &[
            "--method",
            "evogs",
            "--triplane-resolutions",
            "1024,1024,1024,1024",
            "--triplane-channels",
            "128",
        ],
    ];
    for (k, extra) in huge.iter().enumerate() {
        let out = dir.path().join(format!("huge{k}"));
        let mut args = vec![
            "train",
            "--data",
            s(&data),
            "--out",
            s(&out),
            "--preset",
            "tiny",
        ];
        args.extend_from_slice(extra);
        args.extend(["--memory-limit", "100M"]);
        let e = one_line_error(&with_address_space_limit(800 << 10, &args));
        assert!(e.contains("memory_limit"), "{extra:?}: {e}");
        // The two larger networks (1 and 24 GiB) could not have been allocated in the
        // address space the process had.
        assert!(k == 0 || e.contains("GiB"), "{extra:?}: {e}");
        assert!(!out.join("checkpoint.safetensors").exists());
    }
    // 24 GiB of tri-planes without a limit: more than this machine has available (the CI
    // machines have 24 GiB in all), so refused, naming the flag that sets the limit.
    let out = dir.path().join("unlimited");
    let mut args = vec![
        "train",
        "--data",
        s(&data),
        "--out",
        s(&out),
        "--preset",
        "tiny",
    ];
    args.extend_from_slice(huge[2]);
    let available = evogs_train::memory::available_memory().unwrap_or(u64::MAX);
    if available < 24 << 30 {
        let e = one_line_error(&with_address_space_limit(800 << 10, &args));
        assert!(
            e.contains("available") && e.contains("--memory-limit"),
            "{e}"
        );
    }
    // A trained run whose config.json was edited to a network that does not fit its recorded
    // limit: eval and resume refuse it the same way, before allocating it.
    let run = dir.path().join("small");
    let mut args = train_args(&data, &run, 2, 1);
    args.extend(["--memory-limit".into(), "1G".into()]);
    support::ok(&support::command().args(&args).output().unwrap());
    let config = run.join("config.json");
    let text = std::fs::read_to_string(&config).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json["train"]["evogs"]["triplane_channels"] = 128.into();
    json["train"]["evogs"]["triplane_resolutions"] = serde_json::json!([1024, 1024, 1024]);
    std::fs::write(&config, serde_json::to_string_pretty(&json).unwrap()).unwrap();
    for args in [
        vec!["eval", "--run", s(&run), "--split", "test"],
        vec!["train", "--out", s(&run), "--resume"],
    ] {
        let e = one_line_error(&with_address_space_limit(800 << 10, &args));
        assert!(e.contains("GiB") && e.contains("limit"), "{args:?}: {e}");
    }
}

#[test]
fn a_memory_limit_refuses_to_start_below_the_estimate_and_caps_densification_above_it() {
    const ITERATIONS: u64 = 40;
    let dir = tempfile::tempdir().unwrap();
    let data = scene(dir.path());
    let run = |name: &str, limit: Option<&str>| {
        let mut args = train_args(&data, &dir.path().join(name), ITERATIONS, 10);
        if let Some(limit) = limit {
            args.extend(["--memory-limit".into(), limit.into()]);
        }
        support::command().args(&args).output().unwrap()
    };
    let free = run("free", None);
    assert!(free.status.success(), "{}", stderr(&free));
    let out = String::from_utf8_lossy(&free.stdout).into_owned();
    assert!(out.contains("memory estimate: "), "{out}");
    let grown = number_after(&out, "at the most Gaussians (").unwrap();
    let start = number_after(&out, " MiB with ").unwrap();
    assert!(
        grown > start,
        "densification must grow the run for this test: {out}"
    );

    let o = run("small", Some("1M"));
    assert!(!o.status.success());
    let err = stderr(&o);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.contains("memory_limit") && err.contains("needs"),
        "{err}"
    );
    assert!(!dir.path().join("small/checkpoint.safetensors").exists());

    // A limit 2 MiB above the estimate at the start: densification stops at the count that fits.
    let at_start: f64 = out["memory estimate: ".len() + out.find("memory estimate: ").unwrap()..]
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    let o = run("capped", Some(&format!("{:.1}M", at_start + 2.0)));
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    let cap = number_after(&out, "densification stops at ").unwrap();
    assert!(start <= cap && cap < grown, "{out}");
    let most = number_after(&out, "at the most Gaussians (").unwrap();
    assert!(most <= cap, "{out}");

    // Keeping freed memory (glibc's default) changes nothing the run writes, and cannot be
    // combined with a limit, given or recorded in the run.
    let mut args = train_args(&data, &dir.path().join("kept"), ITERATIONS, 10);
    args.push("--keep-freed-memory".into());
    let o = support::command().args(&args).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let ply = |name: &str| std::fs::read(dir.path().join(name).join("canonical.ply")).unwrap();
    assert!(
        ply("kept") == ply("free"),
        "the allocator changed the result"
    );
    args.extend(["--memory-limit".into(), "1G".into()]);
    let e = one_line_error(&support::command().args(&args).output().unwrap());
    assert!(
        e.contains("--keep-freed-memory") && e.contains("--memory-limit"),
        "{e}"
    );
    let capped = dir.path().join("capped");
    let o = support::evogs(&[
        "train",
        "--out",
        s(&capped),
        "--resume",
        "--keep-freed-memory",
    ]);
    let e = one_line_error(&o);
    assert!(e.contains(s(&capped.join("config.json"))), "{e}");
}
