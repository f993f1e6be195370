#!/usr/bin/env python3
"""ablation.svg: test and val PSNR per ladder row, mean ± 1 sample std over seeds, one panel per scene.
usage: plot.py ROOT OUT.svg SCENE..."""
import json, statistics, sys
from pathlib import Path
root, out, scenes = Path(sys.argv[1]), sys.argv[2], sys.argv[3:]
ORDER = ["baseline", "phi", "evo-requery", "evo-buffer", "trigger", "full", "k0", "k0.5", "k1"]
def load(scene):
    runs = {}
    for d in [root / "ladder" / scene] + sorted(root.glob(f"ladder-seed*/{scene}")):
        f = d / "ablation.json"
        if f.exists():
            for r in json.loads(f.read_text())["rows"]:
                for s in r["seeds"]:
                    runs.setdefault(r["name"], {})[s["seed"]] = s
    return runs
W, H, PW, PH, L, T = 420 * len(scenes), 420, 420, 260, 50, 40
svg = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="11">',
       f'<rect width="{W}" height="{H}" fill="white"/>']
for p, scene in enumerate(scenes):
    runs = load(scene)
    rows = [r for r in ORDER if r in runs]
    vals = [v[k] for r in rows for v in runs[r].values() for k in ("psnr", "val_psnr")]
    lo, hi = min(vals) - 0.5, max(vals) + 0.5
    x0 = p * PW + L
    y = lambda v: T + PH * (hi - v) / (hi - lo)
    svg.append(f'<text x="{x0 + (PW - L) / 2 - 40}" y="20" font-size="13">{scene}</text>')
    svg.append(f'<line x1="{x0}" y1="{T}" x2="{x0}" y2="{T + PH}" stroke="black"/>')
    svg.append(f'<line x1="{x0}" y1="{T + PH}" x2="{x0 + PW - L - 10}" y2="{T + PH}" stroke="black"/>')
    t = int(lo) + 1
    while t <= hi:
        svg.append(f'<line x1="{x0 - 4}" y1="{y(t):.1f}" x2="{x0 + PW - L - 10}" y2="{y(t):.1f}" stroke="#ddd"/>')
        svg.append(f'<text x="{x0 - 30}" y="{y(t) + 4:.1f}">{t}</text>')
        t += 1
    svg.append(f'<text x="{x0 - 45}" y="{T - 8}">PSNR (dB)</text>')
    step = (PW - L - 20) / len(rows)
    for i, r in enumerate(rows):
        cx = x0 + step * (i + 0.5)
        for key, colour, dx in (("psnr", "#1f77b4", -4), ("val_psnr", "#ff7f0e", 4)):
            v = [s[key] for s in runs[r].values()]
            m = statistics.mean(v); sd = statistics.stdev(v) if len(v) > 1 else 0
            svg.append(f'<line x1="{cx + dx:.1f}" y1="{y(m - sd):.1f}" x2="{cx + dx:.1f}" y2="{y(m + sd):.1f}" stroke="{colour}"/>')
            svg.append(f'<circle cx="{cx + dx:.1f}" cy="{y(m):.1f}" r="3" fill="{colour}"/>')
        n = len(runs[r])
        svg.append(f'<text transform="translate({cx + 3:.1f},{T + PH + 8}) rotate(60)">{r} (n={n})</text>')
svg.append(f'<circle cx="20" cy="{H - 12}" r="3" fill="#1f77b4"/><text x="28" y="{H - 8}">test</text>')
svg.append(f'<circle cx="70" cy="{H - 12}" r="3" fill="#ff7f0e"/><text x="78" y="{H - 8}">val (mean ± 1 std over seeds)</text>')
svg.append("</svg>")
Path(out).write_text("\n".join(svg))
