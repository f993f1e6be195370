#!/bin/bash
# binary of a2d4419 (the training code of main at cbf302a)
export RAYON_NUM_THREADS=1
/tmp/evogs-traj bench --data /work/shared/data/dnerf-jumpingjacks --out /tmp/runs/jj-d3dgs-s0 --methods baseline --preset dnerf --time-budget 40m --eval-every 4000 --lpips-vgg --seed 0
echo DONE
