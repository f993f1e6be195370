#!/usr/bin/env python3
"""Rebuilds tables.md from the ablation.json files kept here (merge.py per scene). The per-frame K
and residual-memory sections need the run folders, which are not kept: they are carried over from
the tables.md being replaced. usage: python3 tables.py (in this folder)"""
import re, subprocess
from pathlib import Path

old = Path("tables.md").read_text() if Path("tables.md").exists() else ""
kept = {}
for part in re.split(r"(?m)^## ", old):
    name = part.split("\n", 1)[0].strip()
    i = part.find("### K per frame")
    if name and i >= 0:
        kept[name] = part[i:].rstrip() + "\n"
note = "(seed 0; carried over from the tables of the original runs, whose folders are not kept)"
out = []
for scene in ["jump", "wave", "jumpingjacks"]:
    t = subprocess.run(["python3", "merge.py", ".", scene], capture_output=True, text=True, check=True).stdout
    i = t.find("### K per frame")
    if i >= 0 and scene in kept and not t[i:].strip().count("\n- "):
        t = t[:i] + kept[scene].replace("(seed 0)", note, 1)
    out.append(t.rstrip() + "\n")
tmp = Path("tables.md.tmp")
tmp.write_text("\n".join(out))
tmp.replace("tables.md")
