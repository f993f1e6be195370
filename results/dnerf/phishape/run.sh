#!/usr/bin/env bash
# Issue 22: Φ's shape on jumpingjacks. A.14's protocol (50 CPU-minutes, one thread, seed 0, EvoGS
# at the rule's cap of 10 000) with one of Φ's shape flags changed: more B-spline control vectors
# (the deformation's temporal resolution: 16 controls span 200 frames, ~15 frames per knot) or
# finer tri-plane resolutions. Chosen on the training views; test with LPIPS-VGG after.
# Usage: [SEED=N] [BUDGET=50m] [BIN=PATH] run.sh SCENE CAP ID FLAGS...
set -u
here=$(cd "$(dirname "$0")" && pwd)   # before the cd below
O=/work/runs/phishape; cd $O
B=${BIN:-/work/runs/evogs-phiflags}   # BIN: another binary (A.19: 4753ae8 + --bspline-width)
scene=$1; cap=$2; id=$scene-$3; shift 3
RAYON_NUM_THREADS=1 /usr/bin/time -v $B train --data /work/shared/data/dnerf-$scene --out $O/$id --preset dnerf \
    --method evogs --seed ${SEED:-0} --max-gaussians $cap --time-budget ${BUDGET:-50m} "$@" > $O/$id.log 2> $O/$id.time
"$here"/../eval-splits.sh "$B" "$O" "$id" "$scene"
