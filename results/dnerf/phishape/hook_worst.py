"""Ground truth | EvoGS render | error (x4) on the training frames where a hook run is worst,
cropped to the figure: where the missing decibels are.

usage: python3 hook_worst.py OUT.png RUN DATA FRAME...
(RUN holds renders/train/NNNN.png and eval_train.json, whose PSNR of the frame the picture shows,
from `evogs eval --split train`; DATA is the D-NeRF hook scene,
its RGBA training images composited on black as the runs train)
"""
import sys

import numpy as np
from PIL import Image, ImageDraw

from frame_crops import figure_box, ground_truth, render, train_psnr

out_path, run, data = sys.argv[1:4]
frames = [int(f) for f in sys.argv[4:]]
columns = []
for f in frames:
    rendered = render(run, f)
    gt = ground_truth(data, f, rendered.size)
    a, b = np.asarray(rendered).astype(float), np.asarray(gt).astype(float)
    err = Image.fromarray(np.clip(np.abs(a - b).mean(2) * 4, 0, 255).astype(np.uint8))
    box = figure_box(gt, 20)
    columns.append((f, train_psnr(run, f), [im.crop(box) for im in (gt, rendered, err.convert("RGB"))]))
row_h = max(c[2][0].size[1] for c in columns)
width = sum(c[2][0].size[0] for c in columns)
sheet = Image.new("RGB", (width, 3 * (row_h + 16) + 20), (255, 255, 255))
draw = ImageDraw.Draw(sheet)
x = 0
for f, psnr, ims in columns:
    draw.text((x + 4, 4), f"frame {f}: {psnr:.2f} dB", fill=(0, 0, 0))
    for k, im in enumerate(ims):
        sheet.paste(im, (x, 20 + k * (row_h + 16)))
    x += ims[0].size[0]
for k, label in enumerate(["ground truth", "EvoGS render", "|error| x 4"]):
    draw.text((4, 20 + k * (row_h + 16) + row_h + 2), label, fill=(0, 0, 0))
sheet.save(out_path)
