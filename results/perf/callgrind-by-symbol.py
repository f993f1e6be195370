import re,sys,collections
names={}; cur=None; skip=False; ex=collections.Counter()
for line in open(sys.argv[1]):
    line=line.rstrip('\n')
    if line.startswith('fn='):
        m=re.match(r'fn=\((\d+)\)(?: (.*))?',line)
        if m.group(2): names[m.group(1)]=m.group(2)
        cur=names[m.group(1)]; continue
    if line.startswith(('cfn=','cfi=','cfl=','cob=')):
        m=re.match(r'c(fn)=\((\d+)\)(?: (.*))?',line)
        if m and m.group(3): names[m.group(2)]=m.group(3)
        continue
    if line.startswith('calls='): skip=True; continue
    if line and (line[0].isdigit() or line[0] in '+-*'):
        if skip: skip=False; continue
        parts=line.split()
        if len(parts)>=2 and cur: ex[cur]+=int(parts[-1])
tot=sum(ex.values()); n=float(sys.argv[2])
print('total',tot/n/1e6,'M per iteration')
for k,v in ex.most_common(25): print(f"{v/n/1e6:8.1f} M  {100*v/tot:5.1f}%  {k[:140]}")
