#!/usr/bin/env python3
"""LINE-2D (OpenCV contrib `cv2.linemod`) as a peer of acch's pose estimate.

Trains one LINE-2D template per training view of an `acch render` folder
(optionally with in-plane rotated copies), matches every image of one or more
test folders, takes the best-similarity match as the estimate of (θ, φ, roll)
and scores it with acch's rules: the paper's failure rule, the whole camera
rotation against the truth, and whether the similarity score could reject
wrong estimates the way acch's confidence network does.

Example:
    acch render --object fruitbox --out /tmp/train
    acch render --object fruitbox --views random:60 --background A \\
        --textures held-out --seed 7 --roll-deg 45 --out /tmp/test-A
    python eval/line2d.py --train /tmp/train --test /tmp/test-A \\
        --roll-range-deg 45 --roll-step-deg 15 --json out.json

Needs only numpy and opencv-contrib (cv2.linemod); runs on one thread.
"""

import argparse
import csv
import json
import math
import os
import platform
import sys
import time

import numpy as np

try:
    import cv2
except ImportError:  # pragma: no cover - environment problem, say so plainly
    sys.exit("line2d: error: cannot import cv2; install opencv-contrib-python-headless")
if not hasattr(cv2, "linemod"):
    sys.exit("line2d: error: this OpenCV has no cv2.linemod (needs the contrib build)")

# The paper's grasp tolerance, as acch's `protocol::failure_rule`.
FAIL_THETA_DEG = 10.0
FAIL_PHI_DEG = 20.0
# |Δφ| above this counts as the 180° flip a symmetric view invites.
FLIP_PHI_DEG = 160.0
ROT_OK_DEG = 10.0
# Share of estimates the rejection measure keeps (acch reports accepted ~70-100 %).
KEEP_SHARE = 0.70

LABEL_COLUMNS = ["file", "theta_deg", "phi_deg", "mask", "roll_deg",
                 "bbox_x", "bbox_y", "bbox_w", "bbox_h"]


def fail(msg, prog="line2d"):
    sys.exit(f"{prog}: error: {msg}")


def write_json(path, doc, prog="line2d"):
    """DOC to PATH as indented JSON; an error names the file."""
    try:
        with open(path, "w") as f:
            json.dump(doc, f, indent=1)
            f.write("\n")
    except OSError as e:
        fail(f"{path}: cannot write ({e.strerror})", prog)


# ---------------------------------------------------------------- input

def read_labels(folder):
    """Rows of FOLDER/labels.csv with numbers parsed; errors name the file and line."""
    path = os.path.join(folder, "labels.csv")
    if not os.path.isfile(path):
        fail(f"{path}: no such file (is {folder} an `acch render` folder?)")
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        missing = [c for c in LABEL_COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            fail(f"{path}: missing column(s) {', '.join(missing)}")
        rows = []
        for line, r in enumerate(reader, start=2):
            try:
                row = {"file": r["file"], "mask": r["mask"],
                       "theta": float(r["theta_deg"]), "phi": float(r["phi_deg"]),
                       "roll": float(r["roll_deg"] or 0.0),
                       "bbox": [int(float(r[k])) for k in ("bbox_x", "bbox_y", "bbox_w", "bbox_h")]}
            except (TypeError, ValueError) as e:
                fail(f"{path}:{line}: bad number ({e})")
            if not all(map(math.isfinite, (row["theta"], row["phi"], row["roll"]))):
                fail(f"{path}:{line}: non-finite angle")
            rows.append(row)
    if not rows:
        fail(f"{path}: no views")
    return rows


def read_image(folder, name, grey=False):
    path = os.path.join(folder, name)
    if not os.path.isfile(path):  # before imread, which only warns
        fail(f"{path}: no such file (named in {os.path.join(folder, 'labels.csv')})")
    img = cv2.imread(path, cv2.IMREAD_GRAYSCALE if grey else cv2.IMREAD_COLOR)
    if img is None:
        fail(f"{path}: not a readable image")
    return img


# ---------------------------------------------------------------- geometry

def camera_rotation(theta_deg, phi_deg, roll_deg):
    """World-from-camera rotation, columns (right, down, forward): a mirror of
    `ViewPose::world_from_camera_rotation` (stages/capture/src/camera.rs).
    θ is clamped into [0, 90] as `protocol::rotation_error_deg` does."""
    t = math.radians(min(max(theta_deg, 0.0), 90.0))
    p, r = math.radians(phi_deg), math.radians(roll_deg)
    st, ct, sp, cp = math.sin(t), math.cos(t), math.sin(p), math.cos(p)
    forward = -np.array([ct * cp, ct * sp, st])
    down = -np.array([-st * cp, -st * sp, ct])
    right = np.cross(down, forward)
    sr, cr = math.sin(r), math.cos(r)
    return np.column_stack([cr * right + sr * down, cr * down - sr * right, forward])


def rotation_error_deg(a, b):
    """Angle of the rotation between two (θ, φ, roll) cameras, degrees."""
    m = camera_rotation(*a).T @ camera_rotation(*b)
    return math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(m) - 1.0) / 2.0))))


def angle_diff(a, b):
    """|a - b| wrapped into [0, 180] (acch_pose::phi_error)."""
    d = (a - b) % 360.0
    return min(d, 360.0 - d)


def self_check():
    """The convention against acch's own cases (camera.rs, protocol.rs): a φ
    turn of 20° is a 20° rotation, and at θ = 90 a roll equals a φ turn
    (+90 roll = -90 azimuth). Raises rather than asserts (python -O)."""
    cases = [((60, 10, 0), (60, 30, 0), 20.0), ((45, 350, 0), (45, 10, 0), 20.0),
             ((90, 20, 90), (90, 290, 0), 0.0), ((90, 50, 20), (90, 30, 0), 0.0),
             ((60, 10, 0), (60, 10, 15), 15.0)]
    for a, b, want in cases:
        got = rotation_error_deg(a, b)
        if abs(got - want) > 1e-6:
            raise RuntimeError(f"rotation convention broken: {a} vs {b} gave {got}°, want {want}°")
    r = camera_rotation(70, 123, -33)
    if not (np.allclose(r.T @ r, np.eye(3)) and abs(np.linalg.det(r) - 1) < 1e-12):
        raise RuntimeError("camera_rotation is not a proper rotation")


# ---------------------------------------------------------------- detector

def make_detector(pyramid):
    if pyramid is None:
        return cv2.linemod.getDefaultLINE()
    # getDefaultLINE's modality, thresholds (10, 55) and 63 features, other T.
    # 63 is also OpenCV's ceiling: its 8-bit similarity asserts <= 63 features.
    return cv2.linemod.Detector([cv2.linemod.ColorGradient_create(10.0, 63, 55.0)], pyramid)


def roll_list(range_deg, step_deg):
    if range_deg == 0:
        return [0.0]
    n = int(math.floor(range_deg / step_deg + 1e-9))
    return [k * step_deg for k in range(-n, n + 1)]


def rotate_about_mask_centre(img, mask, roll_deg):
    """The view as a camera rolled by ROLL_DEG would see it: content turned
    counter-clockwise on screen (acch's sign), about the object's centre so
    it stays inside the frame."""
    if roll_deg == 0.0:
        return img, mask
    m = cv2.moments(mask, binaryImage=True)
    centre = (m["m10"] / m["m00"], m["m01"] / m["m00"])
    # getRotationMatrix2D's positive angle is counter-clockwise on screen.
    a = cv2.getRotationMatrix2D(centre, roll_deg, 1.0)
    size = (img.shape[1], img.shape[0])
    # Replicated border: no artificial black edge for gradients to lock onto.
    img_r = cv2.warpAffine(img, a, size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    mask_r = cv2.warpAffine(mask, a, size, flags=cv2.INTER_NEAREST, borderValue=0)
    return img_r, mask_r


def train(detector, folder, rolls):
    """One class per training view, one template id per roll copy that
    LINE-2D accepted. Returns the (class_id, template_id) -> view map and
    counts of the templates rejected for too few features."""
    rows = read_labels(folder)
    templates = {}
    rejected = {str(r): 0 for r in rolls}
    rejected_views = []
    t0 = time.perf_counter()
    for row in rows:
        img = read_image(folder, row["file"])
        mask = read_image(folder, row["mask"], grey=True)
        if mask.shape != img.shape[:2]:
            fail(f"{os.path.join(folder, row['mask'])}: size {mask.shape[::-1]} "
                 f"differs from its image's {img.shape[1::-1]}")
        mask = np.where(mask > 127, 255, 0).astype(np.uint8)
        if not mask.any():
            fail(f"{os.path.join(folder, row['mask'])}: empty mask (object not visible)")
        class_id = os.path.splitext(row["file"])[0]
        for roll in rolls:
            im_r, mk_r = rotate_about_mask_centre(img, mask, roll)
            tid, _ = detector.addTemplate([im_r], class_id, mk_r)
            if tid < 0:
                rejected[str(roll)] += 1
                rejected_views.append({"file": row["file"], "roll_deg": roll})
                continue
            # Template roll is added to the view's own (0 for acch's grid).
            templates[(class_id, tid)] = {"file": row["file"], "theta": row["theta"],
                                          "phi": row["phi"], "roll": row["roll"] + roll}
    return templates, {
        "folder": os.path.abspath(folder),
        "views": len(rows),
        "rolls_deg": rolls,
        "templates": len(templates),
        "rejected_too_few_features": sum(rejected.values()),
        "rejected_by_roll": rejected,
        "rejected_templates": rejected_views,
        "train_s": round(time.perf_counter() - t0, 3),
    }


# ---------------------------------------------------------------- scoring

def roc_auc(scores, positive):
    """P(score of a positive > score of a negative), ties count half; None
    when one class is empty (nothing to separate)."""
    pos = [s for s, p in zip(scores, positive) if p]
    neg = [s for s, p in zip(scores, positive) if not p]
    if not pos or not neg:
        return None
    s = np.asarray(scores, float)
    ranks = np.empty(len(s))
    order = np.argsort(s, kind="mergesort")
    ranks[order] = np.arange(1, len(s) + 1)
    for v in np.unique(s):  # average ranks over ties
        idx = s == v
        ranks[idx] = ranks[idx].mean()
    r_pos = ranks[np.asarray(positive, bool)].sum()
    return float((r_pos - len(pos) * (len(pos) + 1) / 2) / (len(pos) * len(neg)))


def mean(xs):
    return float(np.mean(xs)) if xs else None


def rnd(x, k=4):
    return None if x is None else round(float(x), k)


def evaluate(detector, templates, folder, threshold, limit):
    rows = read_labels(folder)[:limit] if limit else read_labels(folder)
    images = []
    for row in rows:
        img = read_image(folder, row["file"])
        t0 = time.perf_counter()
        matches, _ = detector.match([img], threshold)
        ms = (time.perf_counter() - t0) * 1000.0
        truth = (row["theta"], row["phi"], row["roll"])
        rec = {"file": row["file"], "truth_theta_deg": truth[0], "truth_phi_deg": truth[1],
               "truth_roll_deg": truth[2], "time_ms": round(ms, 3), "found": bool(matches)}
        if matches:
            # Sorted by similarity already; max() keeps the first of any tie.
            best = max(matches, key=lambda m: m.similarity)
            view = templates[(best.class_id, best.template_id)]
            est = (view["theta"], view["phi"], view["roll"])
            # Similarity saturates near 100 %: count the other poses that tie
            # with the best, and whether one of them would have passed.
            tied = {(v["theta"], v["phi"], v["roll"]) for v in
                    (templates[(m.class_id, m.template_id)] for m in matches
                     if m.similarity >= best.similarity)}
            tpl = detector.getTemplates(best.class_id, best.template_id)[0]
            bx, by, bw, bh = row["bbox"]
            # Does the template's box land on the object? (centre inside the truth box)
            cx, cy = best.x + tpl.width / 2, best.y + tpl.height / 2
            dtheta, dphi = abs(est[0] - truth[0]), angle_diff(est[1], truth[1])
            rec.update({
                "est_theta_deg": est[0], "est_phi_deg": est[1], "est_roll_deg": est[2],
                "template_view": view["file"], "similarity": round(float(best.similarity), 4),
                "match_x": int(best.x), "match_y": int(best.y),
                "match_w": int(tpl.width), "match_h": int(tpl.height),
                "on_object": bool(bx <= cx <= bx + bw and by <= cy <= by + bh),
                "theta_err_deg": round(dtheta, 4), "phi_err_deg": round(dphi, 4),
                "roll_err_deg": round(angle_diff(est[2], truth[2]), 4),
                "rotation_err_deg": round(rotation_error_deg(est, truth), 4),
                "failed": dtheta > FAIL_THETA_DEG or dphi > FAIL_PHI_DEG,
                "tied_poses": len(tied),
                "tie_has_pass": any(abs(t[0] - truth[0]) <= FAIL_THETA_DEG and
                                    angle_diff(t[1], truth[1]) <= FAIL_PHI_DEG for t in tied),
            })
        else:
            rec["failed"] = True
        images.append(rec)
    return images, metrics(images)


def metrics(images):
    n = len(images)
    found = [r for r in images if r["found"]]
    sims = [r["similarity"] for r in found]
    ok = [not r["failed"] for r in found]
    rot_ok = [r["rotation_err_deg"] <= ROT_OK_DEG for r in found]
    m = {
        "n": n,
        "not_found": n - len(found),
        # Denominator n: a missing match fails and is not within 10°.
        "failure_rate": sum(r["failed"] for r in images) / n,
        "rot10_rate": sum(rot_ok) / n,
        # Denominator: found estimates.
        "flip_rate": mean([r["phi_err_deg"] > FLIP_PHI_DEG for r in found]),
        "mean_phi_err_deg": mean([r["phi_err_deg"] for r in found]),
        "mean_theta_err_deg": mean([r["theta_err_deg"] for r in found]),
        "mean_roll_err_deg": mean([r["roll_err_deg"] for r in found]),
        "median_rotation_err_deg": float(np.median([r["rotation_err_deg"] for r in found])) if found else None,
        "on_object_rate": mean([r["on_object"] for r in found]),
        # Best similarity shared by several poses; failures a tie-break could have saved.
        "tie_rate": mean([r["tied_poses"] > 1 for r in found]),
        "failed_but_tie_had_pass": sum(r["failed"] and r["tie_has_pass"] for r in found),
        "mean_similarity": mean(sims),
        "auc_similarity_not_failed": roc_auc(sims, ok),
        "auc_similarity_rot10": roc_auc(sims, rot_ok),
        "mean_time_ms": mean([r["time_ms"] for r in images]),
        "median_time_ms": float(np.median([r["time_ms"] for r in images])),
    }
    if found:
        # The similarity that keeps 70 % of the estimates (ties may keep a few more).
        k = max(1, math.ceil(KEEP_SHARE * len(found)))
        thr = sorted(sims, reverse=True)[k - 1]
        kept = [r for r in found if r["similarity"] >= thr]
        m.update({
            "keep70_similarity_threshold": thr,
            "keep70_kept": len(kept),
            "keep70_failure_rate": mean([r["failed"] for r in kept]),
            "keep70_rot10_rate": mean([r["rotation_err_deg"] <= ROT_OK_DEG for r in kept]),
            "failure_rate_found": mean([r["failed"] for r in found]),
        })
    return {k: (rnd(v) if isinstance(v, float) else v) for k, v in m.items()}


def pct(x):
    return "   -" if x is None else f"{100 * x:5.1f}"


def deg(x):
    return "    -" if x is None else f"{x:6.2f}"


def print_table(results, out=sys.stdout):
    head = (f"{'test':<34} {'n':>3} {'nf':>3} {'fail%':>5} {'flip%':>5} {'Ephi':>6} {'Eth':>6} "
            f"{'Eroll':>6} {'rot10%':>6} {'AUC':>5} {'f@70%':>5} {'sim':>5} {'ms':>6}")
    print(head, file=out)
    print("-" * len(head), file=out)
    for res in results:
        m = res["metrics"]
        auc = m["auc_similarity_not_failed"]
        print(f"{res['name'][:34]:<34} {m['n']:>3} {m['not_found']:>3} {pct(m['failure_rate'])} "
              f"{pct(m['flip_rate'])} {deg(m['mean_phi_err_deg'])} {deg(m['mean_theta_err_deg'])} "
              f"{deg(m['mean_roll_err_deg'])} {pct(m['rot10_rate']):>6} "
              f"{'    -' if auc is None else f'{auc:5.2f}'} {pct(m.get('keep70_failure_rate'))} "
              f"{m['mean_similarity'] or 0:5.1f} {m['mean_time_ms']:6.1f}", file=out)


# ---------------------------------------------------------------- main

def parse_args(argv):
    p = argparse.ArgumentParser(
        prog="line2d.py",
        description=__doc__.split("\n\n")[0] + " Metrics per test folder: failures (paper rule "
        "|Δθ| > 10° or |Δφ| > 20°, φ wrapped to [0, 180], no match fails), 180° φ flips "
        "(|Δφ| > 160°), mean errors, whole camera rotation within 10° of the truth, and "
        "whether the similarity rejects: ROC AUC of similarity against 'not failed' and the "
        "failure rate above the similarity that keeps 70 % of the estimates.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="Folders are `acch render` output: labels.csv (file, theta_deg, phi_deg, "
        "distance_m, bbox_*, mask, roll_deg) with view images and white-object masks.")
    p.add_argument("--train", required=True, metavar="DIR",
                   help="training folder: one template (per roll) from each view and its mask")
    p.add_argument("--test", required=True, action="append", metavar="DIR",
                   help="test folder (repeat for several)")
    p.add_argument("--json", metavar="OUT", help="write settings, metrics and per-image rows here")
    p.add_argument("--roll-range-deg", type=float, default=0.0, metavar="R",
                   help="also train copies of every template rolled -R..R (0 = upright only; default 0)")
    p.add_argument("--roll-step-deg", type=float, default=15.0, metavar="S",
                   help="roll step of those copies (default 15)")
    p.add_argument("--pyramid", metavar="T1,T2,...", default=None,
                   help="LINE-2D spreading T per pyramid level (default: getDefaultLINE's, 5,8)")
    p.add_argument("--threshold", type=float, default=50.0, metavar="PCT",
                   help="match() similarity threshold in %%, low so a best match almost "
                   "always exists (default 50)")
    p.add_argument("--limit", type=int, default=0, metavar="N",
                   help="only the first N views of each test folder (0 = all)")
    a = p.parse_args(argv)
    if not (0 <= a.roll_range_deg <= 180):
        p.error("--roll-range-deg must be in [0, 180]")
    if a.roll_range_deg > 0 and not (0 < a.roll_step_deg <= a.roll_range_deg):
        p.error("--roll-step-deg must be in (0, --roll-range-deg]")
    if not (0 <= a.threshold <= 100):
        p.error("--threshold is a percentage in [0, 100]")
    if a.limit < 0:
        p.error("--limit must be >= 0")
    if a.pyramid is not None:
        try:
            a.pyramid = [int(t) for t in a.pyramid.split(",")]
        except ValueError:
            p.error(f"--pyramid {a.pyramid!r}: want comma-separated integers like 5,8")
        if not a.pyramid or min(a.pyramid) < 1:
            p.error("--pyramid: every T must be >= 1")
    for d in [a.train] + a.test:
        if not os.path.isdir(d):
            p.error(f"{d}: not a directory")
    # Fail now rather than after the whole run.
    if a.json and not os.path.isdir(os.path.dirname(os.path.abspath(a.json))):
        p.error(f"--json {a.json}: its directory does not exist")
    return a


def main(argv=None):
    a = parse_args(argv)
    self_check()
    # A build shares this machine: one thread, and timings comparable to acch's single-thread stage.
    cv2.setNumThreads(1)
    detector = make_detector(a.pyramid)
    rolls = roll_list(a.roll_range_deg, a.roll_step_deg)
    templates, train_info = train(detector, a.train, rolls)
    if not templates:
        fail(f"{a.train}: LINE-2D accepted no template (all had too few features)")
    print(f"trained {train_info['templates']} templates from {train_info['views']} views x "
          f"{len(rolls)} rolls in {train_info['train_s']:.1f} s; "
          f"{train_info['rejected_too_few_features']} rejected (too few features)", file=sys.stderr)
    results = []
    for folder in a.test:
        images, m = evaluate(detector, templates, folder, a.threshold, a.limit)
        results.append({"name": os.path.basename(os.path.normpath(folder)),
                         "folder": os.path.abspath(folder), "metrics": m, "images": images})
    print_table(results)
    if a.json:
        doc = {
            "method": "LINE-2D (cv2.linemod ColorGradient), best-similarity match",
            "opencv": cv2.__version__, "numpy": np.__version__, "python": platform.python_version(),
            "command": " ".join(sys.argv),
            "settings": {"threshold_pct": a.threshold,
                         "pyramid_T": [detector.getT(i) for i in range(detector.pyramidLevels())],
                         "roll_range_deg": a.roll_range_deg,
                         "roll_step_deg": a.roll_step_deg if a.roll_range_deg else None,
                         "threads": cv2.getNumThreads(), "limit": a.limit or None,
                         "failure_rule": {"theta_deg": FAIL_THETA_DEG, "phi_deg": FAIL_PHI_DEG},
                         "flip_phi_deg": FLIP_PHI_DEG, "rotation_ok_deg": ROT_OK_DEG,
                         "keep_share": KEEP_SHARE},
            "train": train_info,
            "tests": results,
        }
        write_json(a.json, doc)


if __name__ == "__main__":
    main()
