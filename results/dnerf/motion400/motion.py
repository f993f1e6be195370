#!/usr/bin/env python3
"""Motion of a lego run's shovel: reads `evogs export --frames 11` PLYs (deformed Gaussians at
t = 0, 0.1, ..., 1, same order in every frame), selects the opaque Gaussians whose position at
t = 0 lies in BOX, and prints their mean position per time and their mean path length."""
import json, math, struct, sys

def read_ply(path):
    with open(path, 'rb') as f:
        props = []
        n = 0
        while True:
            line = f.readline().decode().strip()
            if line.startswith('element vertex'):
                n = int(line.split()[-1])
            elif line.startswith('property'):
                _, ty, name = line.split()
                assert ty == 'float', ty
                props.append(name)
            elif line == 'end_header':
                break
        data = f.read(4 * len(props) * n)
    vals = struct.unpack('<%df' % (len(props) * n), data)
    k = len(props)
    idx = {p: i for i, p in enumerate(props)}
    return n, k, idx, vals

folder, box = sys.argv[1], [float(x) for x in sys.argv[2].split(",")]
min_op = float(sys.argv[3]) if len(sys.argv) > 3 else 0.5
seq = json.load(open(f'{folder}/sequence.json'))
files = seq['files']
frames = [read_ply(f'{folder}/{name}') for name in files]
n, k, idx, v0 = frames[0]
def pos(vals, i):
    return vals[i * k + idx['x']], vals[i * k + idx['y']], vals[i * k + idx['z']]
sel = []
for i in range(n):
    op = 1 / (1 + math.exp(-v0[i * k + idx['opacity']]))
    x, y, z = pos(v0, i)
    if op > min_op and box[0] <= x <= box[3] and box[1] <= y <= box[4] and box[2] <= z <= box[5]:
        sel.append(i)
print(f'{folder}: {n} Gaussians, {len(sel)} with opacity > {min_op} in the box at t = 0')
path = [0.0] * len(sel)
prev = [pos(v0, i) for i in sel]
for t, (_, _, _, vals) in zip(seq.get('times', range(len(frames))), frames):
    cur = [pos(vals, i) for i in sel]
    for j, (a, b) in enumerate(zip(prev, cur)):
        path[j] += math.dist(a, b)
    prev = cur
    m = [sum(c[d] for c in cur) / len(cur) for d in range(3)]
    print(f't={t:.2f} mean x {m[0]:+.3f} y {m[1]:+.3f} z {m[2]:+.3f}')
print(f'mean path length over t: {sum(path) / len(path):.3f}')
