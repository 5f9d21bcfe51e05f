"""Does the pipeline's per-frame choice (acch eval --protocol robust
--smoothing auto) give, image by image, what ../quality/select.py simulated
from the two recipes' stored runs?

python3 agree.py AUTO.csv[.gz] DEFAULT.csv[.gz] COMBINED.csv[.gz]
  For every image of AUTO (its column `set`: sharp or smoothed), the stored
  run of that set must have the same estimate, failure and acceptance; and
  the set must be the one the default run's measured quality asks for
  (noise_sigma > 2.5 or blockiness > 1.5; the CSV's 3 decimals can put a
  frame on the bar). Prints the counts.
"""
import csv
import gzip
import sys

FIELDS = ["est_theta_deg", "est_phi_deg", "failure", "accepted"]


def rows(path):
    with (gzip.open(path, "rt") if path.endswith(".gz") else open(path)) as f:
        return list(csv.DictReader(f))


def key(r):
    return (r["object"], r["family"], r["level"], r["light_search"],
            r["background"], r["image"])


def main(auto, default, combined):
    by_set = {"sharp": {key(r): r for r in rows(default)},
              "smoothed": {key(r): r for r in rows(combined)}}
    images = rows(auto)
    same = sum(all(r[f] == by_set[r["set"]][key(r)][f] for f in FIELDS)
               for r in images)
    smoothed = sum(r["set"] == "smoothed" for r in images)
    asked = sum((float(d["noise_sigma"]) > 2.5 or float(d["blockiness"]) > 1.5)
                != (r["set"] == "smoothed")
                for r in images for d in [by_set["sharp"][key(r)]])
    print(f"{len(images)} images: {same} as the stored run of their set, "
          f"{smoothed} smoothed, {asked} chosen otherwise than the stored "
          f"quality's 3 decimals say")


if __name__ == "__main__":
    main(*sys.argv[1:4])
