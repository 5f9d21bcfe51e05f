"""Worst level of each family over R1's ranges with the rival rule at
several bars, from one `acch eval --protocol robust --errors` CSV.

    python3 rival_bars.py ERRORS.csv[.gz] none 0.995 0.99 0.985 0.98

An image counts as accepted at bar B when its confidence reaches the
network's threshold (0.8) and its rival is at most B ("none": the network
alone). Failures (wrong or not found, before the confidence) do not
depend on the bar. Each cell: failures % / accepted % / failures among
the accepted % (objects accepting a wrong pose), the worst of each over
the family's levels in range. Light-search rows only.
"""
import collections
import csv
import gzip
import sys

RANGES = {
    'clean': (0, 0), 'exposure': (0.6, 1.5), 'brightness': (0.6, 1.5),
    'colour_temperature': (3500, 6500), 'noise': (0, 6), 'blur': (0, 2),
    'jpeg': (60, 100), 'occlusion': (0, 0.3), 'distance': (0.7, 1.5),
}
THRESHOLD = 0.8


def accepted(row, bar):
    if not row['confidence']:
        return False
    if float(row['confidence']) < THRESHOLD:
        return False
    return bar == 'none' or (row['rival'] != '' and float(row['rival']) <= float(bar))


def cell(rows, bar):
    n = len(rows)
    failed = sum(r['failure'] == '1' for r in rows)
    acc = [r for r in rows if accepted(r, bar)]
    wrong = [r for r in acc if r['failure'] == '1']
    return (100 * failed / n, 100 * len(acc) / n,
            100 * len(wrong) / max(len(acc), 1), len({r['object'] for r in wrong}))


def main():
    path, bars = sys.argv[1], sys.argv[2:]
    opener = gzip.open if path.endswith('.gz') else open
    with opener(path, 'rt') as f:
        rows = [r for r in csv.DictReader(f) if r['light_search'] == '1']
    by_level = collections.defaultdict(list)
    for r in rows:
        by_level[(r['family'], float(r['level']))].append(r)
    print('| bar | ' + ' | '.join(RANGES) + ' |')
    print('| --- ' * (len(RANGES) + 1) + '|')
    for bar in bars:
        out = []
        for family, (lo, hi) in RANGES.items():
            cells = [cell(rs, bar) for (f, level), rs in by_level.items()
                     if f == family and lo <= level <= hi]
            worst = (max(c[0] for c in cells), min(c[1] for c in cells),
                     max(c[2] for c in cells), max(c[3] for c in cells))
            out.append('%.1f / %.0f / %.1f (%d)' % worst)
        print('| %s | ' % bar + ' | '.join(out) + ' |')


if __name__ == '__main__':
    main()
