"""Detection margins (score over threshold) of right and wrong detections.

python3 margins.py multi MULTI_ERRORS.csv[.gz] ...: per file and mode (every
object known, or the object's chain alone), the detections whose window lies
on no part of the object (an object not in the scene found on another, or on
the table), how many of them were accepted, their margins, and the margins of
the right detections.
python3 margins.py robust ROBUST_ERRORS.csv[.gz]: per family, the margins of
the right and of the wrong accepted estimates, and how many fall below 1.3,
1.4 and 1.5.
"""
import csv
import gzip
import sys
from collections import defaultdict


def read(path):
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        return list(csv.DictReader(f))


def below(values, limit):
    return sum(v < limit for v in values)


if sys.argv[1] == "multi":
    for path in sys.argv[2:]:
        rows = read(path)
        for mode in ("multi", "alone"):
            mine = [r for r in rows if r["mode"] == mode and r["detected"] == "1"]
            false = [r for r in mine if r["right"] == "0"]
            right = sorted(float(r["score_margin"]) for r in mine if r["right"] == "1")
            margins = [float(r["score_margin"]) for r in false]
            span = f"{min(margins):.2f}-{max(margins):.2f}" if margins else "-"
            print(f"{path} {mode}: wrong detections {len(false)} "
                  f"(in the scene: {sum(r['in_scene'] == '1' for r in false)}), "
                  f"accepted {sum(r['accepted'] == '1' for r in false)}, margins {span}; "
                  f"right {len(right)}, lowest {right[0]:.2f}, below 1.3/1.4/1.5: "
                  f"{below(right, 1.3)}/{below(right, 1.4)}/{below(right, 1.5)}")
else:
    by_family = defaultdict(list)
    for r in read(sys.argv[2]):
        if r["score_margin"] and r["accepted"] == "1":
            by_family[r["family"]].append(r)
    for family, rows in by_family.items():
        right = [float(r["score_margin"]) for r in rows if r["failure"] == "0"]
        wrong = [float(r["score_margin"]) for r in rows if r["failure"] == "1"]
        print(f"{family:18s} right accepted {len(right)}, lowest {min(right):.2f}, below 1.3/1.4/1.5: "
              f"{below(right, 1.3)}/{below(right, 1.4)}/{below(right, 1.5)} | wrong accepted {len(wrong)}, "
              f"below 1.3/1.5: {below(wrong, 1.3)}/{below(wrong, 1.5)}")
