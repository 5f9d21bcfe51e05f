# Images whose outcome changed between two robust runs of the same scenes
# (--errors CSVs), within R1's ranges: per family, before -> after among
# lost, wrong, right (+acc: accepted); then the after run's estimates whose
# detection margin is under 1 (found under the threshold). Usage, from the
# repository root:
#   python3 docs/results/robust/found-margin/changed.py BEFORE.csv[.gz] AFTER.csv[.gz]
import csv, gzip, sys, collections
R1 = {'clean': None, 'exposure': (0.6, 1.5), 'brightness': (0.6, 1.5),
      'colour_temperature': (3500, 6500), 'noise': (0, 6), 'blur': (0, 2),
      'jpeg': (60, 100), 'occlusion': (0, 0.3), 'occluding_object': (0, 0.3),
      'distance': (0.7, 1.5)}
def within(r):
    lo = R1.get(r['family'], 'x')
    if lo == 'x': return False
    return lo is None or lo[0]-1e-9 <= float(r['level']) <= lo[1]+1e-9
def rd(p):
    f=(gzip.open if p.endswith('gz') else open)(p,'rt')
    return {(r['object'],r['family'],r['level'],r['background'],r['image']):r for r in csv.DictReader(f) if within(r)}
a=rd(sys.argv[1]); b=rd(sys.argv[2])
st=lambda r: 'lost' if r['est_phi_deg']=='' else ('wrong' if r['failure']=='1' else 'right')+('+acc' if r['accepted']=='1' else '')
c=collections.Counter(); low=collections.Counter()
for k,r in b.items():
    o=a[k]
    if st(o)!=st(r):
        c[(k[1], st(o), st(r))]+=1
    if r['score_margin'] and float(r['score_margin'])<1: low[(k[1], st(r))]+=1
print('changed outcome (family, before, after): n'); [print(' ',k,v) for k,v in sorted(c.items())]
print('after: estimates whose detection margin < 1 (family, outcome): n'); [print(' ',k,v) for k,v in sorted(low.items())]
