//! Every fuzz target replayed on the stable toolchain, as part of the workspace's tests (the
//! libFuzzer runs themselves need nightly and minutes of build, `scripts/fuzz`): each target's
//! body runs on
//! - its seeds (written by the project's writers), which its reader must accept: a seed the
//!   reader refuses means a writer and its reader disagree, and fuzzing would start from
//!   rejected inputs;
//! - every truncation of each seed (a killed write leaves a truncated file), which must not panic;
//! - every regression input in `tests/data/<target>/` (each failure fuzzing or review ever found,
//!   see `tests/data/README.md`), which must not panic.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use evogs_fuzz::{TARGETS, Target, write_all_seeds};

/// The folder of the regression inputs, one subfolder per target.
const REGRESSIONS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data");

/// The files of `dir`, sorted; none when it does not exist.
fn files(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut out: Vec<PathBuf> = entries
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .collect();
    out.sort();
    out
}

/// Runs `target` on `data`; a panic names the target and `what` the input was.
fn run(target: Target, data: &[u8], what: &str) -> bool {
    catch_unwind(AssertUnwindSafe(|| (target.run)(data)))
        .unwrap_or_else(|_| panic!("fuzz target `{}` panicked on {what}", target.name))
}

/// At most this many truncations of each seed (every length when the seed is shorter).
const MAX_TRUNCATIONS: usize = 1024;

fn replay(name: &str) {
    let target = *TARGETS
        .iter()
        .find(|t| t.name == name)
        .unwrap_or_else(|| panic!("no fuzz target `{name}` in evogs_fuzz::TARGETS"));
    let dir = tempfile::tempdir().unwrap();
    write_all_seeds(dir.path());
    let seeds = files(&dir.path().join(name));
    assert!(!seeds.is_empty(), "no seeds for `{name}`");
    let mut truncations = 0;
    for seed in &seeds {
        let bytes = std::fs::read(seed).unwrap();
        let label = seed.file_name().unwrap().to_string_lossy();
        assert!(
            run(target, &bytes, &format!("seed {label}")),
            "`{name}` refuses its seed {label}"
        );
        let stride = bytes.len().div_ceil(MAX_TRUNCATIONS).max(1);
        for len in (0..bytes.len()).step_by(stride) {
            truncations += 1;
            run(
                target,
                &bytes[..len],
                &format!("seed {label} cut to {len} of {} bytes", bytes.len()),
            );
        }
    }
    let regressions = files(&Path::new(REGRESSIONS).join(name));
    for input in &regressions {
        let bytes = std::fs::read(input).unwrap();
        run(
            target,
            &bytes,
            &format!("regression input {}", input.display()),
        );
    }
    eprintln!(
        "{name}: {} seeds, {truncations} truncations, {} regression inputs",
        seeds.len(),
        regressions.len()
    );
}

/// One test per target (they run in parallel; each thread has its own scratch directory).
macro_rules! replay_tests {
    ($($name:ident),* $(,)?) => {
        $(
            #[test]
            fn $name() {
                replay(stringify!($name));
            }
        )*

        /// The names of the targets replayed above.
        const REPLAYED: &[&str] = &[$(stringify!($name)),*];
    };
}

replay_tests!(
    ply,
    nerfies_camera,
    nerfies_dataset,
    dnerf_transforms,
    colmap_bin,
    colmap_txt,
    npy,
    nerfstudio,
    evo_state,
    camera_path,
    point_cloud,
    splat,
    compressed_ply,
    checkpoint,
);

/// The same targets everywhere: `evogs_fuzz::TARGETS`, the tests above, the libFuzzer targets
/// (`fuzz/fuzz_targets/*.rs`) and `scripts/fuzz`'s default list, so that no reader is fuzzed
/// but not replayed, or the reverse.
#[test]
fn every_target_is_fuzzed_and_replayed() {
    let mut listed: Vec<&str> = TARGETS.iter().map(|t| t.name).collect();
    listed.sort_unstable();
    let mut replayed = REPLAYED.to_vec();
    replayed.sort_unstable();
    assert_eq!(listed, replayed, "TARGETS against the replay tests");

    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut fuzzed: Vec<String> = files(&root.join("fuzz/fuzz_targets"))
        .iter()
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    fuzzed.sort_unstable();
    assert_eq!(listed, fuzzed, "TARGETS against fuzz/fuzz_targets");

    let script = std::fs::read_to_string(root.join("scripts/fuzz")).unwrap();
    let line = script
        .lines()
        .find_map(|l| {
            l.trim()
                .strip_prefix("targets=(")
                .filter(|rest| *rest != ")")
        })
        .expect("scripts/fuzz: a `targets=(...)` line");
    let mut scripted: Vec<&str> = line.trim_end_matches(')').split_whitespace().collect();
    scripted.sort_unstable();
    assert_eq!(listed, scripted, "TARGETS against scripts/fuzz");
}

/// The regression input of the one reader failure found so far (by review, before fuzzing ran;
/// fixed in 107750a): the tiny seed checkpoint with its header's Gaussian count raised to
/// 6 148 914 691 236 517 206 (above `usize::MAX / 3`). Before the fix, `load_checkpoint` sized
/// its reads from the count before comparing it with the file, and `count * 3` overflowed (a
/// panic with overflow checks, a wrapped size without). It must be refused, naming the field.
#[test]
fn checkpoint_counting_more_gaussians_than_its_bytes_is_refused() {
    let path = Path::new(REGRESSIONS).join("checkpoint/gaussians_beyond_file.safetensors");
    let (mut state, mut backbone) = evogs_fuzz::seeds::tiny_state();
    let err = evogs_train::checkpoint::load_checkpoint(&path, &mut state, backbone.as_mut())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("gaussians") && err.contains("6148914691236517206 Gaussians cannot fit"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");
}
