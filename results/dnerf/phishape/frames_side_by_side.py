"""Ground truth beside several runs' renders of the same training frames, cropped to the figure.

usage: python3 frames_side_by_side.py OUT.png DATA FRAMES LABEL=RUN ...
(FRAMES comma-separated; each RUN holds renders/train/NNNN.png and eval_train.json, whose PSNR
of the frame the label shows, from `evogs eval --split train`;
DATA is the D-NeRF scene, its RGBA training images composited on black as the runs train)
"""
import sys

from PIL import Image, ImageDraw

from frame_crops import figure_box, ground_truth, render, train_psnr

out_path, data, frames = sys.argv[1], sys.argv[2], [int(f) for f in sys.argv[3].split(",")]
runs = [a.rsplit("=", 1) for a in sys.argv[4:]]
rows = []
for f in frames:
    gt = ground_truth(data, f, render(runs[0][1], f).size)
    box = figure_box(gt, 12)
    cells = [("ground truth", gt.crop(box))]
    for label, run in runs:
        cells.append((f"{label}: {train_psnr(run, f):.2f} dB", render(run, f).crop(box)))
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
