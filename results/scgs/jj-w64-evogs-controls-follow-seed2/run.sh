#!/bin/bash
export RAYON_NUM_THREADS=1
/tmp/evogs-de6a84c bench --data /work/shared/data/dnerf-jumpingjacks --out /tmp/runs/jj-evogs-follow-s2 --methods evogs --backbone scgs --control-width 64 --control-follow-densify --preset dnerf --time-budget 40m --eval-every 4000 --lpips-vgg --seed 2
echo DONE
