"""The per-frame choice between the sharp and the smoothed database,
computed from two `acch eval --protocol robust --errors` files of the same
scenes: per image the smoothed chain's estimate is taken when its match
value exceeds RATIO times the sharp chain's (or the sharp one found
nothing). Prints failures / accepted / failures among the accepted (%) per
row for the sharp chain, the smoothed one and the choice, and the worst over
the issue's ranges.

python3 choose_by_match.py SHARP.csv[.gz] SMOOTHED.csv[.gz] [RATIO ...]
"""
import collections
import csv
import gzip
import sys

RANGES = {'clean': (0, 0), 'exposure': (0.6, 1.5), 'brightness': (0.6, 1.5),
          'colour_temperature': (3500, 6500), 'noise': (0, 6), 'blur': (0, 2),
          'jpeg': (60, 100), 'occlusion': (0, 0.3), 'distance': (0.7, 1.5)}


def load(path):
    opener = gzip.open if path.endswith('.gz') else open
    with opener(path, 'rt') as f:
        return {(r['object'], r['family'], r['level'], r['background'], r['image']): r
                for r in csv.DictReader(f)}


def match(r):
    return float(r['match_value']) if r['match_value'] else -1.0


def rates(rows):
    n = len(rows)
    failed = sum(r['failure'] == '1' for r in rows)
    accepted = [r for r in rows if r['accepted'] == '1']
    wrong = sum(r['failure'] == '1' for r in accepted)
    return 100 * failed / n, 100 * len(accepted) / n, 100 * wrong / max(1, len(accepted))


sharp, smoothed = load(sys.argv[1]), load(sys.argv[2])
ratios = [float(x) for x in sys.argv[3:]] or [0.94]
rows = collections.OrderedDict()
for k in sharp:
    rows.setdefault((k[1], k[2]), []).append(k)
chains = [('sharp', lambda a, b: a), ('smoothed', lambda a, b: b)]
chains += [(f'choice {q}', lambda a, b, q=q: b if match(b) > q * match(a) else a) for q in ratios]
print('row'.ljust(26) + ''.join(name.ljust(19) for name, _ in chains))
worst = {name: [0.0, 100.0, 0.0] for name, _ in chains}
for (family, level), keys in rows.items():
    line = f'{family:18} {level:7}'
    for name, choose in chains:
        f, a, w = rates([choose(sharp[k], smoothed[k]) for k in keys])
        line += f'{f:5.1f} /{a:4.0f} /{w:5.1f}  '
        lo, hi = RANGES.get(family, (1, 0))
        if lo <= float(level) <= hi:
            x = worst[name]
            x[0], x[1], x[2] = max(x[0], f), min(x[1], a), max(x[2], w)
    print(line)
print('worst in range'.ljust(26) + ''.join(f'{f:5.1f} /{a:4.0f} /{w:5.1f}  ' for f, a, w in worst.values()))
