#!/usr/bin/env bash
# Issue 22: Φ's (and the baseline network's) learning rate decayed over the whole run, as D-3DGS
# decays its network's over its 40 000 steps, instead of the `dnerf` preset's 40 000 · N / 12 000
# (which ends at ~1.2e-4 instead of 1.6e-6). A.16's binary (4753ae8 + flags) has no flag for it,
# so the run is started for one step, its config.json's `lr.deform_max_steps` set to DECAY
# (12 000: the schedule's N), and the run resumed; everything else is A.16's protocol
# (phishape/run.sh). Since 28d2f97, `evogs train ... --net-lr-decay 12000` does the same.
# Usage: [SEED=N] [BUDGET=45m] [BIN=PATH] [DECAY=12000] [METHOD=evogs] run.sh SCENE CAP ID FLAGS...
set -eu
here=$(cd "$(dirname "$0")" && pwd)   # before the cd below
O=/work/runs/lrdecay; mkdir -p $O; cd $O
B=${BIN:-/work/runs/evogs-phiflags-pc}
scene=$1; cap=$2; id=$scene-$3; shift 3
RAYON_NUM_THREADS=1 $B train --data /work/shared/data/dnerf-$scene --out $O/$id --preset dnerf \
    --method ${METHOD:-evogs} --seed ${SEED:-0} --max-gaussians $cap --time-budget ${BUDGET:-45m} \
    --stop-after 1 "$@" > $O/$id.log0 2>&1
python3 - "$O/$id/config.json" "${DECAY:-12000}" <<'PY'
import json, sys
p, decay = sys.argv[1], int(sys.argv[2])
c = json.load(open(p))
assert c["train"]["lr"]["deform_max_steps"] == 40000, c["train"]["lr"]
c["train"]["lr"]["deform_max_steps"] = decay
json.dump(c, open(p, "w"), indent=2)
PY
RAYON_NUM_THREADS=1 /usr/bin/time -v $B train --out $O/$id --resume > $O/$id.log 2> $O/$id.time
"$here"/../eval-splits.sh "$B" "$O" "$id" "$scene"
