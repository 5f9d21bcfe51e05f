# The map rival's bar, applied offline to a run whose --errors file has
# the map_rival column (built with a bar at least as loose as any tried):
# worst level over R1's ranges per family, failures / accepted / wrong
# among the accepted %, and the totals, for each bar; BEFORE (a run
# without the rule, the same images) for comparison. Usage, from the
# repository root:
#   python3 docs/results/robust/colour-map/map_rival.py BEFORE.csv[.gz] AFTER.csv[.gz] [BAR ...]
import csv, gzip, sys, collections

R1 = {'clean': None, 'exposure': (0.6, 1.5), 'brightness': (0.6, 1.5),
      'colour_temperature': (3500, 6500), 'noise': (0, 6), 'blur': (0, 2),
      'jpeg': (60, 100), 'occlusion': (0, 0.3), 'occluding_object': (0, 0.3),
      'distance': (0.7, 1.5)}


def within(r):
    if r['family'] not in R1:
        return False
    lo_hi = R1[r['family']]
    return lo_hi is None or lo_hi[0] - 1e-9 <= float(r['level']) <= lo_hi[1] + 1e-9


def read(path):
    f = (gzip.open if path.endswith('gz') else open)(path, 'rt')
    key = lambda r: (r['object'], r['family'], r['level'], r['background'], r['image'])
    return {key(r): r for r in csv.DictReader(f) if within(r)}


def accepted(r, bar):
    if r['accepted'] != '1':
        return False
    return bar is None or r['map_rival'] == '' or float(r['map_rival']) <= bar


def worst(rows, bar):
    lv = collections.defaultdict(lambda: [0, 0, 0, 0])
    for r in rows.values():
        k = lv[(r['family'], r['level'])]
        a = accepted(r, bar)
        k[0] += 1; k[1] += r['failure'] == '1'; k[2] += a; k[3] += a and r['failure'] == '1'
    out = {}
    for (fam, _), (n, f, a, w) in lv.items():
        o = out.get(fam, (0, 100, 0))
        out[fam] = (max(o[0], 100 * f / n), min(o[1], 100 * a / n), max(o[2], 100 * w / max(a, 1)))
    return out


before, after = read(sys.argv[1]), read(sys.argv[2])
bars = [float(b) for b in sys.argv[3:]] or [0.1, 0.05, 0.03, 0.02]
assert before.keys() == after.keys(), 'the same images'
same = sum(before[k]['est_phi_deg'] == after[k]['est_phi_deg'] and
           before[k]['failure'] == after[k]['failure'] for k in before)
print(f'{len(before)} images over R1\'s ranges, {same} with the same estimate and failure')
runs = [('before', before, None)] + [(f'bar {b:g}', after, b) for b in bars]
tables = [(name, worst(rows, bar)) for name, rows, bar in runs]
print(f'{"family":20s}' + ''.join(f'{name:>20s}' for name, _ in tables))
for fam in R1:
    if fam in tables[0][1]:
        print(f'{fam:20s}' + ''.join(f'{"%5.1f / %3.0f / %4.1f" % t[fam]:>20s}' for _, t in tables))
for name, rows, bar in runs:
    acc = [r for r in rows.values() if accepted(r, bar)]
    wrong = [r for r in acc if r['failure'] == '1']
    occluded = sum(r['family'] in ('occlusion', 'occluding_object') for r in wrong)
    print(f'{name}: failures {sum(r["failure"] == "1" for r in rows.values())}, accepted {len(acc)}, '
          f'accepted wrong {len(wrong)} ({occluded} occluded)')
