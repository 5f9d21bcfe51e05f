"""Choosing the database by the frame's measured quality, offline: the
default's estimate on a clean-looking frame, the combined recipe's
(--smoothing binomial --confidence-imaging) on a noisy, blocky or blurred
one, from the two recipes' robust-protocol --errors CSVs of the same images
(the default's columns noise_sigma, blockiness, sharpness:
acch_core::QualityMeter; the same images' in both).

python3 select.py DEFAULT.csv[.gz] COMBINED.csv[.gz] [NOISE BLOCK SHARPNESS]
  with thresholds: per family, the worst level over R1's ranges (failures %
  / accepted % / accepted wrong %) when the combined recipe's estimate is
  taken for frames with noise_sigma > NOISE or blockiness > BLOCK or
  sharpness < SHARPNESS, and which share of each family's frames took it;
  without: the quality measures per family and level (median, 10th and
  90th percentile), then a sweep of thresholds, each scored by the
  families meeting all three bounds and the worst accepted wrong.
The bars chosen on the development seed: 2.5 1.5 0 (no sharpness bar: one
that takes blur also takes frames with nothing sharp in view, see
docs/accuracy.md). Output for both seeds: select.txt (the default's CSVs
here, the combined recipe's in ../faint).
A simulation over stored runs, not a pipeline: nothing here is built.
"""
import itertools
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "combined"))
from worst import RANGES, levels  # noqa: E402

KEY = lambda r: (r["object"], r["background"], r["image"])  # noqa: E731


def smoothed(r, t):
    return (float(r["noise_sigma"]) > t[0] or float(r["blockiness"]) > t[1]
            or float(r["sharpness"]) < t[2])


def table(defaults, combined, t):
    """Per family: (worst failures, least accepted, worst accepted wrong,
    share of frames sent to the combined recipe), all %."""
    out = {}
    for family in RANGES:
        worst, sent, total = [], 0, 0
        for (f, level), rows in defaults.items():
            other = {KEY(r): r for r in combined.get((f, level), [])}
            if f != family or not other:
                continue
            chosen = []
            for r in rows:
                o = other[KEY(r)]
                use = smoothed(r, t)
                sent += use
                chosen.append(o if use else r)
            total += len(rows)
            accepted = [r for r in chosen if r["accepted"] == "1"]
            worst.append((100 * sum(r["failure"] == "1" for r in chosen) / len(chosen),
                          100 * len(accepted) / len(chosen),
                          100 * sum(r["failure"] == "1" for r in accepted) / max(1, len(accepted))))
        if worst:
            out[family] = (max(w[0] for w in worst), min(w[1] for w in worst),
                           max(w[2] for w in worst), 100 * sent / max(1, total))
    return out


def meets(w):
    return w[0] <= 10 and w[1] >= 70 and w[2] <= 2


def pct(values, q):
    v = sorted(values)
    return v[min(len(v) - 1, int(q * len(v)))]


defaults = levels([sys.argv[1]])
combined = levels(sys.argv[2].split(","))
if len(sys.argv) > 3:
    t = tuple(float(x) for x in sys.argv[3:6])
    print(f"thresholds: noise > {t[0]}, blockiness > {t[1]}, sharpness < {t[2]}")
    n = 0
    for family, w in table(defaults, combined, t).items():
        n += meets(w)
        print(f"{family:18s} {w[0]:5.1f} / {w[1]:3.0f} / {w[2]:4.1f}  "
              f"{'meets' if meets(w) else '-':5s}  combined on {w[3]:5.1f} % of frames")
    print(f"families meeting all three bounds: {n}")
else:
    print("family level: noise_sigma / blockiness / sharpness, median [10th, 90th percentile]")
    for (f, level), rows in sorted(defaults.items()):
        cols = []
        for m in ("noise_sigma", "blockiness", "sharpness"):
            v = [float(r[m]) for r in rows]
            cols.append(f"{pct(v, .5):6.3f} [{pct(v, .1):6.3f}, {pct(v, .9):6.3f}]")
        print(f"{f:18s} {level:>5s}: " + " | ".join(cols))
    print("\nsweep: noise, blockiness, sharpness -> families meeting, worst accepted wrong %")
    scored = []
    for t in itertools.product((1.5, 2.0, 2.5, 3.0, 99),
                               (1.2, 1.3, 1.4, 1.5, 1.6, 1.8, 99),
                               (0.0, 0.26, 0.28, 0.3)):
        tab = table(defaults, combined, t)
        scored.append((sum(meets(w) for w in tab.values()),
                       -max(w[2] for w in tab.values()),
                       -max(w[0] for w in tab.values()), t))
    scored.sort(reverse=True)
    for s in scored[:25]:
        print(f"{s[3]}: {s[0]} families, worst accepted wrong {-s[1]:.1f} %, worst failures {-s[2]:.1f} %")
