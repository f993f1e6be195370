//! Every fuzz target replayed on the stable toolchain, as part of the workspace's tests (the
//! libFuzzer runs themselves need nightly and minutes of build, `scripts/fuzz`): each target's
//! body runs on
//! - its seeds (written by the project's writers), which its reader must accept: a seed the
//!   reader refuses means a writer and its reader disagree, and fuzzing would start from
//!   rejected inputs;
//! - every truncation of each seed (a killed write leaves a truncated file), which must not panic;
//! - every regression input in `tests/data/<target>/` (each failure fuzzing or review ever found,
//!   see `tests/data/README.md`), which must not panic;
//! - a short mutation pass: [`MUTATIONS`] inputs per target (`EVOGS_FUZZ_MUTATIONS` overrides),
//!   each a seed changed by one to four of libFuzzer's kinds of mutation (bit flips, random and
//!   boundary bytes and integers, inserted, erased, copied and spliced ranges, digits and signs
//!   of text numbers), from a fixed seed, so that every CI run executes the same inputs. None may
//!   panic. It is not coverage-guided: the libFuzzer runs (`scripts/fuzz`, results/fuzz.md) are
//!   the fuzzing; this pass keeps each reader exercised beyond its seeds on every change.

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
fn run_target(target: Target, data: &[u8], what: &str) -> bool {
    catch_unwind(AssertUnwindSafe(|| (target.run)(data)))
        .unwrap_or_else(|_| panic!("fuzz target `{}` panicked on {what}", target.name))
}

/// At most this many truncations of each seed (every length when the seed is shorter).
const MAX_TRUNCATIONS: usize = 1024;

/// Mutated inputs per target in the mutation pass (the CI-sized pass: 20 000 a reader).
const MUTATIONS: usize = 20_000;

/// The mutation pass's size: `EVOGS_FUZZ_MUTATIONS` when set (e.g. 0 to skip it while working on
/// a reader, or millions for a longer stable-toolchain run), else [`MUTATIONS`].
fn mutations() -> usize {
    std::env::var("EVOGS_FUZZ_MUTATIONS").map_or(MUTATIONS, |v| {
        v.parse()
            .unwrap_or_else(|_| panic!("EVOGS_FUZZ_MUTATIONS: not a count: {v:?}"))
    })
}

/// SplitMix64: a small, fixed random stream (the pass must execute the same inputs every run).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (`n > 0`; the modulo bias is irrelevant here).
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// Values at the edges of integer and float ranges, as libFuzzer's "interesting values".
const BOUNDARY: [&[u8]; 12] = [
    &[0x00],
    &[0xFF],
    &[0x7F],
    &[0x80],
    &[0xFF, 0xFF],
    &[0x00, 0x80],
    &[0xFF, 0xFF, 0xFF, 0x7F],
    &[0x00, 0x00, 0x00, 0x80],
    &[0xFF, 0xFF, 0xFF, 0xFF],
    &[0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF],
    &[0x00, 0x00, 0x80, 0x7F], // f32 +inf
    &[0x00, 0x00, 0xC0, 0x7F], // f32 NaN
];

/// Text that breaks numbers and structure in the text formats (JSON, PLY headers, COLMAP txt).
const TOKENS: [&[u8]; 12] = [
    b"-",
    b"1e309",
    b"NaN",
    b"-0",
    b"99999999999999999999",
    b"\n",
    b"\"",
    b"{",
    b"]",
    b",",
    b"null",
    b"element vertex 4294967295\n",
];

/// One mutation of `data` in place; `other` is another seed of the target (for splicing).
fn mutate(rng: &mut Rng, data: &mut Vec<u8>, other: &[u8]) {
    let len = data.len();
    let at = |rng: &mut Rng| rng.below(len.max(1));
    match rng.below(9) {
        0 if len > 0 => {
            let i = at(rng);
            data[i] ^= 1 << rng.below(8);
        }
        1 if len > 0 => {
            let i = at(rng);
            data[i] = rng.next() as u8;
        }
        2 => {
            let v = BOUNDARY[rng.below(BOUNDARY.len())];
            let i = rng.below(len + 1);
            let end = (i + v.len()).min(len);
            data.splice(i..end, v.iter().copied());
        }
        3 => {
            let i = rng.below(len + 1);
            let n = 1 + rng.below(16);
            let bytes: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
            data.splice(i..i, bytes);
        }
        4 if len > 0 => {
            let i = at(rng);
            let n = 1 + rng.below((len - i).min(64));
            data.drain(i..i + n);
        }
        5 if len > 0 => {
            // Copy a range of the input over another place (repeated structure).
            let from = at(rng);
            let n = 1 + rng.below((len - from).min(64));
            let chunk = data[from..from + n].to_vec();
            let to = rng.below(len + 1);
            data.splice(to..to, chunk);
        }
        6 if !other.is_empty() => {
            // Splice: this input's head with another seed's tail.
            let cut = rng.below(len + 1);
            let from = rng.below(other.len());
            data.truncate(cut);
            data.extend_from_slice(&other[from..]);
        }
        7 => {
            let t = TOKENS[rng.below(TOKENS.len())];
            let i = rng.below(len + 1);
            data.splice(i..i, t.iter().copied());
        }
        _ => {
            // A digit or sign of a text number changed (or a random byte when there is none).
            let digits: Vec<usize> = (0..len)
                .filter(|&i| data[i].is_ascii_digit() || data[i] == b'-' || data[i] == b'.')
                .collect();
            if digits.is_empty() {
                if len > 0 {
                    let i = at(rng);
                    data[i] = rng.next() as u8;
                }
            } else {
                let i = digits[rng.below(digits.len())];
                data[i] = b"0123456789-.e"[rng.below(13)];
            }
        }
    }
}

/// The mutation pass of `target` over `seeds` (see the module's doc); returns its input count.
fn mutation_pass(target: Target, seeds: &[Vec<u8>]) -> usize {
    let count = mutations();
    // A different stream per target, the same every run.
    let mut rng = Rng(target.name.bytes().fold(0xCBF2_9CE4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x100_0000_01B3)
    }));
    for k in 0..count {
        let from = rng.below(seeds.len());
        let mut input = seeds[from].clone();
        let other = &seeds[rng.below(seeds.len())];
        for _ in 0..=rng.below(4) {
            mutate(&mut rng, &mut input, other);
        }
        run_target(
            target,
            &input,
            &format!("mutation {k} of seed {from} ({} bytes)", input.len()),
        );
    }
    count
}

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
    let mut seed_bytes = Vec::new();
    for seed in &seeds {
        let bytes = std::fs::read(seed).unwrap();
        seed_bytes.push(bytes.clone());
        let label = seed.file_name().unwrap().to_string_lossy();
        assert!(
            run_target(target, &bytes, &format!("seed {label}")),
            "`{name}` refuses its seed {label}"
        );
        let stride = bytes.len().div_ceil(MAX_TRUNCATIONS).max(1);
        for len in (0..bytes.len()).step_by(stride) {
            truncations += 1;
            run_target(
                target,
                &bytes[..len],
                &format!("seed {label} cut to {len} of {} bytes", bytes.len()),
            );
        }
    }
    let regressions = files(&Path::new(REGRESSIONS).join(name));
    for input in &regressions {
        let bytes = std::fs::read(input).unwrap();
        run_target(
            target,
            &bytes,
            &format!("regression input {}", input.display()),
        );
    }
    let mutated = mutation_pass(target, &seed_bytes);
    eprintln!(
        "{name}: {} seeds, {truncations} truncations, {} regression inputs, {mutated} mutations",
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
    weights,
    checkpoint,
    config,
    run,
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
