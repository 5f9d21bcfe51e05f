# The robust protocol's rows of a run against revision 6's stored
# evaluation-seed run on the same objects (the same images: poses are
# drawn per object), worst level over R1's ranges, failures / accepted /
# wrong among accepted %. Usage, from the repository root:
#   python3 docs/results/robust/layout/paired.py docs/results/robust/layout/subset-s7.csv.gz
import csv,gzip,sys,collections
old=list(csv.DictReader(gzip.open('docs/results/robust/blur-window/auto-s7.csv.gz','rt')))
new=[]
for f in sys.argv[1:]:
    new+=list(csv.DictReader((gzip.open if f.endswith('gz') else open)(f,'rt')))
objs=set(r['object'] for r in new)
old=[r for r in old if r['object'] in objs]
key=lambda r:(r['object'],r['family'],r['level'],r['background'],r['image'])
om={key(r):r for r in old}
same=sum(1 for r in new if key(r) in om and om[key(r)]['theta_deg']==r['theta_deg'] and om[key(r)]['phi_deg']==r['phi_deg'])
print('objects',len(objs),'images new',len(new),'old',len(old),'same truth',same)
# R1 ranges: the families' levels as in the tables (exposure 0.6-1.5 etc.)
R1={'clean':None,'exposure':(0.6,1.5),'brightness':(0.6,1.5),'colour_temperature':(3500,6500),'noise':(0,6),'blur':(0,2),'jpeg':(60,100),'occlusion':(0,0.3),'occluding_object':(0,0.3),'distance':(0.7,1.5)}
def inr(r):
    rng=R1[r['family']]
    if rng is None: return True
    l=float(r['level']); return rng[0]-1e-9<=l<=rng[1]+1e-9
def summ(rows,name):
    rows=[r for r in rows if inr(r)]
    fam=collections.defaultdict(lambda:[0,0,0,0])
    for x in rows:
        k=(x['family'],x['level']); fam[k][0]+=1; fam[k][1]+=x['failure']=='1'; fam[k][2]+=x['accepted']=='1'; fam[k][3]+=(x['accepted']=='1' and x['failure']=='1')
    worst=collections.defaultdict(lambda:(0,100,0))
    for (fa,l),(n,f_,a,w) in fam.items():
        fr,ar,wr=100*f_/n,100*a/n,100*w/max(a,1)
        o=worst[fa]; worst[fa]=(max(o[0],fr),min(o[1],ar),max(o[2],wr))
    fl=sum(r['failure']=='1' for r in rows); aw=sum(r['failure']=='1' and r['accepted']=='1' for r in rows); ac=sum(r['accepted']=='1' for r in rows)
    ab=sum(r['failure']=='1' and float(r['theta_deg'])>=80 for r in rows)
    print(name,'images',len(rows),'fail',fl,'above',ab,'accepted',ac,'accwrong',aw)
    for k,v in worst.items(): print(f"   {k:20s} {v[0]:5.1f} / {v[1]:3.0f} / {v[2]:4.1f}")
summ(old,'r6'); summ(new,'r7')
