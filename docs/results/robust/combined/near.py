"""How far off the accepted wrong estimates of robust-protocol --errors CSVs are.

python3 near.py A.csv[.gz] ...: per file set, the accepted estimates beyond
the failure rule (|dtheta| > 10 or |dphi| > 20 degrees), how many are near
misses (|dtheta| <= 15 and |dphi| <= 30: a neighbouring view or two) and how
many are turned by 90 degrees or more in phi. R1's ranges only (as worst.py).
"""
import csv
import gzip
import sys

from worst import RANGES  # noqa: E402  (same directory)

rows = []
for path in sys.argv[1:]:
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        rows += list(csv.DictReader(f))
seen = set()
wrong = []
for r in rows:
    lo, hi = RANGES.get(r["family"], (None, None))
    if lo is None or not lo <= float(r["level"]) <= hi:
        continue
    key = (r["object"], r["family"], r["level"], r["background"], r["image"])
    if key in seen:
        continue
    seen.add(key)
    if r["failure"] == "1" and r["accepted"] == "1":
        wrong.append(r)
near = [r for r in wrong if float(r["abs_dtheta_deg"]) <= 15 and float(r["abs_dphi_deg"]) <= 30]
turned = [r for r in wrong if float(r["abs_dphi_deg"]) >= 90]
print(f"images {len(seen)}, accepted wrong {len(wrong)}, near misses {len(near)}, turned >= 90 deg {len(turned)}")
