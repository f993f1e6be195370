#!/usr/bin/env python3
"""Where a run's error sits on a fixed-camera split (lego's val): the pixels the motion touches
against the rest, and a picture of it, for one run or several side by side.

The moving region is every pixel whose ground truth, at any of the split's times, differs from the
per-pixel median over the times by more than 0.1 in some channel, dilated by 3 pixels: with one
camera that is what the motion covers (lego: the shovel, its arms and what they uncover). Prints
the region's share of the pixels and of the squared error, and the mean PSNR with either region's
error removed. With --picture, writes one row per frame (--frames), cropped to the figure: the
ground truth, then each run's render and its error (|render − truth| × 4, red over blue) with the
moving region's outline in white; the region comes from the ground truth alone, so it is the same
for every run.

    val_error.py --run RUN [--run RUN_B ...] --data DATA/dnerf-lego --split val \
        [--picture OUT.png --frames 0,5,10]

Needs the renders of `evogs eval --run RUN --split SPLIT` (RUN/renders/SPLIT/NNNN.png); numpy
and Pillow.
"""
import argparse
import json
import sys
from pathlib import Path

import numpy as np
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "phishape"))
from frame_crops import on_black  # noqa: E402  (the ground truth as every picture script reads it)


def load(run, data, split):
    """The split's ground truth (RGBA over black, resized to the renders) and the run's renders."""
    frames = json.load(open(f"{data}/transforms_{split}.json"))["frames"]
    gts, renders = [], []
    for i, f in enumerate(frames):
        r = Image.open(f"{run}/renders/{split}/{i:04d}.png").convert("RGB")
        gt = on_black(f"{data}/{f['file_path']}.png", r.size)
        gts.append(np.asarray(gt, dtype=float) / 255)
        renders.append(np.asarray(r, dtype=float) / 255)
    return np.stack(gts), np.stack(renders)


def dilate(mask, k):
    """The mask grown by k pixels (a square); wraps at the image's edges, which are background."""
    out = mask.copy()
    for dy in range(-k, k + 1):
        for dx in range(-k, k + 1):
            out |= np.roll(np.roll(mask, dy, 0), dx, 1)
    return out


def psnr(mse):
    """The mean over frames of each frame's PSNR, as `evogs eval` averages it."""
    return float(np.mean(-10 * np.log10(mse)))


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--run", required=True, action="append", help="a run directory (repeat to compare)")
    p.add_argument("--data", required=True)
    p.add_argument("--split", default="val")
    p.add_argument("--picture")
    p.add_argument("--frames", default="0,5,10")
    a = p.parse_args()
    columns, moving = [], None
    for run in a.run:
        gts, rs = load(run, a.data, a.split)
        if moving is None:
            med = np.median(gts, 0)
            moving = dilate((np.abs(gts - med[None]).max(3) > 0.1).any(0), 3)
            edge = dilate(moving, 1) & ~moving
            columns.append(gts)
        se = ((rs - gts) ** 2).mean(3)
        total = se.mean((1, 2))
        in_moving = (se * moving).sum((1, 2)) / se[0].size
        print(f"{run} {a.split}: {len(se)} frames, moving region {moving.mean() * 100:.1f} % of the pixels")
        print(f"  mean PSNR {psnr(total):.2f} dB; the moving region holds {in_moving.sum() / total.sum() * 100:.0f} % of the squared error")
        print(f"  PSNR with the moving region's error removed {psnr(total - in_moving):.2f} dB, with the rest's removed {psnr(in_moving):.2f} dB")
        e = np.clip(np.sqrt(se) * 4, 0, 1)
        err = np.stack([e, 0.3 * e, 0.35 * (1 - e) * (gts.sum(3) > 0.02)], 3)
        err[:, edge] = 1.0
        columns += [rs, err]
    if a.picture:
        ys, xs = np.where(columns[0].sum(3).max(0) > 0.06)
        y0, y1, x0, x1 = max(ys.min() - 8, 0), ys.max() + 8, max(xs.min() - 8, 0), xs.max() + 8
        frames = [int(f) for f in a.frames.split(",")]
        rows = [np.concatenate([c[i, y0:y1, x0:x1] for c in columns], 1) for i in frames]
        Image.fromarray((np.concatenate(rows, 0) * 255).astype(np.uint8)).save(a.picture)


if __name__ == "__main__":
    main()
