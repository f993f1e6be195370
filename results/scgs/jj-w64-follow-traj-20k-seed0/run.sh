#!/bin/bash
# binary of 6811775
set -e
B=/tmp/evogs-6811775
R=/tmp/runs/jj-scgs-20k-traj-s0
export RAYON_NUM_THREADS=1
$B train --data /work/shared/data/dnerf-jumpingjacks --out $R --method baseline --backbone scgs --control-width 64 --control-follow-densify --control-placement trajectories --preset dnerf --max-gaussians 20000 --time-budget 40m --seed 0
$B eval --run $R --split test --lpips-vgg
$B eval --run $R --split val --lpips-vgg
echo DONE
