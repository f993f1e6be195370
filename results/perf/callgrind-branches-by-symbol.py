import re,sys,collections
names={}; cur=None; skip=False; ex=collections.defaultdict(lambda:[0]*5); ev=None
for line in open(sys.argv[1]):
    line=line.rstrip('\n')
    if line.startswith('events:'): ev=line.split()[1:]; continue
    if line.startswith('fn='):
        m=re.match(r'fn=\((\d+)\)(?: (.*))?',line)
        if m.group(2): names[m.group(1)]=m.group(2)
        cur=names[m.group(1)]; continue
    if line.startswith(('cfn=',)):
        m=re.match(r'cfn=\((\d+)\)(?: (.*))?',line)
        if m and m.group(2): names[m.group(1)]=m.group(2)
        continue
    if line.startswith(('cfi=','cfl=','cob=','ob=','fl=','fi=','fe=')): continue
    if line.startswith('calls='): skip=True; continue
    if line and (line[0].isdigit() or line[0] in '+-*'):
        if skip: skip=False; continue
        parts=line.split()[1:]
        for i,p in enumerate(parts[:5]): ex[cur][i]+=int(p)
n=float(sys.argv[2])
print('events',ev)
for k,v in sorted(ex.items(),key=lambda kv:-kv[1][0])[:12]:
    print(f"{v[0]/n/1e6:8.1f} M Ir  Bc {v[1]/n/1e6:6.2f} M  Bcm {v[2]/n/1e6:6.3f} M ({100*v[2]/max(v[1],1):.1f} %)  {k[:80]}")
