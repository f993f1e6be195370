#!/bin/bash
# strip.sh SCENE_DIR SPLIT OUT.png RUN... : top row ground truth, one row per run, views 0..n of SPLIT, 4x nearest upscale.
# WORK: the folder the runs were made in (default ./runs/ablation-monocular); EVOGS: the evogs binary (default evogs on PATH).
set -euo pipefail
B=${EVOGS:-evogs}
scene=$1; split=$2; out=$3; shift 3
tmp=$(mktemp -d)
n=$(python3 -c "import json;print(len(json.load(open('$scene/transforms_$split.json'))['frames']))")
idx=$(python3 -c "n=$n;k=min(n,6);print(' '.join(str(round(i*(n-1)/(k-1))) for i in range(k)))")
rows=()
gt=(); for i in $idx; do f=$(python3 -c "import json;print(json.load(open('$scene/transforms_$split.json'))['frames'][$i]['file_path'])"); f="$scene/${f#./}"; [[ $f == *.png ]] || f="$f.png"; ffmpeg -loglevel error -y -i "$f" -vf "format=rgba,geq=r='r(X,Y)*alpha(X,Y)/255':g='g(X,Y)*alpha(X,Y)/255':b='b(X,Y)*alpha(X,Y)/255':a=255" $tmp/gt$i.png; gt+=(-i $tmp/gt$i.png); done
k=$(echo $idx | wc -w)
ffmpeg -loglevel error -y "${gt[@]}" -filter_complex "hstack=inputs=$k" $tmp/row0.png
r=1
for run in "$@"; do
  ins=(); for i in $idx; do $B render --run $run --camera dataset:$split:$i --out $tmp/r$r-$i.png >/dev/null 2>&1; ins+=(-i $tmp/r$r-$i.png); done
  ffmpeg -loglevel error -y "${ins[@]}" -filter_complex "hstack=inputs=$k" $tmp/row$r.png
  r=$((r+1))
done
ins=(); for j in $(seq 0 $((r-1))); do ins+=(-i $tmp/row$j.png); done
ffmpeg -loglevel error -y "${ins[@]}" -filter_complex "vstack=inputs=$r,scale=iw*3:ih*3:flags=neighbor" $out
rm -rf $tmp
