# An occluded object's visible share, and a rival bar for it alone:
# measured with the exploratory patch visible-share.diff (against 112ecaa;
# not kept), whose --errors files have three more columns: the object's
# size over its mask (sqrt of its pixels), the chosen view's training size
# and the scale (given by the distance). Visible share = (size / (view
# size x scale))^2. For each file: per level of the families it ran,
# accepted % / wrong among the accepted %, as built and with "a visible
# share under T takes the rival to at most R". Usage, from the root:
#   python3 docs/results/robust/look-alike/visible-share/visible_share.py
import csv, gzip, collections, statistics

D = 'docs/results/robust/look-alike/visible-share/'
RANGES = {'occlusion': 0.3, 'occluding_object': 0.3}


def share(r):
    s, v, k = float(r['size']), float(r['view_size']), float(r['scale'])
    return (s / (v * k)) ** 2 if s > 0 and v > 0 and k > 0 else 1.0


for name in ('vis-s3.csv.gz', 'vis-s7.csv.gz'):
    rows = [r for r in csv.DictReader(gzip.open(D + name, 'rt'))
            if r['family'] == 'clean' or
            (r['family'] in RANGES and float(r['level']) <= RANGES[r['family']] + 1e-9)]
    print(name, len(rows), 'images')
    acc = [r for r in rows if r['accepted'] == '1']
    for fam in ('clean', 'occlusion', 'occluding_object'):
        right = [share(r) for r in acc if r['family'] == fam and r['failure'] == '0']
        print(f'  visible share of the accepted right, {fam}: deciles',
              [round(x, 2) for x in statistics.quantiles(right, n=10)])
    occl = [r for r in acc if r['family'] != 'clean']
    for k in ('rival',):
        for label, sel in (('right', '0'), ('wrong', '1')):
            v = [float(r[k]) for r in occl if r['failure'] == sel]
            if len(v) > 1:
                print(f'  occluded, accepted {label} ({len(v)}): {k} deciles',
                      [round(x, 3) for x in statistics.quantiles(v, n=10)])

    def report(label, accept):
        lv = collections.defaultdict(lambda: [0, 0, 0])
        for r in rows:
            a = accept(r)
            k = lv[(r['family'], r['level'])]
            k[0] += 1; k[1] += a; k[2] += a and r['failure'] == '1'
        print(f'  {label:26s}', ' '.join(
            f'{f}{l} {100 * a / n:.0f}/{100 * w / max(a, 1):.1f}'
            for (f, l), (n, a, w) in sorted(lv.items())))

    accepted = lambda r: r['accepted'] == '1'
    report('as built', accepted)
    for t, bar in ((0.85, 0.95), (0.85, 0.97), (0.8, 0.95)):
        report(f'share < {t}: rival <= {bar}',
               lambda r: accepted(r) and not (share(r) < t and float(r['rival']) > bar))
