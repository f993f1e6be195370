#!/usr/bin/env bash
# Issue 22, A.21: one lego run of the `dnerf` preset under a CPU budget, then its val split scored
# without LPIPS (on the held-out copy of scripts/holdout, val is the held-out training frames).
# PRIOR=λ trains EvoGS with λ_prior = λ (no flag sets it): the run is started for one step, its
# config.json and evo_state.safetensors given the value (set_lambda_prior.py), and resumed.
# Usage: [SEED=0] [BUDGET=24m] [THREADS=1] [METHOD=evogs] [PRIOR=λ] [BIN=PATH] [O=DIR] \
#        run.sh DATA ID FLAGS...
set -eu
here=$(cd "$(dirname "$0")" && pwd)
B=${BIN:-/work/main/target/release/evogs}; O=${O:-/work/runs}; cd "$O"
data=$1; id=$2; shift 2
args=(--data "$data" --out "$id" --preset dnerf --method "${METHOD:-evogs}" --seed "${SEED:-0}"
      --time-budget "${BUDGET:-24m}" "$@")
train() { /usr/bin/time -v env RAYON_NUM_THREADS=${THREADS:-1} "$B" train "$@"; }
if [ -n "${PRIOR:-}" ]; then
  train "${args[@]}" --stop-after 1 > "$id.log0" 2>&1
  python3 "$here/set_lambda_prior.py" "$id" "$PRIOR"
  args=(--out "$id" --resume)
fi
train "${args[@]}" > "$id.log" 2> "$id.time"
mkdir -p /tmp/nolpips
EVOGS_LPIPS_WEIGHTS=/tmp/nolpips RAYON_NUM_THREADS=1 "$B" eval --run "$id" --split val > "$id-eval-val.log" 2>&1
echo done > "$id.done"
