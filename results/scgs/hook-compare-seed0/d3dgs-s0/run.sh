#!/bin/bash
# binary of 6811775
export RAYON_NUM_THREADS=1
/tmp/evogs-6811775 bench --data /work/shared/data/dnerf-hook --out /tmp/runs/hook-d3dgs-s0 --methods baseline --preset dnerf --time-budget 40m --eval-every 4000 --lpips-vgg --seed 0
echo DONE
