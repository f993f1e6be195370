#!/usr/bin/env python3
"""Mean ± std (sample std, n-1) over seeds of each ladder row, per scene, from ablation.json files.
Also the paired difference of each row against `phi` (same seed), mean ± std."""
import json, glob, statistics as st, sys, os
root = sys.argv[1] if len(sys.argv) > 1 else '.'
for scene in sorted(os.listdir(root)):
    files = sorted(glob.glob(f'{root}/{scene}/seed*/ablation.json') + glob.glob(f'{root}/{scene}/ablation-seed*.json'))
    if not files: continue
    runs = {json.load(open(f))['seed']: {r['name']: r for r in json.load(open(f))['rows']} for f in files}
    seeds = sorted(runs)
    names = [r['name'] for r in json.load(open(files[0]))['rows']]
    print(f'\n### {scene}: seeds {seeds}, {json.load(open(files[0]))["iterations"]} iterations per row\n')
    print('| row | test PSNR (dB) | val PSNR (dB) | test − phi (dB, paired) | val − phi (dB, paired) | SSIM | lpips_alex | flicker | Gaussians |')
    print('| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |')
    def ms(xs, fmt='{:.2f}'):
        if len(xs) == 1: return fmt.format(xs[0])
        return fmt.format(st.mean(xs)) + ' ± ' + fmt.replace('+', '').format(st.stdev(xs))
    for n in names:
        rows = [runs[s][n] for s in seeds if n in runs[s]]
        g = lambda k: [r[k] for r in rows]
        dt = [runs[s][n]['psnr'] - runs[s]['phi']['psnr'] for s in seeds if n in runs[s] and 'phi' in runs[s]]
        dv = [runs[s][n]['val_psnr'] - runs[s]['phi']['val_psnr'] for s in seeds if n in runs[s] and 'phi' in runs[s]]
        print(f"| {n} | {ms(g('psnr'))} | {ms(g('val_psnr'))} | {ms(dt, '{:+.2f}')} | {ms(dv, '{:+.2f}')} | {ms(g('ssim'), '{:.4f}')} | {ms(g('lpips_alex'), '{:.4f}')} | {ms(g('flicker'), '{:.5f}')} | {ms(g('gaussians'), '{:.0f}')} |")
