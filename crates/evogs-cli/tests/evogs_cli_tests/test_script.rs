//! `scripts/test`'s Vulkan decisions, by dry runs over made-up driver directories: install
//! lavapipe when there is no Vulkan driver at all; pin it (any architecture's manifest) in CI or
//! when no hardware driver can be used; otherwise leave the adapter to wgpu.

use std::path::Path;
use std::process::Command;

/// Runs `scripts/test` as a dry run with `icd_dirs` and `gpu_nodes` standing in for the system's;
/// returns its standard output.
fn dry_run(icd_dirs: &[&Path], gpu_nodes: &[&Path], ci: bool) -> String {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scripts/test");
    let join = |ps: &[&Path]| {
        ps.iter()
            .map(|p| p.to_str().unwrap())
            .collect::<Vec<_>>()
            .join(" ")
    };
    let mut cmd = Command::new("bash");
    cmd.arg(script)
        .env("EVOGS_TEST_DRY_RUN", "1")
        .env("EVOGS_TEST_ICD_DIRS", join(icd_dirs))
        // An empty list would mean "the defaults": name a path that does not exist instead.
        .env(
            "EVOGS_TEST_GPU_NODES",
            if gpu_nodes.is_empty() {
                "/nonexistent/gpu-node".to_string()
            } else {
                join(gpu_nodes)
            },
        )
        .env_remove("VK_DRIVER_FILES")
        .env_remove("WGPU_BACKEND")
        .env_remove("CI");
    if ci {
        cmd.env("CI", "true");
    }
    let o = cmd.output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn touch(p: &Path) {
    std::fs::create_dir_all(p.parent().unwrap()).unwrap();
    std::fs::write(p, "{}").unwrap();
}

#[test]
fn pins_lavapipe_without_a_usable_hardware_driver_or_in_ci() {
    let dir = tempfile::tempdir().unwrap();
    let icd = dir.path().join("icd.d");
    let lvp = icd.join("lvp_icd.x86_64.json");
    touch(&lvp);
    touch(&icd.join("intel_icd.x86_64.json"));
    let node = dir.path().join("renderD128");
    let pinned = format!("VK_DRIVER_FILES={} WGPU_BACKEND=vulkan", lvp.display());

    // A hardware manifest but no GPU device node (this machine): lavapipe.
    let out = dry_run(&[&icd], &[], false);
    assert!(out.contains("wgpu pinned to lavapipe"), "{out}");
    assert!(out.contains(&format!("dry run; {pinned}")), "{out}");

    // A GPU as well: wgpu chooses.
    touch(&node);
    let out = dry_run(&[&icd], &[&node], false);
    assert!(out.contains("hardware Vulkan driver present"), "{out}");
    assert!(
        out.contains("dry run; VK_DRIVER_FILES= WGPU_BACKEND="),
        "{out}"
    );

    // In CI, lavapipe even beside a GPU.
    let out = dry_run(&[&icd], &[&node], true);
    assert!(out.contains(&format!("dry run; {pinned}")), "{out}");
}

#[test]
fn finds_other_architectures_and_installs_when_there_is_no_driver() {
    let dir = tempfile::tempdir().unwrap();
    let arm = dir.path().join("arm");
    let lvp = arm.join("lvp_icd.aarch64.json");
    touch(&lvp);
    let out = dry_run(&[&dir.path().join("missing"), &arm], &[], false);
    assert!(
        out.contains(&format!(
            "dry run; VK_DRIVER_FILES={} WGPU_BACKEND=vulkan",
            lvp.display()
        )),
        "{out}"
    );
    assert!(!out.contains("installing"), "{out}");

    let empty = dir.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let out = dry_run(&[&empty], &[], false);
    assert!(
        out.contains("no Vulkan driver found; installing Mesa's lavapipe"),
        "{out}"
    );
    assert!(out.contains("would pin lavapipe"), "{out}");
}
