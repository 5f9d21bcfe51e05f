# The robust protocol's --errors CSV over R1's ranges: failures, and how
# many of them the database itself cannot tell from the truth (the truth's
# nearest training view rates the estimate's view at or above the rival
# bar, column look_alike). Worst level per family: failures % / failures
# the database could tell % / accepted % / wrong among accepted %.
# Usage, from the repository root:
#   python3 docs/results/robust/look-alike/look_alike.py ERRORS.csv[.gz] ...
import csv, gzip, sys, collections

BAR = 0.99  # acch_confidence::MAX_RIVAL_RATIO
R1 = {'clean': None, 'exposure': (0.6, 1.5), 'brightness': (0.6, 1.5),
      'colour_temperature': (3500, 6500), 'noise': (0, 6), 'blur': (0, 2),
      'jpeg': (60, 100), 'occlusion': (0, 0.3), 'occluding_object': (0, 0.3),
      'distance': (0.7, 1.5)}


def in_range(r):
    rng = R1.get(r['family'])
    if r['family'] not in R1:
        return False
    if rng is None:
        return True
    return rng[0] - 1e-9 <= float(r['level']) <= rng[1] + 1e-9


rows = []
for f in sys.argv[1:]:
    with (gzip.open if f.endswith('gz') else open)(f, 'rt') as fh:
        rows += [r for r in csv.DictReader(fh) if in_range(r)]
fail = lambda r: r['failure'] == '1'
alike = lambda r: fail(r) and r['look_alike'] != '' and float(r['look_alike']) >= BAR
acc = lambda r: r['accepted'] == '1'
above = lambda r: float(r['theta_deg']) >= 80
n_f = sum(map(fail, rows))
n_a = sum(map(alike, rows))
print(f"objects {len(set(r['object'] for r in rows))}, images {len(rows)}")
print(f"failures {n_f}, of which the database cannot tell from the truth {n_a} "
      f"(from above {sum(alike(r) and above(r) for r in rows)} of "
      f"{sum(fail(r) and above(r) for r in rows)}); not found "
      f"{sum(r['est_theta_deg'] == '' for r in rows)}")
print(f"accepted {sum(map(acc, rows))}, accepted wrong {sum(acc(r) and fail(r) for r in rows)}, "
      f"of which alike {sum(acc(r) and alike(r) for r in rows)}")
levels = collections.defaultdict(list)
for r in rows:
    levels[(r['family'], r['level'])].append(r)
worst = {}
for (family, _), rs in levels.items():
    n = len(rs)
    a = sum(map(acc, rs))
    v = (100 * sum(map(fail, rs)) / n,
         100 * sum(fail(r) and not alike(r) for r in rs) / n,
         100 * a / n,
         100 * sum(acc(r) and fail(r) for r in rs) / max(a, 1))
    o = worst.get(family, (0, 0, 100, 0))
    worst[family] = (max(o[0], v[0]), max(o[1], v[1]), min(o[2], v[2]), max(o[3], v[3]))
print("family: worst level's failures / failures it could tell / accepted / wrong among accepted, %")
for family in R1:
    if family in worst:
        w = worst[family]
        print(f"  {family:20s} {w[0]:5.1f} / {w[1]:5.1f} / {w[2]:3.0f} / {w[3]:4.1f}")
