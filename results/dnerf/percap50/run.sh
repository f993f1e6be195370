#!/usr/bin/env bash
# Issue 22: the dnerf preset with its per-method cap (baseline 10 000, EvoGS 40 000), A.7's
# protocol: 50 CPU-minutes per run, one rayon thread, the two methods side by side, seed 0.
# usage: run.sh SCENE   (dnerf-jumpingjacks, dnerf-hook, ...)
set -u
S=$1; O=/work/runs/t50/$S; mkdir -p $O; cd $O
B=evogs   # release binary of main 2fbdaa1 (the per-method cap)
uptime > uptime.txt
pids=()
for m in baseline evogs; do
  ( RAYON_NUM_THREADS=1 /usr/bin/time -v $B bench --data /work/shared/data/$S --out $O/$m --methods $m \
      --preset dnerf --time-budget 50m --eval-every 2000 --lpips-vgg --seed 0 > $O/$m.log 2> $O/$m.time
    run=$(ls -d $O/$m/*/$m)
    RAYON_NUM_THREADS=1 $B eval --run $run --split train > $O/$m-eval-train.log 2>&1
    echo done > $O/$m.done ) &
  pids+=($!)
done
( while sleep 60; do uptime >> uptime.txt; done ) &
mon=$!
wait "${pids[@]}"
kill $mon
