#!/bin/bash
# jj_strip.sh GT_DIR OUT.png RUN...: training views 0, 40, 80, 120, 160, 199; top row the dataset's images at the run's
# resolution (GT_DIR: a copy of the dataset scaled to it), one row per run (evogs render --camera dataset:train:I).
set -euo pipefail
B=${EVOGS:-evogs}
gt=$1; out=$2; shift 2
idx="0 40 80 120 160 199"
tmp=$(mktemp -d)
ins=(); for i in $idx; do
  f=$(python3 -c "import json;print(json.load(open('$gt/transforms_train.json'))['frames'][$i]['file_path'])"); f="$gt/${f#./}"; [[ $f == *.png ]] || f="$f.png"
  ffmpeg -loglevel error -y -i "$f" -vf "format=rgba,geq=r='r(X,Y)*alpha(X,Y)/255':g='g(X,Y)*alpha(X,Y)/255':b='b(X,Y)*alpha(X,Y)/255':a=255,format=rgb24" $tmp/gt$i.png; ins+=(-i $tmp/gt$i.png); done
ffmpeg -loglevel error -y "${ins[@]}" -filter_complex "hstack=inputs=6" $tmp/row0.png
r=1; for run in "$@"; do ins=(); for i in $idx; do $B render --run $run --camera dataset:train:$i --out $tmp/r$r-$i.png >/dev/null; ffmpeg -loglevel error -y -i $tmp/r$r-$i.png -vf format=rgb24 $tmp/s$r-$i.png; ins+=(-i $tmp/s$r-$i.png); done
  ffmpeg -loglevel error -y "${ins[@]}" -filter_complex "hstack=inputs=6" $tmp/row$r.png; r=$((r+1)); done
ins=(); for j in $(seq 0 $((r-1))); do ins+=(-i $tmp/row$j.png); done
ffmpeg -loglevel error -y "${ins[@]}" -filter_complex "vstack=inputs=$r,scale=iw*2:ih*2:flags=neighbor" $out
rm -rf $tmp
