# Failures and wrong among the accepted at 30 % occlusion, another object
# in front at 30 % and blur 2 px, from robust runs' --errors CSVs. Usage,
# from the repository root:
#   python3 docs/results/robust/found-faint/levels.py A.csv[.gz] [B.csv ...]
import csv,gzip,sys,collections
def rd(p):
    f=(gzip.open if p.endswith('gz') else open)(p,'rt')
    return list(csv.DictReader(f))
for p in sys.argv[1:]:
    c=collections.Counter()
    for r in rd(p):
        if r['family'] in('occlusion','occluding_object','blur') and r['level'] in('0.3','2'):
            k=(r['family'],r['level']); lost=r['est_phi_deg']==''
            c[k+('n',)]+=1; c[k+('f',)]+= lost or r['failure']=='1'; c[k+('a',)]+= r['accepted']=='1'; c[k+('aw',)]+= r['accepted']=='1' and r['failure']=='1'
    print(p.split('/')[-1], '  '.join('%s %s: fail %d/%d %.1f%%, acc wrong %d/%d %.2f%%'%(f,l,c[(f,l,'f')],c[(f,l,'n')],100*c[(f,l,'f')]/c[(f,l,'n')],c[(f,l,'aw')],c[(f,l,'a')],100*c[(f,l,'aw')]/c[(f,l,'a')]) for f,l in (('occlusion','0.3'),('occluding_object','0.3'),('blur','2'))))
