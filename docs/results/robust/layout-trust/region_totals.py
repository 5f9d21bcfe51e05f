#!/usr/bin/env python3
"""Pools per-object `occlusion_region` outputs (one file per run, each
object's block headed `# generated-K`) into failures per occluder share
and mask, optionally over objects FIRST..LAST only.

usage: region_totals.py [--objects FIRST-LAST] FILE...
"""
import sys

MASKS = ["grown", "grown-extra", "grown+missed", "true", "grown+dropped"]


def totals(path, first, last):
    scenes, fails = {}, {}
    k = None
    for line in open(path):
        if line.startswith("# generated-"):
            k = int(line.split("-")[1])
            continue
        if not line[:3] in ("0.0", "0.1", "0.2", "0.3") or k is None:
            continue
        if not first <= k <= last:
            continue
        share, rest = line.split("|")[0].split(), line.split("|")[1].split()
        s, n = share[0], int(share[1])
        scenes[s] = scenes.get(s, 0) + n
        f = fails.setdefault(s, [0.0] * len(MASKS))
        for i, pct in enumerate(rest):
            f[i] += float(pct) * n / 100.0
    return scenes, fails


def main(argv):
    first, last = 0, 10**9
    if argv[:1] == ["--objects"]:
        first, last = map(int, argv[1].split("-"))
        argv = argv[2:]
    if not argv:
        sys.exit(__doc__)
    for path in argv:
        scenes, fails = totals(path, first, last)
        print(f"{path}: failures of the scenes by mask ({' '.join(MASKS)})")
        for s in sorted(scenes):
            print(f"  share {s} scenes {scenes[s]}: " + " ".join(f"{round(x):d}" for x in fails[s]))


if __name__ == "__main__":
    main(sys.argv[1:])
