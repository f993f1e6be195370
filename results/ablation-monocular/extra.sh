#!/bin/bash
# Extra streams (started 21:00 because the 3-seed ladder would not finish by 21:40 at load ~19):
# WORK: the folder the runs were made in (default ./runs/ablation-monocular); EVOGS: the evogs binary (default evogs on PATH).
# seeds 1 and 2 of the rows the claims need (no baseline, no k1), one process per scene and seed.
# The original 3-seed processes (ladder.sh) are stopped once their seed 0 ladder is written.
set -uo pipefail
WORK=${WORK:-$PWD/runs/ablation-monocular}
mkdir -p "$WORK" && cd "$WORK"
B=${EVOGS:-evogs}
declare -A PIDS=([jump]=25423 [wave]=25424)
ROWS=phi,evo-requery,evo-buffer,trigger,full,k0,k0.5
run() { RAYON_NUM_THREADS=1 nice -n 10 $B ablate --data scenes/$1 --out ladder-seed$2/$1 --preset tiny \
    --iterations 4000 --seed $2 --rows $ROWS > ladder-seed$2-$1.log 2>&1; }
for scene in jump wave; do run $scene 2 & done
for scene in jump wave; do
  ( while ! grep -q "seed 1: started" ladder-$scene.log; do sleep 10; done
    kill "${PIDS[$scene]}"; echo "$(date -u) stopped 3-seed $scene after seed 0" >> extra.out
    run $scene 1 ) &
done
wait
