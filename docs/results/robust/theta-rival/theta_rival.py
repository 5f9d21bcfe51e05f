# The rival in elevation, explored offline: joins a run's --errors file
# (BEFORE, the committed build) with the same run from the exploratory
# build (explore-theta-rival.diff, ACCH_EXPLORE_THETA_RIVAL=1: its `rival`
# column holds the best view more than 10 deg away in theta within 20 deg
# in phi, over the best), and prints, among the accepted, the wrong ones'
# value, the right ones' quantiles and what each bar would reject.
# Usage, from the repository root:
#   python3 docs/results/robust/theta-rival/theta_rival.py \
#     docs/results/robust/colour-map/dev-s5-n12.csv.gz \
#     docs/results/robust/theta-rival/explore-tr-s5-n12.csv.gz
import csv,gzip,sys,math,collections
def read(p):
    op=gzip.open if p.endswith('.gz') else open
    return list(csv.DictReader(op(p,'rt')))
base=read(sys.argv[1]); th=read(sys.argv[2])
assert len(base)==len(th)
def f(x):
    try: return float(x)
    except: return float('nan')
pairs=[]
for a,b in zip(base,th):
    assert (a['object'],a['family'],a['level'],a['image'],a['est_theta_deg'])==(b['object'],b['family'],b['level'],b['image'],b['est_theta_deg'])
    pairs.append((a,f(b['rival'])))
acc=[(a,t) for a,t in pairs if a['accepted']=='1']
wrong=[(a,t) for a,t in acc if a['failure']=='1']
right=[t for a,t in acc if a['failure']=='0']
print('accepted',len(acc),'wrong',len(wrong))
for a,t in wrong:
    print('  wrong',a['object'],a['family'],a['level'],'dth',a['abs_dtheta_deg'],'dphi',a['abs_dphi_deg'],'rival',a['rival'],'theta_rival %.3f'%t)
r=sorted(x for x in right if not math.isnan(x))
q=lambda p: r[min(len(r)-1,int(p*len(r)))]
print('right theta_rival quantiles 50/90/95/99/99.5/max: %.3f %.3f %.3f %.3f %.3f %.3f'%(q(.5),q(.9),q(.95),q(.99),q(.995),r[-1]))
tw=[(a,t) for a,t in wrong if float(a['abs_dtheta_deg'])>10]
for bar in [0.9,0.95,0.97,0.98,0.99,1.0]:
    rej=[a for a,t in acc if t>bar]
    rr=sum(1 for a in rej if a['failure']=='0'); rw=sum(1 for a in rej if a['failure']=='1')
    per=collections.Counter((a['family'],a['level']) for a in rej if a['failure']=='0')
    print('bar %.2f: rejects %d right, %d wrong (theta-wrong %d); worst level %s'%(bar,rr,rw,sum(1 for a,t in tw if t>bar), per.most_common(2)))
