"""What the faint-and-weak rule changed, from robust-protocol --errors CSVs
made with it.

python3 rule.py A.csv[.gz] ...: per family, over the levels of R1's ranges,
the worst level's failures % / accepted % / accepted wrong % with the rule
and without it, and how many wrong and right estimates the rule alone
rejected (rated at or above 0.8 with no rival above 0.99, but detected by
less than 1.3x with a match value under 0.75; the CSV's three decimals
decide at the bars).
"""
import sys
import os

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "combined"))
from worst import RANGES, levels  # noqa: E402

MIN_CLEAR_DETECTION_MARGIN = 1.3
MIN_CLEAR_MATCH_VALUE = 0.75


def faint_only(r):
    """Rejected by the faint rule alone."""
    return (r["accepted"] == "0" and r["confidence"] != "" and float(r["confidence"]) >= 0.8
            and float(r["rival"]) <= 0.99 and r["score_margin"] != ""
            and float(r["score_margin"]) < MIN_CLEAR_DETECTION_MARGIN
            and float(r["match_value"]) < MIN_CLEAR_MATCH_VALUE)


def figures(rows, accepted):
    acc = [r for r in rows if accepted(r)]
    return (100 * sum(r["failure"] == "1" for r in rows) / len(rows),
            100 * len(acc) / len(rows),
            100 * sum(r["failure"] == "1" for r in acc) / max(1, len(acc)))


def worst(by_level, family, accepted):
    rows = [figures(v, accepted) for (f, _), v in by_level.items() if f == family]
    return max(r[0] for r in rows), min(r[1] for r in rows), max(r[2] for r in rows)


by_level = levels(sys.argv[1:])
print(f"{'family':18s} {'with the rule':>20s} {'without':>20s}   rejected by it: wrong / right")
for family in RANGES:
    if not any(f == family for f, _ in by_level):
        continue
    with_rule = worst(by_level, family, lambda r: r["accepted"] == "1")
    without = worst(by_level, family, lambda r: r["accepted"] == "1" or faint_only(r))
    rejected = [r for (f, _), v in by_level.items() if f == family for r in v if faint_only(r)]
    wrong = sum(r["failure"] == "1" for r in rejected)
    print(f"{family:18s} {'%5.1f / %3.0f / %4.1f' % with_rule:>20s} {'%5.1f / %3.0f / %4.1f' % without:>20s}"
          f"   {wrong} / {len(rejected) - wrong}")
