#!/usr/bin/env python3
# Halve a D-NeRF scene's PNGs: 2x2 box filter of the colour premultiplied by alpha, stored as
# straight RGBA (RGB = mean(rgb*a)/mean(a), A = mean(a)), so that compositing over black gives the
# loader's composite-then-box-filter up to 8-bit rounding. Only for shipping data to the lent GPU.
import sys, os, json, shutil, numpy as np
from PIL import Image
src, dst = sys.argv[1], sys.argv[2]
os.makedirs(dst, exist_ok=True)
for split in ("train", "val", "test"):
    meta = json.load(open(f"{src}/transforms_{split}.json"))
    shutil.copy(f"{src}/transforms_{split}.json", dst)
    for fr in meta["frames"]:
        p = fr["file_path"]
        p = p[2:] if p.startswith("./") else p
        p = p if p.endswith(".png") else p + ".png"
        im = np.asarray(Image.open(f"{src}/{p}").convert("RGBA")).astype(np.float64) / 255.0
        rgb, a = im[..., :3] * im[..., 3:], im[..., 3:]
        box = lambda x: x.reshape(x.shape[0] // 2, 2, x.shape[1] // 2, 2, -1).mean(axis=(1, 3))
        rgbp, ap = box(rgb), box(a)
        straight = np.where(ap > 0, rgbp / np.maximum(ap, 1e-12), 0.0)
        out = np.concatenate([straight, ap], axis=-1)
        os.makedirs(os.path.dirname(f"{dst}/{p}"), exist_ok=True)
        Image.fromarray(np.clip(np.round(out * 255), 0, 255).astype(np.uint8), "RGBA").save(f"{dst}/{p}")
