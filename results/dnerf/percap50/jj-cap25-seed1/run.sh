#!/usr/bin/env bash
# Issue 22: is EvoGS's dnerf cap of 40 000 (chosen on lego) right for jumpingjacks? EvoGS with
# --max-gaussians 10000 and 40000, 25 CPU-minutes each, one thread each, side by side, seed 1;
# then test and the training views.
set -u
O=/work/runs/jjcap1; cd $O
B=evogs   # release binary of main d38af20
uptime > uptime.txt
pids=()
for cap in 10000 40000; do
  id=evogs-cap$cap
  ( RAYON_NUM_THREADS=1 /usr/bin/time -v $B train --data /work/shared/data/dnerf-jumpingjacks --out $O/$id --preset dnerf \
      --method evogs --seed 1 --max-gaussians $cap --time-budget 25m > $O/$id.log 2> $O/$id.time
    for s in test train; do
      RAYON_NUM_THREADS=1 $B eval --run $O/$id --split $s > $O/$id-eval-$s.log 2>&1
    done
    echo done > $O/$id.done ) &
  pids+=($!)
done
( while sleep 60; do uptime >> uptime.txt; done ) &
mon=$!
wait "${pids[@]}"
kill $mon
