"""Per-frame training-view PSNR of EvoGS with the learned gain minus EvoGS with K = 1 (observation
only), over each frame's time, one panel per pair: an SVG written by hand (no plotting library).

usage: python3 gain_frames.py OUT.svg LEARNED_RUN:K1_RUN[:LABEL] ...
(each run directory holds `eval_train.json` from `evogs eval --split train`)
"""
import json
import sys

out, pairs = sys.argv[1], sys.argv[2:]
W, H, PAD, GAP = 720, 170, 46, 26
panels = []
for pair in pairs:
    parts = pair.split(":")
    a, b = parts[0], parts[1]
    label = parts[2] if len(parts) > 2 else f"{a} − {b}"
    x = json.load(open(f"{a}/eval_train.json"))["images"]
    y = json.load(open(f"{b}/eval_train.json"))["images"]
    assert [i["name"] for i in x] == [i["name"] for i in y]
    d = sorted((i["time"], i["psnr"] - j["psnr"]) for i, j in zip(x, y))
    panels.append((label, d))
span = max(max(abs(v) for _, v in d) for _, d in panels)
span = max(1.0, float(int(span) + 1))
total_h = len(panels) * (H + GAP) + 20
svg = [
    f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{total_h}" '
    'font-family="sans-serif" font-size="12">',
    f'<rect width="{W}" height="{total_h}" fill="white"/>',
]
for k, (label, d) in enumerate(panels):
    top = 10 + k * (H + GAP)
    x0, x1, y0, y1 = PAD, W - 10, top + 18, top + H - 18
    mid = (y0 + y1) / 2

    def ys(v):
        return mid - v / span * (y1 - y0) / 2

    better = sum(v > 0 for _, v in d)
    mean = sum(v for _, v in d) / len(d)
    svg.append(
        f'<text x="{x0}" y="{top + 12}">{label}: learned gain − K = 1, training views '
        f"(mean {mean:+.2f} dB; learned better on {better} of {len(d)} frames)</text>"
    )
    svg.append(f'<rect x="{x0}" y="{y0}" width="{x1 - x0}" height="{y1 - y0}" fill="none" stroke="#999"/>')
    for v in (-span, 0, span):
        svg.append(f'<line x1="{x0}" x2="{x1}" y1="{ys(v):.1f}" y2="{ys(v):.1f}" stroke="#ccc"/>')
        svg.append(f'<text x="{x0 - 4}" y="{ys(v) + 4:.1f}" text-anchor="end">{v:+.0f}</text>')
    bw = (x1 - x0) / len(d)
    for i, (t, v) in enumerate(d):
        xa = x0 + i * bw
        top_y, h = (ys(v), ys(0) - ys(v)) if v > 0 else (ys(0), ys(v) - ys(0))
        colour = "#2a7ab0" if v > 0 else "#d0632a"
        svg.append(
            f'<rect x="{xa:.1f}" y="{top_y:.1f}" width="{max(bw - 0.5, 0.5):.1f}" '
            f'height="{h:.1f}" fill="{colour}"/>'
        )
    svg.append(f'<text x="{x1}" y="{y1 + 14}" text-anchor="end">frames in time order (t = 0 … 1); bars in dB</text>')
svg.append("</svg>")
open(out, "w").write("\n".join(svg) + "\n")
