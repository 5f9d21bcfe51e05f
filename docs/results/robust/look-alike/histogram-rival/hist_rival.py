# The rival rule read on the histogram's response alone (before the colour
# layout lowers it), measured on the development seed with the exploratory
# patch hist-rival.diff (against 1e65fe4; not kept). Its --errors file has
# three more columns: trv = the best match beyond 20 deg of the chosen
# view's azimuth over the chosen view's, both in the histogram's response;
# tre = the same over that response's maximum; fre = the chosen view's
# value over that maximum. Usage, from the repository root:
#   python3 docs/results/robust/look-alike/histogram-rival/hist_rival.py
import csv, gzip, collections, statistics

R1 = {'clean': None, 'exposure': (0.6, 1.5), 'brightness': (0.6, 1.5),
      'colour_temperature': (3500, 6500), 'noise': (0, 6), 'blur': (0, 2),
      'jpeg': (60, 100), 'occlusion': (0, 0.3), 'occluding_object': (0, 0.3),
      'distance': (0.7, 1.5)}


def in_range(r):
    rng = R1[r['family']]
    return rng is None or rng[0] - 1e-9 <= float(r['level']) <= rng[1] + 1e-9


path = 'docs/results/robust/look-alike/histogram-rival/hist-rival-s3.csv.gz'
rows = [r for r in csv.DictReader(gzip.open(path, 'rt')) if in_range(r)]
value = lambda r, c: float(r[c]) if r[c] != '' else 0.0
print('the chosen view in the histogram alone, over its best (deciles):',
      [round(x, 3) for x in statistics.quantiles(
          [value(r, 'fre') for r in rows if r['fre'] != ''], n=10)])


def report(name, accept):
    levels = collections.defaultdict(lambda: [0, 0, 0])
    total = [0, 0]
    for r in rows:
        a = accept(r)
        w = a and r['failure'] == '1'
        k = levels[(r['family'], r['level'])]
        k[0] += 1; k[1] += a; k[2] += w
        total[0] += a; total[1] += w
    worst = {}
    for (f, _), (n, a, w) in levels.items():
        o = worst.get(f, (100, 0))
        worst[f] = (min(o[0], 100 * a / n), max(o[1], 100 * w / max(a, 1)))
    print(f'{name:32s} accepted {total[0]}, wrong {total[1]}; worst accepted / wrong %: ' +
          ', '.join(f'{f} {a:.0f}/{w:.1f}' for f, (a, w) in worst.items()))


accepted = lambda r: r['accepted'] == '1'
report('as built (layout response)', accepted)
for bar in (0.99, 0.98):
    report(f'and histogram rival <= {bar}', lambda r: accepted(r) and value(r, 'trv') <= bar)
    report(f'and histogram rival/max <= {bar}', lambda r: accepted(r) and value(r, 'tre') <= bar)
