"""What the picture scripts of this directory share: a training frame's render, its ground truth
as the runs train on it, the crop to the figure, and the frame's PSNR from the run's evaluation."""
import json

import numpy as np
from PIL import Image


def render(run, f):
    """Frame f's render from `evogs eval --split train` (renders/train/NNNN.png)."""
    return Image.open(f"{run}/renders/train/{f:04d}.png").convert("RGB")


def on_black(path, size):
    """A D-NeRF image file: RGBA composited on black, resized to `size` (the renders')."""
    gt = Image.open(path).convert("RGBA")
    black = Image.new("RGBA", gt.size, (0, 0, 0, 255))
    return Image.alpha_composite(black, gt).convert("RGB").resize(size, Image.LANCZOS)


def ground_truth(data, f, size):
    """Training frame f of the D-NeRF scene DATA, as the runs train on it (`on_black`)."""
    return on_black(f"{data}/train/r_{f:03d}.png", size)


def figure_box(gt, margin):
    """The box around the figure's pixels of a ground-truth image, `margin` pixels wider."""
    ys, xs = np.where(np.asarray(gt).astype(float).sum(2) > 15)
    w, h = gt.size
    return (
        max(xs.min() - margin, 0),
        max(ys.min() - margin, 0),
        min(xs.max() + margin, w - 1),
        min(ys.max() + margin, h - 1),
    )


def train_psnr(run, f):
    """Frame f's PSNR as the run's `eval_train.json` records it."""
    images = json.load(open(f"{run}/eval_train.json"))["images"]
    return next(i["psnr"] for i in images if i["name"] == f"r_{f:03d}.png")
