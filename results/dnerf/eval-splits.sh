#!/usr/bin/env bash
# Issue 22's evaluation of one finished run, as every run script here does it: the training views
# first (no LPIPS: an empty weights directory), then val (lego only) and test with LPIPS-VGG, one
# thread each; logs beside the run, then ID.done.
# Usage: eval-splits.sh BIN OUT ID SCENE   (the run is OUT/ID)
set -u
B=$1; O=$2; id=$3; scene=$4
mkdir -p /tmp/nolpips
EVOGS_LPIPS_WEIGHTS=/tmp/nolpips RAYON_NUM_THREADS=1 $B eval --run $O/$id --split train > $O/$id-eval-train.log 2>&1
if [ "$scene" = lego ]; then
  RAYON_NUM_THREADS=1 $B eval --run $O/$id --split val --lpips-vgg > $O/$id-eval-val.log 2>&1
fi
RAYON_NUM_THREADS=1 $B eval --run $O/$id --split test --lpips-vgg > $O/$id-eval-test.log 2>&1
echo done > $O/$id.done
