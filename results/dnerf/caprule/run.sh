#!/usr/bin/env bash
# Issue 22: the cap rule "EvoGS's cap = 2 000 000 / training frames" (lego 50 -> 40 000, jj 200 -> 10 000,
# both chosen on training views) tried where it was not: hook (100 frames -> 20 000) and mutant
# (150 -> 13 333), at the preset's protocol (50 CPU-minutes, one thread, seed 0, main 591d409).
# Training views first (no LPIPS: an empty weights directory), then test with LPIPS-VGG.
set -u
O=/work/runs/caprule; cd $O
B=/work/runs/evogs-591d409
scene=$1; cap=$2
id=$scene-evogs-cap$cap
RAYON_NUM_THREADS=1 /usr/bin/time -v $B train --data /work/shared/data/dnerf-$scene --out $O/$id --preset dnerf \
    --method evogs --seed 0 --max-gaussians $cap --time-budget 50m > $O/$id.log 2> $O/$id.time
mkdir -p /tmp/nolpips
EVOGS_LPIPS_WEIGHTS=/tmp/nolpips RAYON_NUM_THREADS=1 $B eval --run $O/$id --split train > $O/$id-eval-train.log 2>&1
RAYON_NUM_THREADS=1 $B eval --run $O/$id --split test --lpips-vgg > $O/$id-eval-test.log 2>&1
echo done > $O/$id.done
