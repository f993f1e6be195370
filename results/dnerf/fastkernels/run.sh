#!/usr/bin/env bash
# Issue 22 with issue 14's faster kernels (c4d9021: fused exp, two blocks in flight in the forward
# kernel): the same protocol as A.10-A.13 (50 CPU-minutes, one thread, seed 0, EvoGS at the cap the
# rule "2 000 000 / training frames" gives), to see what the speed-up buys in quality.
# Training views first (no LPIPS: an empty weights directory), then val (lego) and test with LPIPS-VGG.
set -u
here=$(cd "$(dirname "$0")" && pwd)   # before the cd below
O=/work/runs/fastkernels; cd $O
B=/work/runs/evogs-c4d9021
scene=$1; cap=$2
id=$scene-evogs-cap$cap
RAYON_NUM_THREADS=1 /usr/bin/time -v $B train --data /work/shared/data/dnerf-$scene --out $O/$id --preset dnerf \
    --method evogs --seed 0 --max-gaussians $cap --time-budget 50m > $O/$id.log 2> $O/$id.time
"$here"/../eval-splits.sh "$B" "$O" "$id" "$scene"
