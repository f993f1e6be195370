"""Ground truth beside several runs' renders of the same training frames, cropped to the figure.

usage: python3 frames_side_by_side.py OUT.png DATA FRAMES LABEL=RUN ...
(FRAMES comma-separated; each RUN holds renders/train/NNNN.png and eval_train.json, whose PSNR
of the frame the label shows, from `evogs eval --split train`;
DATA is the D-NeRF scene, its RGBA training images composited on black as the runs train)
"""
import json
import sys

import numpy as np
from PIL import Image, ImageDraw

out_path, data, frames = sys.argv[1], sys.argv[2], [int(f) for f in sys.argv[3].split(",")]
runs = [a.rsplit("=", 1) for a in sys.argv[4:]]
rows = []
for f in frames:
    gt = Image.open(f"{data}/train/r_{f:03d}.png").convert("RGBA")
    first = Image.open(f"{runs[0][1]}/renders/train/{f:04d}.png").convert("RGB")
    black = Image.new("RGBA", gt.size, (0, 0, 0, 255))
    gt = Image.alpha_composite(black, gt).convert("RGB").resize(first.size, Image.LANCZOS)
    g = np.asarray(gt).astype(float)
    ys, xs = np.where(g.sum(2) > 15)
    w, h = first.size
    box = (max(xs.min() - 12, 0), max(ys.min() - 12, 0), min(xs.max() + 12, w - 1), min(ys.max() + 12, h - 1))
    cells = [("ground truth", gt.crop(box))]
    for label, run in runs:
        r = Image.open(f"{run}/renders/train/{f:04d}.png").convert("RGB")
        images = json.load(open(f"{run}/eval_train.json"))["images"]
        psnr = next(i["psnr"] for i in images if i["name"] == f"r_{f:03d}.png")
        cells.append((f"{label}: {psnr:.2f} dB", r.crop(box)))
    rows.append((f, cells))
cw = max(c.size[0] for _, cells in rows for _, c in cells)
ch = max(c.size[1] for _, cells in rows for _, c in cells)
sheet = Image.new("RGB", (cw * (len(runs) + 1), len(rows) * (ch + 18)), (255, 255, 255))
draw = ImageDraw.Draw(sheet)
for i, (f, cells) in enumerate(rows):
    for j, (label, im) in enumerate(cells):
        x, y = j * cw, i * (ch + 18)
        draw.text((x + 3, y + 3), f"frame {f}, {label}" if j == 0 else label, fill=(0, 0, 0))
        sheet.paste(im, (x, y + 16))
sheet.save(out_path)
