import sys; import os; sys.path.insert(0, os.path.dirname(os.path.abspath(__file__))); from theta import *
import collections
def pts(E):
    l2t,l2r,lt,lr,t0,b,ut,ur,u2t,u2r=E[:10]
    P=[(l2t,l2r),(lt,lr),(t0,b),(ut,ur),(u2t,u2r)]
    return [p if not math.isnan(p[0]) else None for p in P]
def recentred(E, clampfull=False):
    P=pts(E)
    # argmax of r among the centre and its neighbours
    cand=[i for i in (1,2,3) if P[i]]
    c=max(cand,key=lambda i:P[i][1])
    if c==2: 
        v=current(E); return v if v is not None else E[4]
    # fit around c
    lo,hi=P[c-1],P[c+1]
    if lo and hi:
        v=vertex(lo,P[c],hi)
        if v is None: return P[c][0]
        return min(max(v,(lo[0]+P[c][0])/2),(P[c][0]+hi[0])/2)
    # edge: toward the centre side only
    return P[c][0]
def noclamp(E):
    P=pts(E)
    if P[1] and P[3]:
        v=vertex(P[1],P[2],P[3])
        if v is None: return E[4]
        return min(max(v,P[1][0]),P[3][0])
    v=current(E); return v if v is not None else E[4]
rules={'current':lambda E:(current(E) if current(E) is not None else E[4]),'recentred':recentred,'noclamp':noclamp}
for f in sys.argv[1:]:
    rows=[r for r in load(f) if r['light_search']=='1' and r['explore']]
    res={}
    for name,rule in rules.items():
        c=collections.Counter(); err=[]
        for r in rows:
            E=[float(x) for x in r['explore'].split(';')]
            t=rule(E); dt=abs(t-float(r['theta_deg'])); dp=float(r['abs_dphi_deg'])
            fail=dt>10 or dp>20
            err.append(dt)
            c['fail']+=fail
            if r['accepted']=='1': c['acc']+=1; c['accwrong']+=fail; c['accwrongθ']+= dt>10
            if r['family']=='clean': c['cleanfail']+=fail
        print(f[-12:],name,dict(c),'E(θ) %.3f'%(sum(err)/len(err)))
