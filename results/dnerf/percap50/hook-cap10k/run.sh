#!/usr/bin/env bash
# Issue 22: EvoGS on hook with --max-gaussians 10000 at the preset's protocol (50 CPU-minutes, one
# thread, seed 0), against the preset's 40 000 run of the same bench (hm50); then test and the training views.
set -u
O=/work/runs/hookcap; cd $O
B=/work/runs/evogs-591d409
id=evogs-cap10000
RAYON_NUM_THREADS=1 /usr/bin/time -v $B train --data /work/shared/data/dnerf-hook --out $O/$id --preset dnerf \
    --method evogs --seed 0 --max-gaussians 10000 --time-budget 50m > $O/$id.log 2> $O/$id.time
RAYON_NUM_THREADS=1 $B eval --run $O/$id --split test --lpips-vgg > $O/$id-eval-test.log 2>&1
# The training views without LPIPS (an empty weights directory): with VGG on 100 views at one
# thread the evaluation was too slow for the session, so it was stopped and run again this way.
EVOGS_LPIPS_WEIGHTS=/tmp/nolpips RAYON_NUM_THREADS=1 $B eval --run $O/$id --split train > $O/$id-eval-train.log 2>&1
echo done > $O/$id.done
