# Before and after the crest rule, the same images: worst level over R1's
# ranges per family, failures / accepted / wrong among the accepted %,
# and the totals. Usage, from the repository root:
#   python3 docs/results/robust/crest/crest.py BEFORE.csv.gz AFTER.csv.gz
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


before, after = read(sys.argv[1]), read(sys.argv[2])
assert before.keys() == after.keys(), 'the same images'
same = sum(before[k]['est_phi_deg'] == after[k]['est_phi_deg'] and
           before[k]['failure'] == after[k]['failure'] for k in before)
print(f'{len(before)} images over R1\'s ranges, {same} with the same estimate and failure')


def worst(rows):
    lv = collections.defaultdict(lambda: [0, 0, 0, 0])
    for r in rows.values():
        k = lv[(r['family'], r['level'])]
        a = r['accepted'] == '1'
        k[0] += 1; k[1] += r['failure'] == '1'; k[2] += a; k[3] += a and r['failure'] == '1'
    out = {}
    for (fam, _), (n, f, a, w) in lv.items():
        o = out.get(fam, (0, 100, 0))
        out[fam] = (max(o[0], 100 * f / n), min(o[1], 100 * a / n), max(o[2], 100 * w / max(a, 1)))
    return out


wb, wa = worst(before), worst(after)
print(f'{"family":20s} {"before":>20s} {"after":>20s}')
for fam in R1:
    if fam in wb:
        print(f'{fam:20s} {"%5.1f / %3.0f / %4.1f" % wb[fam]:>20s} {"%5.1f / %3.0f / %4.1f" % wa[fam]:>20s}')
for name, rows in (('before', before), ('after', after)):
    acc = [r for r in rows.values() if r['accepted'] == '1']
    wrong = [r for r in acc if r['failure'] == '1']
    print(f'{name}: failures {sum(r["failure"] == "1" for r in rows.values())}, accepted {len(acc)}, '
          f'accepted wrong {len(wrong)} ({sum(r["family"] in ("occlusion", "occluding_object") for r in wrong)} '
          f'occluded)')
lost = [k for k in before if before[k]['accepted'] == '1' and after[k]['accepted'] == '0']
print(f'no longer accepted: {len(lost)}, of them wrong {sum(before[k]["failure"] == "1" for k in lost)}; '
      f'newly accepted: {sum(before[k]["accepted"] == "0" and after[k]["accepted"] == "1" for k in before)}')
