#!/usr/bin/env python3
"""Issue 15: fixed-camera flicker against ground truth for trained runs of a monocular synthetic
scene. `evogs synth --protocol monocular` writes SCENE/fixed/ (every training time seen from one
fixed camera, never noisy); this makes SCENE-fixed/ (that sequence as a train and a test split),
points a copy of each run at it and runs `evogs eval --split train`: the split's views share one
camera, so the eval reports flicker of the render, of the ground truth, and their difference
(excess), plus PSNR on the fixed-camera views and trajectory jitter.
usage: fixed_flicker.py SCENE OUT EVOGS ROW/seedS=RUN...   (a markdown table per run, then per row the
mean ± sample std over seeds and the differences to `phi` paired per seed)"""
import json, os, shutil, statistics, subprocess, sys
from pathlib import Path

scene, out, evogs = Path(sys.argv[1]).resolve(), Path(sys.argv[2]), sys.argv[3]
fixed = scene.parent / (scene.name + "-fixed")
if not fixed.exists():
    fixed.mkdir()
    os.symlink(scene / "fixed" / "train", fixed / "train")
    for split in ("train", "test"):
        shutil.copy(scene / "fixed" / "transforms_train.json", fixed / f"transforms_{split}.json")
print("| run | fixed-camera PSNR (dB) | flicker rendered | flicker ground truth | flicker excess | jitter |")
print("| --- | ---: | ---: | ---: | ---: | ---: |")
scores = {}
for arg in sys.argv[4:]:
    label, run = arg.split("=", 1)
    d = out / label.replace("/", "_")
    if d.exists():
        shutil.rmtree(d)
    shutil.copytree(run, d, ignore=shutil.ignore_patterns("renders", "eval_*"))
    cfg = json.loads((d / "config.json").read_text())
    cfg["data"] = str(fixed)
    (d / "config.json").write_text(json.dumps(cfg, indent=1))
    subprocess.run([evogs, "eval", "--run", str(d), "--split", "train"], check=True, stdout=subprocess.DEVNULL)
    r = json.loads((d / "eval_train.json").read_text())
    t = r["temporal"]
    print(f"| {label} | {r['mean_psnr']:.2f} | {t['flicker_rendered']:.3e} | {t['flicker_ground_truth']:.3e} | {t['flicker_excess']:+.3e} | {t['jitter']:.3e} |")
    shutil.rmtree(d / "renders", ignore_errors=True)
    row, seed = label.split("/seed")
    scores.setdefault(row, {})[int(seed)] = (r["mean_psnr"], t["flicker_excess"], t["jitter"])

def ms(v, fmt):
    if len(v) == 1:
        return fmt.format(v[0]) + " (1 seed)"
    return fmt.format(statistics.mean(v)) + " ± " + fmt.format(statistics.stdev(v)).lstrip("+")

print()
print("| row | seeds | fixed-camera PSNR (dB) | flicker excess | jitter | PSNR − phi (paired) | excess − phi (paired) |")
print("| --- | --- | ---: | ---: | ---: | ---: | ---: |")
for row, by_seed in scores.items():
    seeds = sorted(by_seed)
    col = lambda i: [by_seed[s][i] for s in seeds]
    common = [s for s in seeds if s in scores.get("phi", {})]
    dp = [by_seed[s][0] - scores["phi"][s][0] for s in common]
    de = [by_seed[s][1] - scores["phi"][s][1] for s in common]
    diff = row != "phi" and common
    print(f"| {row} | {','.join(map(str, seeds))} | {ms(col(0), '{:.2f}')} | {ms(col(1), '{:+.2e}')} | {ms(col(2), '{:.2e}')} | "
          f"{ms(dp, '{:+.2f}') if diff else '-'} | {ms(de, '{:+.2e}') if diff else '-'} |")
