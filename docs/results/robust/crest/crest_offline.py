# The crest rule applied to a run of the exploratory build that dumps each
# estimate's response (dump-responses.diff, on 331aa36: --errors gains the
# columns size, view_size, scale, best_view and response; ACCH_LAYOUT_WEIGHT
# unset keeps the built weight). Writes the run's rows with the response
# dropped, phi_plateau_deg added as acch_confidence::phi_plateau_deg
# computes it (ratio 0.98, the walk about the best view in its theta
# slice) and accepted = accepted and phi_plateau_deg < 40: what the
# confidence stage with the crest rule decides (checked equal, image for
# image, against the built rule on the development seeds). The views are
# the paper's grid, 45-90 deg by 10 deg of phi, in database order.
# Usage: crest_offline.py DUMP.csv OUT.csv.gz
import csv, gzip, sys

csv.field_size_limit(10 ** 9)
THETAS = [45, 50, 60, 70, 80, 90]
VIEWS = [(t, p) for t in THETAS for p in range(0, 360, 10)]
RATIO, LIMIT = 0.98, 40.0


def plateau(response, best):
    """Span in phi of the run about `best`, in its slice, within RATIO."""
    theta, phi0 = VIEWS[best]
    floor = RATIO * response[best]
    same = [j for j, v in enumerate(VIEWS) if v[0] == theta and j != best]
    span = 0.0
    for turn in (1, -1):
        edge = 0.0
        while True:
            ahead = [((turn * (VIEWS[j][1] - phi0)) % 360, j) for j in same]
            ahead = [a for a in ahead if a[0] > edge]
            if not ahead:
                return 360.0
            offset, j = min(ahead)
            if response[j] < floor:
                break
            edge = offset
        span += edge
    return min(span, 360.0)


src, out = sys.argv[1], sys.argv[2]
rows = csv.DictReader((gzip.open if src.endswith('gz') else open)(src, 'rt'))
drop = {'size', 'view_size', 'scale', 'best_view', 'response'}
fields = [f for f in rows.fieldnames if f not in drop] + ['phi_plateau_deg']
with gzip.open(out, 'wt', newline='') as f:
    w = csv.DictWriter(f, fields, extrasaction='ignore', lineterminator='\n')
    w.writeheader()
    for r in rows:
        r['phi_plateau_deg'] = ''
        if r['best_view'] and r['confidence']:
            response = [float(x) for x in r['response'].split()]
            assert len(response) == len(VIEWS), 'the paper grid'
            p = plateau(response, int(r['best_view']))
            r['phi_plateau_deg'] = f'{p:.3f}'
            if p >= LIMIT:
                r['accepted'] = '0'
        w.writerow(r)
