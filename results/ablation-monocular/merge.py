#!/usr/bin/env python3
"""Issue 15 monocular ladder: merge the per-seed ablate outputs of a scene, paired differences,
claims, and K / residual statistics from the runs' train_metrics.json and evo_state.safetensors.
usage: merge.py ROOT SCENE  (ROOT holds ladder/SCENE (seed 0, all rows) and ladder-seedS/SCENE)"""
import json, math, statistics, struct, sys
from pathlib import Path

root, scene = Path(sys.argv[1]), sys.argv[2]
runs = {}  # row -> seed -> scores
order = []
for d in [root / "ladder" / scene] + sorted(root.glob(f"ladder-seed*/{scene}")):
    f = d / "ablation.json"
    if not f.exists():
        continue
    for r in json.loads(f.read_text())["rows"]:
        if r["name"] not in order:
            order.append(r["name"])
        for s in r["seeds"]:
            runs.setdefault(r["name"], {})[s["seed"]] = s

def ms(v, d=2, sign=False):
    if not v:
        return "-"
    m = statistics.mean(v)
    f = f"{{:{'+' if sign else ''}.{d}f}}"
    if len(v) == 1:
        return f.format(m) + " (1 seed)"
    return f.format(m) + f" ± {statistics.stdev(v):.{d}f}"

def paired(a, b, key):
    seeds = sorted(set(runs.get(a, {})) & set(runs.get(b, {})))
    return [runs[a][s][key] - runs[b][s][key] for s in seeds], seeds

def read_tensor(path, names):
    with open(path, "rb") as f:
        n = struct.unpack("<Q", f.read(8))[0]
        h = json.loads(f.read(n))
        base = 8 + n
        out = {}
        for name in names:
            if name not in h:
                continue
            t = h[name]
            a, b = t["data_offsets"]
            f.seek(base + a)
            raw = f.read(b - a)
            fmt = {"F32": "f", "F64": "d"}[t["dtype"]]
            out[name] = (struct.unpack(f"<{len(raw)//struct.calcsize(fmt)}{fmt}", raw), t["shape"])
        return out, h["__metadata__"]

def residual_stats(run):
    """Per frame: mean over Gaussians of |M[k] position| and of the buffer's frame-to-frame position
    change |B[k] - B[k-1]|, both over the extent."""
    p = Path(run) if Path(run).is_absolute() else root / run
    st = p / "evo_state.safetensors"
    if not st.exists():
        return None
    with open(st, "rb") as f:
        n = struct.unpack("<Q", f.read(8))[0]
        h = json.loads(f.read(n))
    frames = sorted(k for k in h if k.startswith("memory."))
    bufs = sorted(k for k in h if k.startswith("buffer."))
    data, meta = read_tensor(st, frames + bufs)
    ext = float(meta["extent"])
    def posnorms(name):
        v, (rows, dim) = data[name]
        return [math.sqrt(v[i*dim]**2 + v[i*dim+1]**2 + v[i*dim+2]**2) / ext for i in range(rows)]
    mem = [statistics.mean(posnorms(k)) for k in frames]
    motion = []
    for a, b in zip(bufs, bufs[1:]):
        va, (rows, dim) = data[a]; vb, _ = data[b]
        motion.append(statistics.mean(math.sqrt(sum((vb[i*dim+c]-va[i*dim+c])**2 for c in range(3))) for i in range(rows)) / ext)
    return mem, motion

print(f"## {scene}\n")
print("| row | seeds | test PSNR (dB) | val PSNR (dB) | test − phi (paired) | val − phi (paired) | Gaussians | K mean | K moving / still |")
print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
for name in order:
    r = runs[name]
    seeds = sorted(r)
    t = [r[s]["psnr"] for s in seeds]; v = [r[s]["val_psnr"] for s in seeds]
    g = [r[s]["gaussians"] for s in seeds]
    dt, _ = paired(name, "phi", "psnr"); dv, _ = paired(name, "phi", "val_psnr")
    k = [r[s]["k_mean"] for s in seeds if r[s]["k_mean"] is not None]
    km = [r[s]["k_moving"] for s in seeds if r[s]["k_moving"] is not None]
    kst = [r[s]["k_still"] for s in seeds if r[s]["k_still"] is not None]
    print(f"| {name} | {','.join(map(str, seeds))} | {ms(t)} | {ms(v)} | {ms(dt, sign=True) if name != 'phi' else '0'} | {ms(dv, sign=True) if name != 'phi' else '0'} | {ms(g, 0)} | {ms(k, 3) if k else '-'} | {(ms(km, 3) + ' / ' + ms(kst, 3)) if km else '-'} |")

print("\n### Claims (paired per seed: mean ± sample std of the difference, seeds)\n")
def claim(label, a, b):
    if not paired(a, b, "psnr")[0]:
        print(f"- {label}: {a} − {b}: not run on this scene")
        return
    for key, what in (("psnr", "test"), ("val_psnr", "val")):
        d, s = paired(a, b, key)
        print(f"- {label} {what}: {a} − {b} = {ms(d, sign=True)} dB (seeds {s}; per seed {', '.join(f'{x:+.2f}' for x in d)})")
    d, s = paired(a, b, "gaussians")
    print(f"- {label} Gaussians: {a} − {b} = {ms(d, 0, sign=True)}")
claim("(a)", "full", "phi")
claim("(b)", "evo-buffer", "evo-requery")
claim("(c1)", "full", "k0.5")
claim("(c2)", "k0.5", "k0")
claim("(c3)", "full", "k1")
claim("(e)", "phi", "baseline")
claim("(d)", "trigger", "evo-buffer")

print("\n### K per frame and residual memory per frame (seed 0)\n")
for name in ["evo-requery", "evo-buffer", "trigger", "full", "k0.5", "k0"]:
    if 0 not in runs.get(name, {}):
        continue
    run = runs[name][0]["run"]
    metrics = (root / run) / "train_metrics.json"
    if not metrics.exists():  # the run folders are not kept in the repository
        continue
    tm = json.loads(metrics.read_text())
    pf = tm.get("gain", {}).get("per_frame", [])
    ks = " ".join("-" if f is None else f"{f['mean']:.2f}" for f in pf)
    rs = residual_stats(run)
    print(f"- {name}: K per frame [{ks}]")
    if rs:
        mem, motion = rs
        line = f"  |M[k]| pos / extent per frame [{' '.join(f'{x*1e3:.2f}' for x in mem)}] e-3; mean {statistics.mean(mem)*1e3:.2f}e-3"
        if motion:
            line += f"; |B[k]−B[k−1]| pos / extent mean {statistics.mean(motion)*1e3:.2f}e-3, max {max(motion)*1e3:.2f}e-3 (frame {motion.index(max(motion))+1})"
        print(line)
