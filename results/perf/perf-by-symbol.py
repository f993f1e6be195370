import subprocess,collections,sys,re
files=sys.argv[3:]; iters=int(sys.argv[1]); hz=float(sys.argv[2])
c=collections.Counter()
for f in files:
    out=subprocess.run(['perf','script','-i',f,'-F','ip,sym'],capture_output=True,text=True).stdout
    for line in out.splitlines():
        c[line.strip().split(None,1)[-1][:120]]+=1
# split run_avx2 monomorphs by mangled name
c2=collections.Counter()
for f in files:
    out=subprocess.run(['perf','script','-i',f,'-F','ip,sym','--no-demangle'],capture_output=True,text=True).stdout
    for line in out.splitlines():
        if 'splat_raster' in line and 'run_avx2' in line: c2[line.strip().split(None,1)[-1]]+=1
tot=sum(c.values()); n=len(files)*iters
print(f"{tot} samples, {tot/hz/n*1000:.1f} ms CPU per iteration")
for k,v in c2.items(): print(f"{v/hz/n*1000:7.2f} ms {100*v/tot:5.1f}%  {k}")
for k,v in c.most_common(22): print(f"{v/hz/n*1000:7.2f} ms {100*v/tot:5.1f}%  {k}")
