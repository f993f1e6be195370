#!/bin/bash
# Issue 15 monocular ladder: 2 synthetic monocular scenes x 3 seeds x 9 rows at 48x48, 4000 iterations,
# WORK: the folder the runs were made in (default ./runs/ablation-monocular); EVOGS: the evogs binary (default evogs on PATH).
# plus D-NeRF jumpingjacks (downscaled to 100x100 with ffmpeg) x 4 rows x 1 seed, 3000 iterations.
# Three streams side by side, one thread each, nice 10. Binary: ../bin/evogs (../bin/commit.txt).
set -uo pipefail
WORK=${WORK:-$PWD/runs/ablation-monocular}
mkdir -p "$WORK" && cd "$WORK"
B=${EVOGS:-evogs}
( while true; do echo "$(date -u +%H:%M:%S) $(cut -d' ' -f1-3 /proc/loadavg)"; sleep 60; done ) > load.log &
LOADER=$!
trap 'kill $LOADER' EXIT
for scene in jump wave; do
  RAYON_NUM_THREADS=1 nice -n 10 $B ablate --data scenes/$scene --out ladder/$scene --preset tiny \
    --iterations 4000 --seed 0 --seeds 3 \
    --rows baseline,phi,evo-requery,evo-buffer,trigger,full,k0,k0.5,k1 > ladder-$scene.log 2>&1 &
done
RAYON_NUM_THREADS=1 nice -n 10 $B ablate --data ${JJ100:?JJ100: D-NeRF jumpingjacks downscaled to 100x100} --out ladder/jumpingjacks --preset tiny \
    --iterations 3000 --seed 0 --rows baseline,phi,k0.5,full > ladder-jumpingjacks.log 2>&1 &
wait
date -u > DONE
