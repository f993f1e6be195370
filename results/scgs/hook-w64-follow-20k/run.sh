#!/bin/bash
set -e
B=/tmp/evogs-a570285
export RAYON_NUM_THREADS=1
$B train --data /work/shared/data/dnerf-hook --out /tmp/runs/hook-scgs-20k --method baseline --backbone scgs --control-width 64 --control-follow-densify --preset dnerf --max-gaussians 20000 --time-budget 40m --seed 0
$B eval --run /tmp/runs/hook-scgs-20k --split test --lpips-vgg
$B eval --run /tmp/runs/hook-scgs-20k --split val --lpips-vgg
echo DONE
