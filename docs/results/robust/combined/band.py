"""Failures of views from above against the rest, from robust --errors CSVs.

python3 band.py A.csv[.gz] ...: per family, the worst level over R1's ranges
of the failure rate (wrong or not found) among the poses with theta below 80
degrees and among those at 80 or above (views from above: a box's lid, a
can's or bottle's cap), and the share of the poses at 80 or above.
"""
import csv
import gzip
import sys
from collections import defaultdict

from worst import RANGES

rows = {}
for path in sys.argv[1:]:
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        for r in csv.DictReader(f):
            key = (r["object"], r["family"], r["level"], r["background"], r["image"])
            rows.setdefault(key, r)
levels = defaultdict(list)
for r in rows.values():
    lo, hi = RANGES.get(r["family"], (None, None))
    if lo is not None and lo <= float(r["level"]) <= hi:
        levels[(r["family"], r["level"])].append(r)


def rate(rs):
    return 100 * sum(r["failure"] == "1" for r in rs) / max(1, len(rs))


for family in RANGES:
    mine = [v for (f, _), v in levels.items() if f == family]
    if not mine:
        continue
    side = max(rate([r for r in v if float(r["theta_deg"]) < 80]) for v in mine)
    above = max(rate([r for r in v if float(r["theta_deg"]) >= 80]) for v in mine)
    share = 100 * sum(float(r["theta_deg"]) >= 80 for r in mine[0]) / len(mine[0])
    print(f"{family:18s} below 80: {side:5.1f} %   80 and above: {above:5.1f} %   ({share:.0f} % of poses)")
