"""R1's bounds on each draw of the robust protocol and on the draws pooled.

python3 pooled.py [--json OUT.json] A.csv[.gz] [B.csv ...]: each file is one draw's --errors
CSV (its own seed: the same object, level, background and image number
are another image in another draw). For every level of R1's ranges: per
draw, the failures (wrong or not found), the accepted and the wrong among
the accepted; then the draws pooled, with 95 % Wilson intervals. A level
meets R1 when failures <= 10 %, accepted >= 70 % and wrong among the
accepted <= 2 %. --json also writes the pooled rates as a robust-protocol
--json's rows (for eval/examples/robust_bounds_plot.rs).
"""
import csv
import gzip
import json
import math
import os
import sys
from collections import defaultdict

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "combined"))
from worst import RANGES  # noqa: E402


def wilson(k, n, z=1.96):
    """95 % Wilson interval of k successes in n, %."""
    if n == 0:
        return (float("nan"), float("nan"))
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return (100 * (c - h), 100 * (c + h))


def counts(path):
    """(family, level) -> [images, failures, accepted, accepted wrong, not found]."""
    out = defaultdict(lambda: [0, 0, 0, 0, 0])
    with (gzip.open if path.endswith(".gz") else open)(path, "rt") as f:
        for r in csv.DictReader(f):
            lo, hi = RANGES.get(r["family"], (None, None))
            if lo is None or not lo <= float(r["level"]) <= hi:
                continue
            c = out[(r["family"], r["level"])]
            fail, acc = r["failure"] == "1", r["accepted"] == "1"
            c[0] += 1
            c[1] += fail
            c[2] += acc
            c[3] += fail and acc
            c[4] += r["est_phi_deg"] == ""
    return out


def meets(c):
    n, f, a, aw = c[:4]
    return f <= 0.10 * n and a >= 0.70 * n and aw <= 0.02 * a


def main(paths, json_out=None):
    draws = [counts(p) for p in paths]
    keys = sorted(set().union(*draws), key=lambda k: (list(RANGES).index(k[0]), float(k[1])))
    names = [p.split("/")[-1].split(".")[0] for p in paths]
    print("level: per draw failures / accepted / wrong among accepted (counts); pooled % [95 % interval]")
    over = defaultdict(int)
    rows = []
    # Worst pooled failures, accepted, wrong among accepted, with the
    # interval end towards the bound.
    worst = {"failures": (0, 0, ""), "accepted": (100, 100, ""), "wrong": (0, 0, "")}
    for k in keys:
        per = []
        pooled = [0, 0, 0, 0, 0]
        for name, d in zip(names, draws):
            c = d.get(k)
            if c is None:
                continue
            pooled = [x + y for x, y in zip(pooled, c)]
            mark = "" if meets(c) else " OVER"
            over[name] += not meets(c)
            per.append(f"{name} {c[1]}/{c[0]} {c[2]}/{c[0]} {c[3]}/{c[2]}{mark}")
        n, f, a, aw, lost = pooled
        rows.append(
            {
                "family": k[0],
                "level": float(k[1]),
                "light_search": True,
                "n": n,
                "not_found_rate": lost / n,
                "failure_rate": f / n,
                "accepted_rate": a / n,
                "acc_failure_rate": aw / max(a, 1),
            }
        )
        fi, ai, wi = wilson(f, n), wilson(a, n), wilson(aw, a)
        verdict = "meets" if meets(pooled) else "OVER"
        print(f"{k[0]} {k[1]}: " + "; ".join(per))
        name = f"{k[0]} {k[1]}"
        if fi[1] > worst["failures"][1]:
            worst["failures"] = (100 * f / n, fi[1], name)
        if ai[0] < worst["accepted"][1]:
            worst["accepted"] = (100 * a / n, ai[0], name)
        if wi[1] > worst["wrong"][1]:
            worst["wrong"] = (100 * aw / max(a, 1), wi[1], name)
        print(
            f"    pooled n {n}: failures {100*f/n:.1f} % [{fi[0]:.1f}, {fi[1]:.1f}], "
            f"accepted {100*a/n:.1f} % [{ai[0]:.1f}, {ai[1]:.1f}], "
            f"wrong among accepted {100*aw/max(a,1):.2f} % [{wi[0]:.2f}, {wi[1]:.2f}]  {verdict}"
        )
    for what, (value, end, name) in worst.items():
        side = "lower" if what == "accepted" else "upper"
        print(f"pooled, worst interval end of {what}: {name}, {value:.2f} % ({side} end {end:.2f} %)")
    print("levels over a bound, per draw: " + ", ".join(f"{n} {over[n]}" for n in names))
    if json_out:
        with open(json_out, "w") as f:
            json.dump({"protocol": "robust", "pooled": names, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    args = sys.argv[1:]
    out = None
    if args[:1] == ["--json"]:
        out, args = args[1], args[2:]
    main(args, out)
