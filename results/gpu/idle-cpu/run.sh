#!/usr/bin/env bash
# Idle-CPU measurements for issue 14 on the lent machine's CPU (its GPU unused).
set -u
R=$PWD
export LD_LIBRARY_PATH=$R/.gpu/lib
[ -e /work/main ] || { mkdir -p /work && ln -s "$R" /work/main; }
lscpu > $OUT/cpu.txt 2>&1; nproc >> $OUT/cpu.txt
# one logical CPU per physical core, in order
mapfile -t C < <(lscpu -p=CPU,CORE 2>/dev/null | grep -v '^#' | sort -t, -k2,2n -u | cut -d, -f1)
echo "cpus per core: ${C[*]}" | tee -a $OUT/cpu.txt
P0=${C[0]},${C[1]}; P1=${C[2]},${C[3]}; P2=${C[4]},${C[5]}; S0=${C[0]}
ts() { if command -v taskset >/dev/null; then taskset -c "$@"; else shift; "$@"; fi; }
E=$R/.gpu/evogs; D=$R/.gpu/dnerf-lego
run() { # method cores
  local m=$1 c=$2 o=/tmp/lego-$1
  local t0=$SECONDS
  RAYON_NUM_THREADS=2 ts $c $E train --data $D --out $o --preset cpu --downscale 1 --method $m --seed 0 --max-screen-radius 20 > $OUT/train-$m.log 2>&1
  echo "wall $((SECONDS - t0)) s" >> $OUT/train-$m.log
  for s in val test; do RAYON_NUM_THREADS=2 ts $c $E eval --run $o --split $s >> $OUT/train-$m.log 2>&1; done
  cp $o/train_metrics.json $OUT/metrics-$m.json
}
run baseline $P1 & run evogs $P2 &
B=$R/.gpu/bin
{
  date -u
  for k in new old new old; do
    RAYON_NUM_THREADS=1 ts $S0 $B/raster-$k --bench --warm-up-time 1 --measurement-time 2 --sample-size 10 'cpu/.*/(forward|forward_backward|scalar_forward|scalar_forward_backward)$' 2>&1 | grep -E "^cpu/|time:" | sed "s/^/$k /"
  done
  RAYON_NUM_THREADS=2 ts $P0 $B/metrics --bench --warm-up-time 1 --measurement-time 4 loss_and_gradient 2>&1 | grep -E "metrics|time:"
  RAYON_NUM_THREADS=2 ts $P0 $B/iteration --bench --warm-up-time 1 --measurement-time 5 2>&1 | grep -vE "^$|Warming|Collecting|Analyzing|outlier|Found"
  date -u
} > $OUT/bench.txt 2>&1
wait
uptime >> $OUT/cpu.txt
