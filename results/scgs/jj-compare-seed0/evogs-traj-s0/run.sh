#!/bin/bash
# binary of a2d4419 (the training code of main at cbf302a)
export RAYON_NUM_THREADS=1
/tmp/evogs-traj bench --data /work/shared/data/dnerf-jumpingjacks --out /tmp/runs/jj-evogs-traj-s0 --methods evogs --backbone scgs --control-width 64 --evolution-on controls --control-follow-densify --control-placement trajectories --preset dnerf --time-budget 40m --eval-every 4000 --lpips-vgg --seed 0
echo DONE
