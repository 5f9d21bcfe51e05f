import sys; import os; sys.path.insert(0, os.path.dirname(os.path.abspath(__file__))); from theta import *
import collections
def signed(a,b):
    d=(a-b+180)%360-180; return d
tot=collections.Counter()
for f in sys.argv[1:]:
    c=collections.Counter()
    for r in load(f):
        if r['light_search']!='1' or r['accepted']!='1' or not r['explore']: continue
        E=[float(x) for x in r['explore'].split(';')]
        if math.isnan(E[11]): continue
        rs=[E[12],E[13],E[5],E[14],E[15]]
        am=max(range(5),key=lambda i:rs[i])
        # phi-ramp: r at +-2 above centre
        flag = am in (0,4)
        w = r['failure']=='1'
        wp = w and float(r['abs_dphi_deg'])>20
        c[('flag' if flag else 'ok', 'W' if w else 'R')]+=1
        if wp:
            s=signed(float(r['est_phi_deg']),float(r['phi_deg']))
            print(f[-10:], r['family'],r['level'],'signed est-truth %.1f'%s, 'r',[round(x,3) for x in rs], 'argmax',am-2)
    print(f, dict(c)); tot.update(c)
print(dict(tot))
