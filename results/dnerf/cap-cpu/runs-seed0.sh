#!/usr/bin/env bash
# Issue 22: EvoGS on lego with a higher Gaussian cap, the A.7 protocol (dnerf preset, 50 CPU-minutes, one thread, seed 0).
set -u
O=/work/runs/cap; mkdir -p $O; cd $O
B=/work/runs/evogs-cap   # release binary of main cbd3419
uptime > uptime.txt
pids=()
for spec in "20000 16000" "40000 12000"; do
  set -- $spec
  id=evogs-cap$1
  ( RAYON_NUM_THREADS=1 /usr/bin/time -v $B train --data /work/shared/data/dnerf-lego --out $O/$id --preset dnerf \
      --method evogs --seed 0 --max-gaussians $1 --iterations $2 --time-budget 50m > $O/$id.log 2> $O/$id.time
    for s in val test train; do
      RAYON_NUM_THREADS=1 $B eval --run $O/$id --split $s --lpips-vgg > $O/$id-eval-$s.log 2>&1
    done
    echo done > $O/$id.done ) &
  pids+=($!)
done
( while sleep 60; do uptime >> uptime.txt; done ) &
mon=$!
wait "${pids[@]}"
kill $mon
