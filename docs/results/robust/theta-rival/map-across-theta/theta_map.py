# A map rival across theta, explored offline (not adopted): joins a run's
# --errors file (BEFORE) with the same run from the exploratory build
# (explore-theta-map.diff, ACCH_EXPLORE_THETA_MAP=1: its `map_rival`
# column holds the best share among views >= 10 deg away in theta within
# 10 deg in phi, minus the estimate's own), and prints what each bar
# would reject. Usage, from the repository root:
#   python3 docs/results/robust/theta-rival/map-across-theta/theta_map.py \
#     docs/results/robust/colour-map/dev-s3-n12.csv.gz \
#     docs/results/robust/theta-rival/map-across-theta/theta-map-s3-n12.csv.gz
import csv,gzip,sys
def read(p):
    op=gzip.open if p.endswith('.gz') else open
    return list(csv.DictReader(op(p,'rt')))
base=read(sys.argv[1]); th=read(sys.argv[2])
assert len(base)==len(th)
for a,b in zip(base,th):
    assert (a['object'],a['family'],a['level'],a['image'],a['est_theta_deg'])==(b['object'],b['family'],b['level'],b['image'],b['est_theta_deg'])
def f(x):
    try: return float(x)
    except: return float('nan')
acc=[(a,f(b['map_rival'])) for a,b in zip(base,th) if a['accepted']=='1']
wrong=[(a,t) for a,t in acc if a['failure']=='1']
right=[t for a,t in acc if a['failure']=='0']
print('accepted',len(acc),'wrong',len(wrong))
for a,t in wrong:
    print('  wrong',a['object'],a['family'],a['level'],'dth',a['abs_dtheta_deg'],'dphi',a['abs_dphi_deg'],'map',a['map_rival'],'theta_map %.3f'%t)
import math
r=sorted(x for x in right if not math.isnan(x))
q=lambda p: r[min(len(r)-1,int(p*len(r)))]
print('right theta_map quantiles 50/90/95/99/99.5/max: %.3f %.3f %.3f %.3f %.3f %.3f'%(q(.5),q(.9),q(.95),q(.99),q(.995),r[-1]))
for bar in [0.0,0.02,0.05,0.08,0.1,0.15]:
    rej_right=sum(1 for x in right if x>bar)
    rej_wrong=sum(1 for a,t in wrong if t>bar)
    print('bar %.2f: rejects %d right, %d wrong'%(bar,rej_right,rej_wrong))
