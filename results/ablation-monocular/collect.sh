#!/bin/bash
# Copies the ladder's outputs into the repository's results/ablation-monocular/.
# WORK: the folder the runs were made in (default ./runs/ablation-monocular); EVOGS: the evogs binary (default evogs on PATH).
set -euo pipefail
R=$(cd "$(dirname "$0")" && pwd)
WORK=${WORK:-$PWD/runs/ablation-monocular}
cd "$WORK"

mkdir -p $R
for d in ladder/jump ladder/wave ladder/jumpingjacks ladder-seed1/jump ladder-seed1/wave ladder-seed2/jump ladder-seed2/wave; do
  [ -f $d/ablation.json ] || continue
  mkdir -p $R/$d; cp $d/ablation.md $d/ablation.json $d/ablation.png $R/$d/
done
{ for s in jump wave jumpingjacks; do python3 merge.py . $s; echo; done; } > $R/tables.md
python3 plot.py . $R/ablation.svg jump wave jumpingjacks
cp ladder.sh extra.sh merge.py plot.py collect.sh load.log $R/
cp ../tools/strip.sh $R/
