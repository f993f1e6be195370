#!/usr/bin/env bash
# hook and mutant, dnerf preset (caps 10 000 / 40 000), 50 CPU-minutes per run, one thread each, two at a time
set -euo pipefail
DATA=/work/shared/data
( while true; do echo "$(date -u +%H:%M:%S) $(cat /proc/loadavg)"; sleep 60; done ) > uptime.txt &
mon=$!
/usr/bin/time -v /work/runs/evogs-591d409 bench --jobs 2 --data $DATA/dnerf-hook,$DATA/dnerf-mutant --out /work/runs/hm50/out \
  --preset dnerf --time-budget 50m --eval-every 2000 --lpips-vgg --seed 0 > bench.log 2> bench.err
kill $mon
