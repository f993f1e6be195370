//! One picture of bench runs of one scene made by several `evogs bench` calls (a D-3DGS run, an
//! SC-GS run, an EvoGS(SC-GS) run, ...): ground truth, then each run in the order given, at the
//! earliest, middle and latest time of the scene's headline split. The picture `evogs bench`
//! draws for the methods of one call ([`evogs_experiments::bench::write_picture`]), written as
//! `OUT_DIR/<scene>.png`.
//!
//! ```sh
//! cargo run --release -p evogs-experiments --example bench_picture -- \
//!     OUT_DIR DATA/dnerf-jumpingjacks RUN_DIR...
//! ```
//!
//! Each `RUN_DIR` is a bench run's directory (`<bench out>/<scene>/<method>`, holding its
//! `bench_run.json`).

use std::path::PathBuf;

use evogs_experiments::bench::{BenchScene, read_run_record, write_picture};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    let [out, data, runs @ ..] = args.as_slice() else {
        return Err("usage: bench_picture OUT_DIR DATA_DIR RUN_DIR...".into());
    };
    if runs.is_empty() {
        return Err("usage: bench_picture OUT_DIR DATA_DIR RUN_DIR... (no run given)".into());
    }
    let scene = BenchScene::from_dir(data);
    let mut records = Vec::with_capacity(runs.len());
    for dir in runs {
        let mut record = read_run_record(dir)?;
        // The record names the run where it was trained; the directory given is where it is.
        record.run.clone_from(dir);
        record.scene.clone_from(&scene.name);
        records.push(record);
    }
    std::fs::create_dir_all(out)?;
    write_picture(out, &scene, &records)?;
    println!("{}", out.join(format!("{}.png", scene.name)).display());
    Ok(())
}
