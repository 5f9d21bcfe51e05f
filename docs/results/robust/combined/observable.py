"""Failures without the poses no image tells apart in phi.

python3 observable.py AMBIGUITY.csv LIMIT ERRORS.csv[.gz] ...: AMBIGUITY.csv
is the output of `cargo run --release -p acch-eval --example view_ambiguity`
on the same run's clean rows; a pose counts as unobservable in phi when a
turn of more than 20 degrees changes its render by less than LIMIT grey
levels on average over the object's pixels. Per family, the worst level
over R1's ranges of the failure rate (wrong or not found) over every pose,
and over the observable poses only.
"""
import csv
import sys

from worst import RANGES, failure_rate, levels

with open(sys.argv[1]) as f:
    far = {(r["object"], r["background"], r["image"]): float(r["far_difference"]) for r in csv.DictReader(f)}
limit = float(sys.argv[2])
hidden = {k for k, d in far.items() if d < limit}
by_level = levels(sys.argv[3:])
print(f"{len(hidden)} of {len(far)} poses unobservable in phi (a far turn changes them by < {limit} grey levels)")
for family in RANGES:
    mine = [v for (f, _), v in by_level.items() if f == family]
    if not mine:
        continue
    every = max(failure_rate(v) for v in mine)
    seen = max(failure_rate([r for r in v if (r["object"], r["background"], r["image"]) not in hidden]) for v in mine)
    print(f"{family:18s} every pose {every:5.1f} %   observable {seen:5.1f} %")
