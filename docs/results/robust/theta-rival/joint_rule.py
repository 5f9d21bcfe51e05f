# A joint rule, measured offline and not adopted: reject an accepted estimate
# whose map rival exceeds A and whose rival exceeds B (both columns of a
# robust run's --errors file); per bar pair, the right and wrong estimates
# it would reject, the lowest acceptance of any level and the worst wrong
# share among the accepted, over R1's ranges. Usage, from the repository root:
#   python3 docs/results/robust/theta-rival/joint_rule.py docs/results/robust/theta-rival/dev-s3-n12.csv.gz ...
import csv,gzip,math,sys,collections
R1 = {'clean': None, 'exposure': (0.6, 1.5), 'brightness': (0.6, 1.5),
      'colour_temperature': (3500, 6500), 'noise': (0, 6), 'blur': (0, 2),
      'jpeg': (60, 100), 'occlusion': (0, 0.3), 'occluding_object': (0, 0.3),
      'distance': (0.7, 1.5)}
def within(r):
    if r['family'] not in R1: return False
    lh=R1[r['family']]
    return lh is None or lh[0]-1e-9 <= float(r['level']) <= lh[1]+1e-9
def f(x):
    try: return float(x)
    except: return float('nan')
for path in sys.argv[1:]:
    rows=[r for r in csv.DictReader(gzip.open(path,'rt')) if within(r)]
    print(path)
    for a in [0.0,0.005,0.01]:
        for b in [0.9,0.95,0.97]:
            lv=collections.defaultdict(lambda:[0,0,0])
            rr=rw=0
            for r in rows:
                k=lv[(r['family'],r['level'])]
                acc=r['accepted']=='1'
                if acc and f(r['map_rival'])>a and f(r['rival'])>b:
                    acc=False; rr+=r['failure']=='0'; rw+=r['failure']=='1'
                k[0]+=1; k[1]+=acc; k[2]+=acc and r['failure']=='1'
            worst_acc=min(v[1]/v[0] for v in lv.values())
            worst_w=max((v[2]/v[1] if v[1] else 0,key) for key,v in lv.items())
            print('  map>%.3f rival>%.2f: rejects right %d wrong %d; min accepted %.1f%%; worst wrong %.2f%% %s'%(a,b,rr,rw,100*worst_acc,100*worst_w[0],worst_w[1]))
