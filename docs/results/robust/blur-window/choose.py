"""Choosing the smoothed databases for a blurred object, offline: the bar on
the sharpness over the object's window (acch_core::BLURRED), and whether a
frame the sharp set found nothing in goes through the smoothed set too.

python3 choose.py AUTO.csv[.gz] DEFAULT.csv[.gz] COMBINED.csv[.gz] BARS
  AUTO: a `--smoothing auto` run's --errors file (its object_sharpness
  column: measured over the window the sharp set found, before any choice,
  so the same whatever the bar the run had); DEFAULT and COMBINED: the
  default and the combined recipe's (--smoothing binomial
  --confidence-imaging) runs of the same images. For each bar (comma
  separated) with and without the fallback: the combined recipe's estimate
  for a frame that is noisy or blocky (noise > 2.5, blockiness > 1.5, as
  built), whose object measured below the bar, or (fallback) whose object
  the default did not find; the default's otherwise; and, tried and not
  kept, the fallback plus a second opinion: the combined recipe's estimate
  too when the default rejected and it accepts. Prints per family the
  worst level over R1's ranges, failures % / accepted % / accepted wrong %,
  * when all three bounds hold, and the accepted wrong over every image.
The bar and the fallback were chosen on the development seed (3) only:
0.30 with the fallback (choose.txt). A simulation over stored runs; the
real chain's runs (auto-s*.json) give the same worst rows.
"""
import csv
import gzip
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "combined"))
from worst import RANGES, levels  # noqa: E402

KEY = lambda r: (r["object"], r["background"], r["image"], r["family"], r["level"])  # noqa: E731


def opened(path):
    return gzip.open(path, "rt") if path.endswith(".gz") else open(path)


def chosen(defaults, combined, sharpness, bar, fallback, second_opinion=False):
    """Per (family, level): failures %, accepted %, accepted wrong %,
    accepted wrong images."""
    out = {}
    for (family, level), rows in defaults.items():
        other = {KEY(r): r for r in combined[(family, level)]}
        picked = []
        for r in rows:
            noisy = float(r["noise_sigma"]) > 2.5 or float(r["blockiness"]) > 1.5
            s = sharpness[KEY(r)]
            lost = r["est_theta_deg"] == ""
            use = noisy or 0 < s < bar or (fallback and lost)
            o = other[KEY(r)]
            use |= second_opinion and r["accepted"] == "0" and o["accepted"] == "1"
            picked.append(o if use else r)
        n = len(picked)
        accepted = [r for r in picked if r["accepted"] == "1"]
        out[(family, level)] = (
            100 * sum(r["failure"] == "1" for r in picked) / n,
            100 * len(accepted) / n,
            100 * sum(r["failure"] == "1" for r in accepted) / max(1, len(accepted)),
            sum(r["failure"] == "1" for r in accepted),
        )
    return out


def main():
    with opened(sys.argv[1]) as f:
        sharpness = {KEY(r): float(r["object_sharpness"]) for r in csv.DictReader(f)}
    defaults, combined = levels([sys.argv[2]]), levels([sys.argv[3]])
    for bar in (float(b) for b in sys.argv[4].split(",")):
        for fallback, second in ((False, False), (True, False), (True, True)):
            table = chosen(defaults, combined, sharpness, bar, fallback, second)
            cells, meeting = [], 0
            for family in RANGES:
                rows = [v for (f, _), v in table.items() if f == family]
                if not rows:
                    continue
                w = (max(v[0] for v in rows), min(v[1] for v in rows), max(v[2] for v in rows))
                ok = w[0] <= 10 and w[1] >= 70 and w[2] <= 2
                meeting += ok
                cells.append(f"{family} {w[0]:.1f}/{w[1]:.0f}/{w[2]:.1f}{'*' if ok else ''}")
            wrong = sum(v[3] for v in table.values())
            how = "+ second opinion" if second else ("yes" if fallback else "no ")
            print(f"bar {bar:.2f} fallback {how} meets {meeting}, accepted wrong {wrong}: "
                  + ", ".join(cells))


main()
