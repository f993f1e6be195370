#!/usr/bin/env bash
# Issue 22: EvoGS on hook with --max-gaussians 10000 at the preset's protocol (50 CPU-minutes, one
# thread, seed 0), against the preset's 40 000 run of the same bench (hm50); then test and the training views.
set -u
O=/work/runs/hookcap; cd $O
B=/work/runs/evogs-591d409
id=evogs-cap10000
RAYON_NUM_THREADS=1 /usr/bin/time -v $B train --data /work/shared/data/dnerf-hook --out $O/$id --preset dnerf \
    --method evogs --seed 0 --max-gaussians 10000 --time-budget 50m > $O/$id.log 2> $O/$id.time
for s in test train; do
  RAYON_NUM_THREADS=1 $B eval --run $O/$id --split $s --lpips-vgg > $O/$id-eval-$s.log 2>&1
done
echo done > $O/$id.done
