"""CPU time per function from `perf record -e cpu-clock` files, per iteration.

usage: perf-by-symbol.py ITERATIONS_PER_FILE SAMPLE_HZ FILE...

Reads each file once (`perf script --no-demangle`) and counts samples per mangled symbol, so that
monomorphs of one generic function (the rasterizer's forward and backward kernels are both
`run_avx2`) stay apart; names are demangled by `c++filt` for printing (Rust's legacy mangling
keeps the hash: `…::run_avx2::h0e0f…`).
"""
import collections
import subprocess
import sys

iters, hz, files = int(sys.argv[1]), float(sys.argv[2]), sys.argv[3:]
samples = collections.Counter()
for f in files:
    out = subprocess.run(
        ["perf", "script", "-i", f, "-F", "ip,sym", "--no-demangle"],
        capture_output=True, text=True, check=True,
    ).stdout
    for line in out.splitlines():
        samples[line.strip().split(None, 1)[-1]] += 1
top = samples.most_common(25)
names = subprocess.run(
    ["c++filt"], input="\n".join(k for k, _ in top), capture_output=True, text=True, check=True
).stdout.splitlines()
total, n = sum(samples.values()), len(files) * iters
print(f"{total} samples, {total / hz / n * 1000:.1f} ms CPU per iteration")
for name, (_, v) in zip(names, top):
    print(f"{v / hz / n * 1000:7.2f} ms {100 * v / total:5.1f}%  {name[:120]}")
