"""Two databases per object, offline: what accepting on the default's and
the combined recipe's (--smoothing binomial --confidence-imaging) estimates
of the same images would give, from their robust-protocol --errors CSVs.

python3 two_databases.py DEFAULT.csv[.gz] COMBINED.csv[.gz][,MORE...]: per
family, the worst level over R1's ranges (failures % / accepted % / accepted
wrong %) for two ways of judging both estimates:
  agree:    the default's estimate when it is accepted and the combined
            recipe's lies within the failure tolerances of it; else the
            combined recipe's when it is accepted; else rejected (the
            combined recipe's estimate reported, or the default's when it
            found nothing).
  combined first: the combined recipe's when accepted; else the default's
            when accepted; else rejected, reported as above.
A simulation over stored runs, not a pipeline: nothing here is built.
"""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "combined"))
from worst import RANGES, levels  # noqa: E402


def agree(a, b):
    """Two estimates within the failure tolerances of each other."""
    if not a["est_theta_deg"] or not b["est_theta_deg"]:
        return False
    dt = abs(float(a["est_theta_deg"]) - float(b["est_theta_deg"]))
    dp = abs(float(a["est_phi_deg"]) - float(b["est_phi_deg"])) % 360
    return dt <= 10 and min(dp, 360 - dp) <= 20


def judge(default, combined, way):
    """(the estimate reported, whether accepted)."""
    d_ok, c_ok = default["accepted"] == "1", combined["accepted"] == "1"
    reported = combined if combined["est_theta_deg"] else default
    if way == "agree":
        if d_ok and agree(default, combined):
            return default, True
        if c_ok:
            return combined, True
    else:
        if c_ok:
            return combined, True
        if d_ok:
            return default, True
    return reported, False


defaults = levels([sys.argv[1]])
combined = levels(sys.argv[2].split(","))
key = lambda r: (r["object"], r["background"], r["image"])  # noqa: E731
for way in ("agree", "combined first"):
    meets = 0
    print(f"== {way}")
    for family in RANGES:
        worst = []
        for (f, level), rows in defaults.items():
            other = {key(r): r for r in combined.get((f, level), [])}
            if f != family or not other:
                continue
            judged = [judge(r, other[key(r)], way) for r in rows]
            accepted = [r for r, ok in judged if ok]
            worst.append((100 * sum(r["failure"] == "1" for r, _ in judged) / len(rows),
                          100 * len(accepted) / len(rows),
                          100 * sum(r["failure"] == "1" for r in accepted) / max(1, len(accepted))))
        if worst:
            w = (max(x[0] for x in worst), min(x[1] for x in worst), max(x[2] for x in worst))
            ok = w[0] <= 10 and w[1] >= 70 and w[2] <= 2
            meets += ok
            print(f"{family:18s} {w[0]:5.1f} / {w[1]:3.0f} / {w[2]:4.1f}  {'meets' if ok else '-'}")
    print(f"families meeting all three bounds: {meets}")
