#!/bin/bash
# gain_strip.sh SCENE CF OUT.png [FRAMES]: training views FRAMES (default 9..14) of SCENE; rows from the top:
# ground truth, K = 0 (prior), K = 1 (observation), learned K, from gain_counterfactual.py's output folder CF.
set -euo pipefail
scene=$1; cf=$2; out=$3; frames=${4:-"9 10 11 12 13 14"}
tmp=$(mktemp -d)
row() { local name=$1; shift; local ins=(); for f in "$@"; do ins+=(-i "$f"); done
  ffmpeg -loglevel error -y "${ins[@]}" -filter_complex "hstack=inputs=$#" $tmp/$name.png; }
gt=(); for i in $frames; do
  f=$(python3 -c "import json;print(json.load(open('$scene/transforms_train.json'))['frames'][$i]['file_path'])"); f="$scene/${f#./}"; [[ $f == *.png ]] || f="$f.png"
  ffmpeg -loglevel error -y -i "$f" -vf "format=rgba,geq=r='r(X,Y)*alpha(X,Y)/255':g='g(X,Y)*alpha(X,Y)/255':b='b(X,Y)*alpha(X,Y)/255':a=255,format=rgb24" $tmp/gt$i.png; gt+=($tmp/gt$i.png); done
row r0 "${gt[@]}"
r=1; for v in prior observation learned; do fs=(); for i in $frames; do fs+=($(printf "$cf/$v/renders/train/%04d.png" $i)); done; row r$r "${fs[@]}"; r=$((r+1)); done
ffmpeg -loglevel error -y -i $tmp/r0.png -i $tmp/r1.png -i $tmp/r2.png -i $tmp/r3.png -filter_complex "vstack=inputs=4,scale=iw*3:ih*3:flags=neighbor" $out
rm -rf $tmp
