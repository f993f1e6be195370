"""Exclusive cost per function of a callgrind output file, per iteration.

usage: callgrind-by-symbol.py FILE ITERATIONS

Sums each function's own cost lines (the inclusive cost lines after `calls=` are skipped), over
every event the file has (`Ir`; with `--branch-sim=yes` also `Bc Bcm Bi Bim`), and prints the
25 functions with the most instructions, per iteration. callgrind_annotate 3.19 charges these
runs to `clone`, hence this reader.
"""
import collections
import re
import sys

names = {}
events = ["Ir"]
cur = None
skip = False
cost = collections.defaultdict(lambda: [0] * len(events))
for line in open(sys.argv[1]):
    line = line.rstrip("\n")
    if line.startswith("events:"):
        events = line.split()[1:]
        continue
    m = re.match(r"c?fn=\((\d+)\)(?: (.*))?", line)
    if m:
        if m.group(2):
            names[m.group(1)] = m.group(2)
        if line.startswith("fn="):
            cur = names[m.group(1)]
        continue
    if line.startswith("calls="):
        skip = True
        continue
    if line and (line[0].isdigit() or line[0] in "+-*"):
        if skip:
            skip = False
            continue
        row = cost.setdefault(cur, [0] * len(events))
        for i, v in enumerate(line.split()[1:]):
            row[i] += int(v)

n = float(sys.argv[2])
total = sum(v[0] for v in cost.values())
print(f"total {total / n / 1e6} M instructions per iteration; events {' '.join(events)}")
branches = "Bc" in events and "Bcm" in events
for name, v in sorted(cost.items(), key=lambda kv: -kv[1][0])[:25]:
    line = f"{v[0] / n / 1e6:8.1f} M  {100 * v[0] / total:5.1f}%"
    if branches:
        bc, bcm = v[events.index("Bc")], v[events.index("Bcm")]
        line += f"  Bc {bc / n / 1e6:6.2f} M  Bcm {bcm / n / 1e6:6.3f} M ({100 * bcm / max(bc, 1):.1f} %)"
    print(f"{line}  {name[:140]}")
