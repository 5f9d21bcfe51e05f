# The exploratory patch's spatial column (explore-maps.diff: each estimate's
# candidates 0-60 deg about its best view in its slice, the share of the
# true visible part each holds in place, and the truth's nearest view): the
# gap, best view 20 deg or more away minus the estimate's, by family and
# outcome, and the acceptance a bar on it would leave. Usage:
#   python3 docs/results/robust/colour-map/explore_gap.py docs/results/robust/colour-map/explore-s3-n12.csv.gz
import csv,sys,gzip,collections
rows=[]
for f in sys.argv[1:]: rows+=list(csv.DictReader((gzip.open if f.endswith('gz') else open)(f,'rt')))
def parse(r):
    s=r['spatial']
    if not s: return None
    d={}
    for tok in s.split():
        k,v=tok.split(':')
        if not k.startswith('T'): d[float(k)]=float(v)
    return d
def gap(r, lim=20):
    d=parse(r)
    if not d: return None
    far=max([v for k,v in d.items() if abs(k)>=lim] or [0])
    return far-d.get(0.0,0)
for fam in ['clean','blur','occlusion','occluding_object']:
    for ok in '01':
        g=sorted(gap(r) for r in rows if r['family']==fam and r['accepted']=='1' and r['failure']==ok and gap(r) is not None)
        if g: print(fam,ok,len(g),[round(g[int(len(g)*p)],3) for p in (0.5,0.9,0.95,0.99)], 'max',round(g[-1],3))
for lim in [20,30]:
  for m in [0.02,0.03,0.04,0.05,0.07,0.1]:
    acc=collections.Counter(); wr=collections.Counter(); tot=collections.Counter()
    for r in rows:
        k=(r['family'],r['level']); tot[k]+=1
        if r['accepted']!='1': continue
        g=gap(r,lim)
        if g is None or g < m:
            acc[k]+=1; wr[k]+=r['failure']=='1'
    worst=max(((wr[k]/acc[k]*100 if acc[k] else 0),k) for k in tot)
    low=min((acc[k]/tot[k]*100,k) for k in tot)
    print(f"lim {lim} m={m:+.2f} accepted {sum(acc.values())} wrong {sum(wr.values())} worst {worst[0]:.1f}% {worst[1]} lowest acc {low[0]:.0f}% {low[1]}")
