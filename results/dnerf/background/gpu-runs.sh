#!/usr/bin/env bash
# Issue 22 on a lent GPU: random vs black background, lego, dnerf preset, 8 runs side by side.
set -u
start=$SECONDS
R=$OUT/r; mkdir -p $R
log() { echo "[$((SECONDS - start)) s] $*" | tee -a $R/progress.txt; tar -C $OUT -czf $OUT/r.tar.gz r; }
for f in .gl/*.deb; do dpkg -x $f / >/dev/null; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
mkdir -p /tmp/b && tar -C /tmp/b -xzf .dev/bin.tar.gz
B=/tmp/b; export LD_LIBRARY_PATH=$PWD/.dev/lib
ln -sfn $PWD/.dev/lego/train .dev/lego-holdout/train
nvidia-smi --query-gpu=name,driver_version --format=csv > $R/gpu.txt 2>&1; nproc >> $R/gpu.txt
BUDGET=${BUDGET:-300}
log "training, $BUDGET s wall each"
for data in lego lego-holdout; do for m in baseline evogs; do for bg in black random; do
  id=$data-$m-$bg
  ( RAYON_NUM_THREADS=2 $B/evogs train --data .dev/$data --out /tmp/$id --preset dnerf --method $m \
      --background $bg --seed ${SEED:-0} --backend wgpu --time-budget $BUDGET --budget-clock wall > $R/train-$id.log 2>&1
    cp /tmp/$id/train_metrics.json $R/metrics-$id.json
    splits="val train"; [ $data = lego ] && splits="val test train"
    for s in $splits; do
      RAYON_NUM_THREADS=2 $B/evogs eval --run /tmp/$id --split $s --backend wgpu > $R/eval-$id-$s.log 2>&1
      cp /tmp/$id/eval_$s.json $R/eval-$id-$s.json
    done
    if [ $data = lego ]; then
      RAYON_NUM_THREADS=2 $B/evogs render --run /tmp/$id --camera dataset:val:0 --sweep 5 --out /tmp/sweep-$id --backend wgpu > $R/render-$id.log 2>&1
      cp /tmp/sweep-$id/strip.png $R/strip-$id.png
    fi
    echo "[$((SECONDS - start)) s] $id done" >> $R/progress.txt ) &
done; done; done
sleep 200; log "training"
wait
for f in $R/eval-*.log; do echo "$(basename $f): $(grep -h 'mean PSNR' $f)"; done | tee $R/summary.txt
log end
