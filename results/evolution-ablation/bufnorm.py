#!/usr/bin/env python3
"""Per-frame buffer and memory norms of an evo_state.safetensors (F32 storage): for each frame k,
time, valid, mean over Gaussians of |B[k]_pos| (position part, first 3 components), and of |M[k]|.
Also the straight-line residual of the position part: mean |B[k] - (B[k-1] + (B[k-1]-B[k-2]))|."""
import json, struct, sys, array, math
path = sys.argv[1]
f = open(path, 'rb'); n = struct.unpack('<Q', f.read(8))[0]; hdr = json.loads(f.read(n)); base = 8 + n
data = open(path, 'rb').read()
def tensor(name):
    h = hdr[name]; a, b = h['data_offsets']; assert h['dtype'] == 'F32', h['dtype']
    arr = array.array('f'); arr.frombytes(data[base + a: base + b]); return arr, h['shape']
times, _ = tensor('times')
valid = data[base + hdr['valid']['data_offsets'][0]: base + hdr['valid']['data_offsets'][1]]
meta = hdr.get('__metadata__', {})
print('metadata:', {k: v for k, v in meta.items() if len(v) < 80})
def rows(name):
    if name not in hdr: return None
    arr, shape = tensor(name); N, D = shape; return [arr[i*D:(i+1)*D] for i in range(N)], N, D
print('k  time   valid  mean|B_pos|  mean|M|  mean|B_k - line(B_k-1,B_k-2)|_pos')
prev = []
for k, t in enumerate(times):
    b = rows(f'buffer.{k:05d}'); m = rows(f'memory.{k:05d}')
    bn = sum(math.sqrt(sum(x*x for x in r[:3])) for r in b[0]) / b[1] if b else float('nan')
    mn = sum(math.sqrt(sum(x*x for x in r)) for r in m[0]) / m[1] if m else float('nan')
    line = float('nan')
    if b and len(prev) == 2 and valid[k] and all(v for v in valid[k-2:k]):
        b1, b2 = prev[-1], prev[-2]
        line = sum(math.sqrt(sum((r[j] - (2*r1[j] - r2[j]))**2 for j in range(3))) for r, r1, r2 in zip(b[0], b1, b2)) / b[1]
    prev = (prev + [b[0] if b else None])[-2:]
    print(f'{k:2d} {t:.3f} {valid[k]:5d} {bn:12.5f} {mn:9.5f} {line:12.6f}')
