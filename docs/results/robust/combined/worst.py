"""Worst level of each family over R1's ranges, from robust-protocol JSON files.

python3 worst.py A.json [B.json ...]: failures % / accepted % / failures among
the accepted % (objects accepting a wrong pose), each the worst over the levels
of the issue's ranges (max, min, max), and whether all three bounds hold
(failures <= 10 %, accepted >= 70 %, accepted wrong <= 2 %).
"""
import csv
import gzip
import json
import sys
from collections import defaultdict

RANGES = {
    "clean": (0, 0),
    "exposure": (0.6, 1.5),
    "brightness": (0.6, 1.5),
    "colour_temperature": (3500, 6500),
    "noise": (0, 6),
    "blur": (0, 2),
    "jpeg": (60, 100),
    "occlusion": (0, 0.3),
    "occluding_object": (0, 0.3),
    "distance": (0.7, 1.5),
}


def levels(paths):
    """Rows of robust --errors CSVs (plain or gzipped) within R1's ranges, each
    image once, by (family, level)."""
    rows = {}
    for path in paths:
        opener = gzip.open if path.endswith(".gz") else open
        with opener(path, "rt") as f:
            for r in csv.DictReader(f):
                rows.setdefault((r["object"], r["family"], r["level"], r["background"], r["image"]), r)
    out = defaultdict(list)
    for r in rows.values():
        lo, hi = RANGES.get(r["family"], (None, None))
        if lo is not None and lo <= float(r["level"]) <= hi:
            out[(r["family"], r["level"])].append(r)
    return out


def failure_rate(rows):
    """Failures (wrong or not found) among `rows`, %."""
    return 100 * sum(r["failure"] == "1" for r in rows) / max(1, len(rows))


def report(rows):
    for family, (lo, hi) in RANGES.items():
        inside = [r for r in rows if r["family"] == family and lo <= r["level"] <= hi]
        if not inside:
            continue
        fail = max(r["failure_rate"] for r in inside)
        acc = min(r["accepted_rate"] for r in inside)
        wrong = max(r["acc_failure_rate"] for r in inside)
        objects = max(r["objects_accepting_wrong"] for r in inside)
        ok = fail <= 0.10 and acc >= 0.70 and wrong <= 0.02
        verdict = "meets" if ok else "-"
        print(f"{family:18s} {100*fail:5.1f} / {100*acc:3.0f} / {100*wrong:4.1f} ({objects})  {verdict}")


if __name__ == "__main__":
    rows = []
    for path in sys.argv[1:]:
        with open(path) as f:
            rows += json.load(f)["rows"]
    report(rows)
