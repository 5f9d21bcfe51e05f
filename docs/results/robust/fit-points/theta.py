import csv,gzip,sys,collections,math
def load(f):
    op=gzip.open if f.endswith('.gz') else open
    return list(csv.DictReader(op(f,'rt')))
def vertex(p0,p1,p2):
    (x0,y0),(x1,y1),(x2,y2)=p0,p1,p2
    d01=(y1-y0)/(x1-x0); d12=(y2-y1)/(x2-x1); a=(d12-d01)/(x2-x0)
    if not (a<0): return None
    b=d01-a*(x0+x1); return -b/(2*a)
def current(E):
    l2t,l2r,lt,lr,t0,b,ut,ur,u2t,u2r,resp=E[:11]
    L=None if math.isnan(lt) else (lt,lr); U=None if math.isnan(ut) else (ut,ur)
    L2=None if math.isnan(l2t) else (l2t,l2r); U2=None if math.isnan(u2t) else (u2t,u2r)
    if L and U:
        v=vertex(L,(t0,b),U); 
        return None if v is None else min(max(v,(lt+t0)/2),(t0+ut)/2)
    if L and not U:
        if not L2: return None
        v=vertex(L2,L,(t0,b)); return None if v is None else min(max(v,(lt+t0)/2),t0)
    if U and not L:
        if not U2: return None
        v=vertex((t0,b),U,U2); return None if v is None else min(max(v,t0),(t0+ut)/2)
    return None
