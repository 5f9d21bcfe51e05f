"""Failures of views from above against the rest, from robust --errors CSVs.

python3 band.py A.csv[.gz] ...: per family, the worst level over R1's ranges
of the failure rate (wrong or not found) among the poses with theta below 80
degrees and among those at 80 or above (views from above: a box's lid, a
can's or bottle's cap), and the share of the poses at 80 or above.
"""
import sys

from worst import RANGES, failure_rate, levels

by_level = levels(sys.argv[1:])
for family in RANGES:
    mine = [v for (f, _), v in by_level.items() if f == family]
    if not mine:
        continue
    side = max(failure_rate([r for r in v if float(r["theta_deg"]) < 80]) for v in mine)
    above = max(failure_rate([r for r in v if float(r["theta_deg"]) >= 80]) for v in mine)
    share = 100 * sum(float(r["theta_deg"]) >= 80 for r in mine[0]) / len(mine[0])
    print(f"{family:18s} below 80: {side:5.1f} %   80 and above: {above:5.1f} %   ({share:.0f} % of poses)")
