"""How far off the accepted wrong estimates of robust-protocol --errors CSVs are.

python3 near.py A.csv[.gz] ...: per file set, the accepted estimates beyond
the failure rule (|dtheta| > 10 or |dphi| > 20 degrees), how many are near
misses (|dtheta| <= 15 and |dphi| <= 30: a neighbouring view or two) and how
many are turned by 90 degrees or more in phi. R1's ranges only (as worst.py).
"""
import sys

from worst import levels

images = [r for rows in levels(sys.argv[1:]).values() for r in rows]
wrong = [r for r in images if r["failure"] == "1" and r["accepted"] == "1"]
near = [r for r in wrong if float(r["abs_dtheta_deg"]) <= 15 and float(r["abs_dphi_deg"]) <= 30]
turned = [r for r in wrong if float(r["abs_dphi_deg"]) >= 90]
print(f"images {len(images)}, accepted wrong {len(wrong)}, near misses {len(near)}, turned >= 90 deg {len(turned)}")
