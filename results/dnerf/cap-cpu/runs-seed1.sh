#!/usr/bin/env bash
# Issue 22: EvoGS on lego, cap 10 000 (N 20 000, as A.7) and 40 000 (N 12 000), seed 1, the A.7 protocol.
set -u
O=/work/runs/cap; cd $O
B=/work/runs/evogs-cap
pids=()
for spec in "10000 20000" "40000 12000"; do
  set -- $spec
  id=evogs-cap$1-s1
  ( RAYON_NUM_THREADS=1 /usr/bin/time -v $B train --data /work/shared/data/dnerf-lego --out $O/$id --preset dnerf \
      --method evogs --seed 1 --max-gaussians $1 --iterations $2 --time-budget 50m > $O/$id.log 2> $O/$id.time
    RAYON_NUM_THREADS=1 $B eval --run $O/$id --split val --lpips-vgg > $O/$id-eval-val.log 2>&1
    for s in train test; do
      RAYON_NUM_THREADS=1 $B eval --run $O/$id --split $s > $O/$id-eval-$s.log 2>&1
    done
    echo done > $O/$id.done ) &
  pids+=($!)
done
( while sleep 60; do uptime >> uptime1.txt; done ) &
mon=$!
wait "${pids[@]}"
kill $mon
