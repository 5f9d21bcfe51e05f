"""Independent reader of a BOP challenge results file (tests/real_photographs.rs).

Reads FILE.csv as the BOP toolkit documents the format (header
scene_id,im_id,obj_id,score,R,t,time; R: 9 numbers, row-major, model to
camera; t: 3 numbers, millimetres; time: seconds) with Python's csv module
and NumPy only, checks every row, and compares the rows whose score is at
least 1 (what acch accepted) with the dataset's own annotations
(scene_gt.json, read here, not by acch): the rotation's angle to the
annotated one, and the translation's distance over the annotated distance.
Prints one JSON line.

Usage: bop_results_check.py RESULTS.csv SCENE_GT.json OBJ_ID [SYMMETRY]
SYMMETRY: z:2 when a half turn about the model's z axis looks the same.
"""
import csv
import json
import math
import sys

import numpy as np


def fail(msg):
    print(json.dumps({"error": msg}))
    sys.exit(1)


def main():
    path, gt_path, obj_id = sys.argv[1], sys.argv[2], int(sys.argv[3])
    symmetric = len(sys.argv) > 4 and sys.argv[4] == "z:2"
    with open(gt_path) as f:
        gt = json.load(f)
    turns = [np.eye(3)]
    if symmetric:
        turns.append(np.diag([-1.0, -1.0, 1.0]))
    rows = []
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header != ["scene_id", "im_id", "obj_id", "score", "R", "t", "time"]:
            fail(f"header {header}")
        for n, rec in enumerate(reader, start=2):
            if len(rec) != 7:
                fail(f"line {n}: {len(rec)} fields")
            scene, im, obj = int(rec[0]), int(rec[1]), int(rec[2])
            score, time_s = float(rec[3]), float(rec[6])
            r = np.array([float(x) for x in rec[4].split()])
            t = np.array([float(x) for x in rec[5].split()])
            if r.size != 9 or t.size != 3:
                fail(f"line {n}: R has {r.size} numbers, t {t.size}")
            r = r.reshape(3, 3)
            if not (np.allclose(r @ r.T, np.eye(3), atol=1e-4) and abs(np.linalg.det(r) - 1) < 1e-4):
                fail(f"line {n}: R is not a rotation")
            if not (np.all(np.isfinite(t)) and t[2] > 0):
                fail(f"line {n}: t {t} is not in front of the camera")
            if obj != obj_id or not math.isfinite(score) or time_s < 0:
                fail(f"line {n}: obj_id {obj}, score {score}, time {time_s}")
            annotated = [e for e in gt.get(str(im), []) if e["obj_id"] == obj_id]
            if not annotated:
                fail(f"line {n}: image {im} does not show object {obj_id}")
            # The instance nearest the estimate (LM-O shows each object once).
            best = None
            for e in annotated:
                # The annotation's nearest rotation: LM-O's are rounded
                # (R R^T up to 1e-2 off the identity).
                u, _, vt = np.linalg.svd(np.array(e["cam_R_m2c"]).reshape(3, 3))
                rg = u @ vt
                tg = np.array(e["cam_t_m2c"])
                angle = min(
                    math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(r.T @ rg @ s) - 1) / 2))))
                    for s in turns
                )
                rel = float(np.linalg.norm(t - tg) / np.linalg.norm(tg))
                if best is None or rel < best[1]:
                    best = (angle, rel)
            rows.append({"scene": scene, "im": im, "score": score, "rot": best[0], "rel": best[1]})
    accepted = [r for r in rows if r["score"] >= 1.0]
    med = lambda xs: float(np.median(xs)) if xs else None
    print(json.dumps({
        "rows": len(rows),
        "accepted": len(accepted),
        "median_rotation_err_deg": med([r["rot"] for r in accepted]),
        "median_translation_err_rel": med([r["rel"] for r in accepted]),
        "within_15deg_10pct": sum(1 for r in accepted if r["rot"] <= 15 and r["rel"] <= 0.1),
    }))


if __name__ == "__main__":
    main()
