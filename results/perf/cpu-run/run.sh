#!/bin/bash
# $1 = tag (old|new, or a commit: /work/runs/evogs-COMMIT), binary accordingly; lego cpu preset EvoGS seed 0, 2 threads, alone.
set -u
case $1 in old) B=/work/runs/evogs-591d409;; new) B=/work/runs/evogs-c4d9021;; *) B=/work/runs/evogs-$1;; esac
M=${2:-evogs}
O=/work/runs/cpurun/$1-$M
rm -rf $O
uptime > $O.uptime
/usr/bin/time -v $B train --data /work/shared/data/dnerf-lego --out $O --preset cpu --method $M --seed 0 --max-screen-radius 20 > $O.log 2> $O.time
uptime >> $O.uptime
mkdir -p /tmp/nolpips
for s in val test; do EVOGS_LPIPS_WEIGHTS=/tmp/nolpips $B eval --run $O --split $s > $O-eval-$s.log 2>&1; done
python3 - $O <<'PY'
import json,sys
d=json.load(open(sys.argv[1]+'/train_metrics.json'))
p=d['phases']; tot=sum(p.values())
print(sys.argv[1], 'iter', d['iteration'], 'secs %.1f'%d['seconds'], 'mean ms %.1f'%(1000*d['seconds']/d['iteration']), 'gaussians', d['gaussians'], ' '.join('%s %.1f'%(k,v) for k,v in p.items()))
PY
