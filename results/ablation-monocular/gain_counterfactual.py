#!/usr/bin/env python3
"""Issue 15: which of the prior and the observation renders a training frame better, for a trained
EvoGS run with a learned gain. Copies RUN three times, fixes the gain of the copies at 0 (d̃ = d̂,
prior only) and 1 (d̃ = z, observation only) in config.json and in evo_state.safetensors' metadata
(same Φ, Ψ, buffer and residual memory), evaluates the three on the training split with
`evogs eval --split train`, and prints per-frame PSNR and the training-step mean K of the run.
usage: gain_counterfactual.py RUN OUT [EVOGS]   (EVOGS: the evogs binary, default `evogs`)"""
import json, shutil, struct, subprocess, sys
from pathlib import Path

run, out = Path(sys.argv[1]), Path(sys.argv[2])
evogs = sys.argv[3] if len(sys.argv) > 3 else "evogs"

def fix_gain(d: Path, k: str):
    cfg = json.loads((d / "config.json").read_text())
    def walk(x):
        if isinstance(x, dict):
            for key, v in x.items():
                if key == "gain" and v == "learned":
                    x[key] = {"fixed": float(k)}
                else:
                    walk(v)
    walk(cfg)
    (d / "config.json").write_text(json.dumps(cfg, indent=1))
    st = d / "evo_state.safetensors"
    b = st.read_bytes()
    n = struct.unpack("<Q", b[:8])[0]
    h = json.loads(b[8:8 + n])
    assert h["__metadata__"]["gain"] == "learned", "the run's gain is not learned"
    h["__metadata__"]["gain"] = f"fixed:{k}"
    hb = json.dumps(h, separators=(",", ":")).encode()
    hb += b" " * ((8 - len(hb) % 8) % 8)
    tmp = st.with_suffix(".tmp")
    tmp.write_bytes(struct.pack("<Q", len(hb)) + hb + b[8 + n:])
    tmp.replace(st)

psnr = {}
for name, k in (("learned", None), ("prior", "0"), ("observation", "1")):
    d = out / name
    if d.exists():
        shutil.rmtree(d)
    shutil.copytree(run, d, ignore=shutil.ignore_patterns("renders", "eval_*"))
    if k is not None:
        fix_gain(d, k)
    subprocess.run([evogs, "eval", "--run", str(d), "--split", "train"], check=True,
                   stdout=subprocess.DEVNULL)
    psnr[name] = json.loads((d / "eval_train.json").read_text())["images"]

tm = json.loads((run / "train_metrics.json").read_text())
kpf = tm.get("gain", {}).get("per_frame", [])
print(f"training views of {run}: PSNR (dB) per frame with the learned K, K = 0 (prior d̂ only), K = 1 (observation z only)\n")
print("| frame | t | K mean (training steps) | learned | K = 0 prior | K = 1 observation | prior − observation |")
print("| ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
for i, img in enumerate(psnr["learned"]):
    a, p, o = (psnr[x][i]["psnr"] for x in ("learned", "prior", "observation"))
    k = kpf[i]["mean"] if i < len(kpf) and kpf[i] else None
    print(f"| {i} | {img['time']:.3f} | {'-' if k is None else f'{k:.2f}'} | {a:.2f} | {p:.2f} | {o:.2f} | {p - o:+.2f} |")
