//! Any one mutation of a valid `config.json` yields an error or a run, never a panic or an
//! abort (issue F2: ten edited values made `eval`, `render` or `train --resume` abort).
//!
//! The configurations are those of the `run` fuzz target's template runs (EvoGS and the
//! baseline, trained for two iterations on the repository's lego fixture). A mutation replaces
//! one value anywhere in the file (numbers at the edges of every integer and float type,
//! strings, null, booleans, arrays, objects) or removes one field. The result is read as every
//! command reads a run ([`evogs_fuzz::targets::config`]: parse, ranges, parameter count, memory
//! estimate, the backbone when small) and, when it is accepted, trained for one iteration on
//! the fixture under a 512 MiB memory limit: the run starts or refuses in one error.
#![cfg(feature = "checkpoint")]

use std::path::Path;

use proptest::prelude::*;
use serde_json::Value;

/// One step of a path into a JSON document.
#[derive(Clone, Debug)]
enum Key {
    Field(String),
    Index(usize),
}

/// The paths of every value in `v` (objects and arrays included), depth first.
fn paths(v: &Value, prefix: &mut Vec<Key>, out: &mut Vec<Vec<Key>>) {
    out.push(prefix.clone());
    match v {
        Value::Object(map) => {
            for (k, child) in map {
                prefix.push(Key::Field(k.clone()));
                paths(child, prefix, out);
                prefix.pop();
            }
        }
        Value::Array(items) => {
            for (i, child) in items.iter().enumerate() {
                prefix.push(Key::Index(i));
                paths(child, prefix, out);
                prefix.pop();
            }
        }
        _ => {}
    }
}

fn at<'a>(v: &'a mut Value, path: &[Key]) -> &'a mut Value {
    path.iter().fold(v, |v, k| match k {
        Key::Field(f) => &mut v[f.as_str()],
        Key::Index(i) => &mut v[*i],
    })
}

/// Values a hand edit or a corrupted file may put anywhere.
fn replacement() -> impl Strategy<Value = Value> {
    prop_oneof![
        Just(Value::from(0)),
        Just(Value::from(1)),
        Just(Value::from(-1)),
        Just(Value::from(65_535)),
        Just(Value::from(65_536)),
        Just(Value::from(2_147_483_647)),
        Just(Value::from(2_147_483_648u64)),
        Just(Value::from(4_294_967_296u64)),
        Just(Value::from(u64::MAX)),
        Just(Value::from(i64::MIN)),
        Just(Value::from(1e300)),
        Just(Value::from(-1e300)),
        Just(Value::from(1e-300)),
        Just(Value::from(0.5)),
        Just(Value::from(-0.0)),
        Just(Value::from("")),
        Just(Value::from("\u{1b}]0;title\u{7}")),
        Just(Value::Null),
        Just(Value::from(true)),
        Just(Value::Array(vec![])),
        Just(serde_json::json!([2_147_483_647, 1])),
        Just(serde_json::json!({})),
        any::<i64>().prop_map(Value::from),
        any::<f64>()
            .prop_filter("JSON numbers are finite", |f| f.is_finite())
            .prop_map(Value::from),
    ]
}

/// Trains the run whose `config.json` is `text` for one iteration on the fixture, under a
/// memory limit: Ok or one error.
fn one_iteration(dir: &Path, text: &[u8]) -> Result<(), String> {
    let run = dir.join("accepted");
    let _ = std::fs::remove_dir_all(&run);
    std::fs::create_dir_all(&run).unwrap();
    std::fs::write(run.join("config.json"), text).unwrap();
    let (_, file) = evogs_train::run::read_run_file(&run).map_err(|e| e.to_string())?;
    let mut config = file.train;
    config.memory_limit = Some(config.memory_limit.unwrap_or(u64::MAX).min(512 << 20));
    let request = evogs_train::run::TrainRequest {
        data: Path::new(evogs_fuzz::scratch::DNERF_FIXTURE).to_path_buf(),
        out: dir.join("trained"),
        config,
        resume: false,
        stop_after: Some(1),
        resume_backend: None,
        resume_net_backend: None,
    };
    let _ = std::fs::remove_dir_all(&request.out);
    evogs_train::run::train(&request, &mut |_, _| {})
        .map(|_| ())
        .map_err(|e| e.to_string())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    #[test]
    fn one_mutation_of_a_valid_config_is_an_error_or_a_run(
        evogs in any::<bool>(),
        pick in any::<prop::sample::Index>(),
        remove in prop::bool::weighted(0.2),
        value in replacement(),
    ) {
        let template = evogs_fuzz::seeds::template_run(evogs);
        let text = std::fs::read(template.join("config.json")).unwrap();
        let mut json: Value = serde_json::from_slice(&text).unwrap();
        let mut all = Vec::new();
        paths(&json, &mut Vec::new(), &mut all);
        let path = &all[pick.index(all.len())];
        match (remove, path.split_last()) {
            (true, Some((Key::Field(f), parent))) => {
                if let Value::Object(map) = at(&mut json, parent) {
                    map.remove(f);
                }
            }
            _ => *at(&mut json, path) = value,
        }
        let mutated = serde_json::to_vec_pretty(&json).unwrap();
        let accepted = evogs_fuzz::targets::config(&mutated);
        let dir = tempfile::tempdir().unwrap();
        let trained = one_iteration(dir.path(), &mutated);
        if let Err(e) = &trained {
            prop_assert!(!e.contains('\n'), "an error is one line: {e}");
        }
        // What the reader refuses, training refuses too (the same reader).
        prop_assert!(accepted || trained.is_err());
    }
}
