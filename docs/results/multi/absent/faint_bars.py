"""Sweep the bars of the faint-and-weak rule on development data.

python3 faint_bars.py ROBUST_ERRORS.csv[.gz] MULTI_ERRORS.csv[.gz] ...: for
each pair of bars (detection margin, match value), an accepted estimate
whose margin and match value are both below them would be rejected; per
pair, how many accepted detections of an object not in the scene the
multi CSVs keep, how many right accepted ones they lose, and on the robust
CSV how many wrong accepted estimates are removed and right ones lost.
The CSVs must come from runs without the rule (before commit 398eb10). The
bars chosen (1.3, 0.75): the first to keep no absent object and lose no
right detection among several objects, losing the fewest right single
objects; from development seeds only (robust 3; multi 3, 5, 11, and 3
with the combined databases).
"""
import csv
import gzip
import sys


def read(path):
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        return list(csv.DictReader(f))


robust = [r for r in read(sys.argv[1]) if r["accepted"] == "1" and r["score_margin"]]
multi = [r for path in sys.argv[2:] for r in read(path)
         if r["detected"] == "1" and r["accepted"] == "1"]
for margin_bar in (1.1, 1.2, 1.25, 1.3, 1.35, 1.4, 1.5):
    for value_bar in (0.6, 0.65, 0.7, 0.75, 0.8):
        def faint(r):
            return float(r["score_margin"]) < margin_bar and float(r["match_value"]) < value_bar
        absent_kept = sum(r["right"] == "0" and not faint(r) for r in multi)
        right_lost = sum(r["right"] == "1" and faint(r) for r in multi)
        wrong_removed = sum(r["failure"] == "1" and faint(r) for r in robust)
        single_lost = sum(r["failure"] == "0" and faint(r) for r in robust)
        print(f"margin < {margin_bar:.2f}, match < {value_bar:.2f}: several objects: absent accepted "
              f"{absent_kept}, right lost {right_lost} | single: wrong removed {wrong_removed} of "
              f"{sum(r['failure'] == '1' for r in robust)}, right lost {single_lost} of "
              f"{sum(r['failure'] == '0' for r in robust)}")
