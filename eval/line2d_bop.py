#!/usr/bin/env python3
"""LINE-2D (OpenCV contrib `cv2.linemod`) on a BOP dataset's real photographs,
templates rendered from the object's mesh, side by side with acch's own
evaluation of the same instances.

For one object: renders the training views from the model with `acch render`
(the dataset's camera focal length, the dataset's median distance, the
elevations and roll range acch's own recipe takes from the dataset), trains
one LINE-2D template per view and in-plane rotated copy (eval/line2d.py),
matches every annotated instance with the search restricted to its annotated
visible mask's bounding box plus a margin (what `acch eval --segment mask`
is given), takes the most similar template's (θ, φ, roll) as the estimate
and scores it with acch's rules.

The truth and the instances are those of acch's JSON (`acch eval --bop DIR
--object ID --json FILE`): its `truth_deg` in acch's (θ, φ, roll)
convention, `bop_ids`, `distance_m`, `visib_fract`, and acch's own
`failure` / `accepted` for the side-by-side figures.

Example:
    acch eval --bop $L --object 1 --json /tmp/acch-1.json
    python eval/line2d_bop.py --bop $L --object 1 --acch-json /tmp/acch-1.json \\
        --out docs/results/line2d/lmo/obj_1.json

Needs numpy and opencv-contrib (cv2.linemod) and the acch binary (for the
templates); runs on one thread.
"""

import argparse
import glob
import json
import math
import os
import platform
import shlex
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import line2d  # noqa: E402  (exits with a plain message when cv2.linemod is missing)
from line2d import angle_diff, rotation_error_deg, FAIL_THETA_DEG, FAIL_PHI_DEG, FLIP_PHI_DEG, ROT_OK_DEG  # noqa: E402

cv2 = line2d.cv2
KEEP_SHARES = (0.25, 0.50, 1.00)
VISIBLE_BANDS = ((0.7, 1.01, "[0.7, 1]"), (0.3, 0.7, "[0.3, 0.7)"), (0.0, 0.3, "[0, 0.3)"))
# LINE-2D's linearised memories want each side divisible by T at every
# pyramid level: with T = (5, 8) on two levels, a multiple of 80 px. Widths
# that are an odd multiple of 80 (240, 400) crash cv2.linemod's match with
# a segmentation fault (OpenCV 5.0, measured): widths are multiples of 160.
WIDTH_MULTIPLE = 160
HEIGHT_MULTIPLE = 80


def fail(msg):
    line2d.fail(msg, "line2d_bop")


# ---------------------------------------------------------------- input

def read_json(path, what):
    if not os.path.isfile(path):
        fail(f"{path}: no such file ({what})")
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError) as e:
        fail(f"{path}: not readable JSON ({what}): {e}")


def read_acch(path, obj_id):
    """acch's per-instance rows, keyed by (scene, image, instance)."""
    d = read_json(path, "acch eval --bop ... --json output")
    if not isinstance(d, dict) or "images" not in d:
        fail(f"{path}: no `images` list (is it `acch eval --bop ... --json` output?)")
    want = f"obj_{obj_id:06d}"
    if d.get("object") != want:
        fail(f"{path}: evaluates object {d.get('object')!r}, not {want} (--object {obj_id})")
    if d.get("segment") != "mask":
        fail(f"{path}: acch ran with --segment {d.get('segment')}; the side-by-side wants mask")
    rows = []
    for k, r in enumerate(d["images"]):
        try:
            s, im, g = (int(x) for x in r["bop_ids"])
            truth = [float(x) for x in r["truth_deg"]]
            rows.append({"ids": (s, im, g), "truth": truth, "distance_m": float(r["distance_m"]),
                         "visib_fract": r.get("visib_fract"), "acch_failure": bool(r["failure"]),
                         "acch_accepted": bool(r["accepted"]), "acch_estimate": r.get("estimate_deg"),
                         "acch_rotation_err_deg": r.get("rotation_err_deg")})
        except (KeyError, TypeError, ValueError) as e:
            fail(f"{path}: images[{k}] lacks or mangles a field ({e!r}); "
                 "want bop_ids, truth_deg, distance_m, failure, accepted")
    if not rows:
        fail(f"{path}: no instances")
    return d, rows


def find_masks(explicit, scene):
    """The directory holding mask_visib/ and scene_gt_info.json for SCENE."""
    if explicit:
        cands = [explicit]
    else:
        root = os.path.expanduser("~/.cache/acch/bop-derived")
        cands = sorted(glob.glob(os.path.join(root, f"{scene:06d}-*")))
        if not cands:
            fail(f"{root}: no {scene:06d}-* directory of derived masks "
                 "(run `acch eval --bop` first, or give --masks DIR)")
        if len(cands) > 1:
            fail(f"{root}: several derived mask sets for scene {scene} ({', '.join(cands)}); "
                 "pick one with --masks DIR")
    d = cands[0]
    if not os.path.isdir(os.path.join(d, "mask_visib")):
        fail(f"{d}: no mask_visib/ directory")
    info = read_json(os.path.join(d, "scene_gt_info.json"), "visible boxes and shares")
    return d, info


def read_camera(scene_dir, bop_dir):
    for p in (os.path.join(scene_dir, "camera.json"), os.path.join(bop_dir, "camera.json")):
        if os.path.isfile(p):
            c = read_json(p, "BOP camera")
            try:
                return float(c["fx"]), float(c["fy"]), p
            except (KeyError, TypeError, ValueError):
                fail(f"{p}: no numeric fx, fy")
    fail(f"no camera.json in {scene_dir} or {bop_dir}")


def find_model(bop_dir, scene_dir, obj_id):
    name = f"obj_{obj_id:06d}.ply"
    for d in (os.path.join(bop_dir, "models"), os.path.join(scene_dir, "models")):
        if os.path.isfile(os.path.join(d, name)):
            return os.path.join(d, name)
    fail(f"{name}: not in {bop_dir}/models or {scene_dir}/models")


# ---------------------------------------------------------------- templates

def run(cmd):
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if p.returncode != 0:
        fail(f"`{shlex.join(cmd)}` failed ({p.returncode}): {p.stderr.strip()[-800:]}")


def object_radius_m(acch, model, work):
    """The bounding radius acch gives the model (its `object_radius_m`)."""
    probe = os.path.join(work, "probe")
    run([acch, "render", "--mesh", model, "--mesh-up", "+z", "--mesh-unit-m", "0.001",
         "--views", "grid:90:360", "--out", probe])
    with open(os.path.join(probe, "truth.jsonl")) as f:
        return float(json.loads(f.readline())["object_radius_m"])


def acch_recipe(rows, radius_m):
    """acch's `dataset_recipe` (eval/src/dataset.rs): elevations every 10°
    from the lowest annotated one (rounded down, at least 0) to 90, the
    median distance in radii (to 0.1), the roll of 95 % of instances rounded
    up to 15°."""
    lowest = max(0.0, min(min(r["truth"][0] for r in rows), 90.0))
    lowest = int(math.floor(lowest / 10.0) * 10)
    ds = sorted(r["distance_m"] for r in rows)
    dist_r = round(ds[len(ds) // 2] / radius_m * 10.0) / 10.0
    rolls = sorted(abs(r["truth"][2]) for r in rows)
    roll = rolls[min(len(rolls) * 95 // 100, len(rolls) - 1)]
    return lowest, dist_r, min(math.ceil(roll / 15.0) * 15.0, 180.0)


def render_templates(acch, model, out, lowest, dist_r, focal, phi_step):
    thetas = ",".join(str(t) for t in range(lowest, 91, 10))
    cmd = [acch, "render", "--mesh", model, "--mesh-up", "+z", "--mesh-unit-m", "0.001",
           "--views", f"grid:{thetas}:{phi_step:g}", "--distance", f"{dist_r:g}",
           "--focal", f"{focal:.3f}", "--out", out]
    if not os.path.isfile(os.path.join(out, "labels.csv")):
        t0 = time.perf_counter()
        run(cmd)
        return cmd, time.perf_counter() - t0
    return cmd, 0.0


# ---------------------------------------------------------------- matching

def crop_region(cx, cy, need_w, need_h, img_w, img_h):
    """A window of sides rounded up to WIDTH_ and HEIGHT_MULTIPLE around
    (cx, cy), moved inside the image where it fits; returns x0, y0, w, h (may
    overhang when the image is smaller: padded then)."""
    w = int(math.ceil(need_w / WIDTH_MULTIPLE) * WIDTH_MULTIPLE)
    h = int(math.ceil(need_h / HEIGHT_MULTIPLE) * HEIGHT_MULTIPLE)
    x0 = int(round(cx - w / 2))
    y0 = int(round(cy - h / 2))
    if w <= img_w:
        x0 = min(max(x0, 0), img_w - w)
    if h <= img_h:
        y0 = min(max(y0, 0), img_h - h)
    return x0, y0, w, h


def take(img, x0, y0, w, h):
    """img[y0:y0+h, x0:x0+w], replicated past the borders."""
    H, W = img.shape[:2]
    pad = max(0, -x0, -y0, x0 + w - W, y0 + h - H)
    if pad:
        img = cv2.copyMakeBorder(img, pad, pad, pad, pad, cv2.BORDER_REPLICATE)
        x0, y0 = x0 + pad, y0 + pad
    return np.ascontiguousarray(img[y0:y0 + h, x0:x0 + w])


def match_instance(detector, templates, tsize, img, bbox, scales, margin, threshold):
    """Best match over SCALES of the image around the visible box BBOX
    (x, y, w, h): the template's centre must lie within the box grown by
    MARGIN of its larger side. Returns (best dict or None, seconds)."""
    bx, by, bw, bh = bbox
    grow = margin * max(bw, bh)
    best = None
    t_total = 0.0
    tmax_w, tmax_h = tsize
    for k_s, s in enumerate(scales):
        t0 = time.perf_counter()
        interp = cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR
        H, W = img.shape[:2]
        sw, sh = max(1, int(round(W * s))), max(1, int(round(H * s)))
        im_s = cv2.resize(img, (sw, sh), interpolation=interp) if s != 1 else img
        # Allowed template centres, scaled image coordinates.
        ax0, ay0 = (bx - grow) * s, (by - grow) * s
        ax1, ay1 = (bx + bw + grow) * s, (by + bh + grow) * s
        # The window: every allowed centre with a whole template around it.
        # At least 160 px and twice the largest template: smaller windows
        # crash cv2.linemod's match (a segmentation fault at 80 x 80).
        need_w = max((ax1 - ax0) + tmax_w + 2, 2 * tmax_w, 160)
        need_h = max((ay1 - ay0) + tmax_h + 2, 2 * tmax_h, 160)
        x0, y0, w, h = crop_region((ax0 + ax1) / 2, (ay0 + ay1) / 2, need_w, need_h, sw, sh)
        crop = take(im_s, x0, y0, w, h)
        matches, _ = detector.match([crop], threshold)
        for m in matches:  # sorted by similarity, best first
            tw, th = tsize_of(detector, templates, m)
            cx = (m.x + x0 + tw / 2) / s
            cy = (m.y + y0 + th / 2) / s
            if not (bx - grow <= cx <= bx + bw + grow and by - grow <= cy <= by + bh + grow):
                continue
            if best is None or m.similarity > best["similarity"]:
                v = templates[(m.class_id, m.template_id)]
                best = {"similarity": float(m.similarity), "scale": s, "k": k_s,
                        "est": (v["theta"], v["phi"], v["roll"]), "x": cx, "y": cy}
            break  # later matches of this scale are no more similar
        t_total += time.perf_counter() - t0
    return best, t_total


_TSIZE = {}


def tsize_of(detector, templates, m):
    key = (m.class_id, m.template_id)
    if key not in _TSIZE:
        t = detector.getTemplates(m.class_id, m.template_id)[0]
        _TSIZE[key] = (t.width, t.height)
    return _TSIZE[key]


# ---------------------------------------------------------------- scoring

def truths_of(truth, symmetric):
    t = list(truth)
    out = [t]
    if symmetric:
        # A half turn about the model's up axis: same elevation and roll,
        # azimuth + 180 (acch's `Symmetry::equivalents` for z:2).
        out.append([t[0], (t[1] + 180.0) % 360.0, t[2]])
    return out


def fails(est, truth):
    return abs(est[0] - truth[0]) > FAIL_THETA_DEG or angle_diff(est[1], truth[1]) > FAIL_PHI_DEG


def score(est, truths):
    failed = all(fails(est, t) for t in truths)
    near = min(truths, key=lambda t: rotation_error_deg(est, t))
    return {"failed": failed, "rot_err": rotation_error_deg(est, near),
            "phi_err": angle_diff(est[1], near[1]), "theta_err": abs(est[0] - near[0])}


def share(k, n):
    return None if n == 0 else round(k / n, 4)


def rejection(rows):
    """Wrong share among the most similar KEEP_SHARES of the estimates."""
    found = [r for r in rows if r["sim"] is not None]
    sims = sorted((r["sim"] for r in found), reverse=True)
    out = {}
    for keep in KEEP_SHARES:
        if not found:
            out[f"keep{int(keep * 100)}"] = None
            continue
        k = max(1, math.ceil(keep * len(found)))
        thr = sims[k - 1]
        kept = [r for r in found if r["sim"] >= thr]  # ties keep a few more
        out[f"keep{int(keep * 100)}"] = {
            "similarity_threshold": round(thr, 3), "kept": len(kept),
            "wrong": sum(r["failed"] for r in kept),
            "wrong_share": share(sum(r["failed"] for r in kept), len(kept)),
            "rot10_share": share(sum(r["rot_err"] <= ROT_OK_DEG for r in kept), len(kept))}
    out["auc_similarity_right"] = line2d.roc_auc([r["sim"] for r in found],
                                                 [not r["failed"] for r in found])
    if out["auc_similarity_right"] is not None:
        out["auc_similarity_right"] = round(out["auc_similarity_right"], 4)
    return out


def summarise(rows, symmetric):
    n = len(rows)
    found = [r for r in rows if r["sim"] is not None]
    m = {"n": n, "not_found": n - len(found),
         "failures": sum(r["failed"] for r in rows),
         "failure_rate": share(sum(r["failed"] for r in rows), n),
         # Against the nearest truth by symmetry: for a half-turn-symmetric
         # object a 180° azimuth error is right and cannot count here.
         "flips": sum(r["phi_err"] > FLIP_PHI_DEG for r in found),
         "flip_rate": share(sum(r["phi_err"] > FLIP_PHI_DEG for r in found), n),
         "rot10": sum(r["rot_err"] <= ROT_OK_DEG for r in found),
         "rot10_rate": share(sum(r["rot_err"] <= ROT_OK_DEG for r in found), n),
         "median_rotation_err_deg": round(float(np.median([r["rot_err"] for r in found])), 2)
         if found else None,
         "rejection": rejection(rows)}
    m["by_visible_share"] = []
    for lo, hi, name in VISIBLE_BANDS:
        b = [r for r in rows if r["visib"] is not None and lo <= r["visib"] < hi]
        m["by_visible_share"].append({"band": name, "n": len(b),
                                      "failure_rate": share(sum(r["failed"] for r in b), len(b)),
                                      "acch_failure_rate": share(sum(r["acch_failure"] for r in b), len(b))})
    return m


def acch_summary(rows):
    n = len(rows)
    acc = [r for r in rows if r["acch_accepted"]]
    wrong = sum(r["acch_failure"] for r in acc)
    return {"n": n, "failures": sum(r["acch_failure"] for r in rows),
            "failure_rate": share(sum(r["acch_failure"] for r in rows), n),
            "accepted": len(acc), "accepted_rate": share(len(acc), n),
            "wrong_among_accepted": wrong, "wrong_among_accepted_share": share(wrong, len(acc)),
            "accepted_and_right_rate": share(len(acc) - wrong, n)}


def check_symmetry_rule(rows, symmetric):
    """Our failure rule on acch's own estimates against acch's `failure`."""
    agree, total, disagree = 0, 0, []
    for r in rows:
        e = r["acch_estimate"]
        if e is None:
            continue
        total += 1
        mine = all(fails(e, t) for t in truths_of(r["truth"], symmetric))
        if mine == r["acch_failure"]:
            agree += 1
        else:
            disagree.append(list(r["ids"]))
    return {"acch_estimates": total, "same_verdict": agree, "differ": disagree[:20]}


# ---------------------------------------------------------------- main

def parse_args(argv):
    p = argparse.ArgumentParser(
        prog="line2d_bop.py", description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="Scores: failure (the paper's |Δθ| > 10° or |Δφ| > 20°, φ wrapped, right if "
        "right against any symmetric truth; no match fails), flip (|Δφ| > 160° from the "
        "nearest truth), rotation within 10° (the whole camera rotation, θ, φ and roll), "
        "and rejection: the wrong share among the estimates whose similarity is in the top "
        "25 %, 50 %, 100 %, and the ROC AUC of similarity for 'right'. For a half-turn-"
        "symmetric object a flip is measured from the nearest truth, so it is no 180° "
        "turn the symmetry makes right.\n\n"
        + "\n\n".join(__doc__.split("\n\n")[1:]))
    p.add_argument("--bop", required=True, metavar="DIR", help="the BOP dataset (as acch eval --bop)")
    p.add_argument("--object", required=True, type=int, metavar="ID", help="BOP obj_id")
    p.add_argument("--acch-json", required=True, metavar="FILE",
                   help="`acch eval --bop DIR --object ID --json FILE` output: instances and truth")
    p.add_argument("--out", metavar="FILE", help="write the summary JSON here")
    p.add_argument("--acch", default=os.path.expanduser("~/.cache/acch-target/release/acch"),
                   metavar="BIN", help="the acch binary that renders the templates")
    p.add_argument("--work", default=None, metavar="DIR",
                   help="where templates are rendered (default /tmp/line2d_bop/obj_ID); "
                   "reused when it holds them")
    p.add_argument("--masks", metavar="DIR",
                   help="a directory with mask_visib/IMAGE_INSTANCE.png and scene_gt_info.json "
                   "(default: the dataset's own scene, else acch's derived cache ~/.cache/acch/bop-derived)")
    p.add_argument("--symmetry", choices=["none", "z:2"], default="none",
                   help="z:2: a half turn about the model's up axis looks the same (LM-O 10, 11)")
    p.add_argument("--roll-range-deg", type=float, default=None, metavar="R",
                   help="rolled template copies in -R..R (default: acch's recipe, the roll of "
                   "95 %% of the instances rounded up to 15°)")
    p.add_argument("--roll-step-deg", type=float, default=15.0, metavar="S", help="(default 15)")
    p.add_argument("--phi-step-deg", type=float, default=10.0, metavar="S",
                   help="azimuth step of the rendered views (default 10, as acch)")
    p.add_argument("--scale", choices=["box", "search", "truth"], default="box",
                   help="how the photograph is brought to the templates' size (templates are "
                   "rendered at the dataset's median distance with its focal length). box "
                   "(default): the image rescaled so the visible box's diagonal is the median "
                   "template's, times each of --scales, the most similar wins (uses only the "
                   "box, as acch takes its scale from the region); search: the image rescaled "
                   "by each of --scales; truth: by the annotated distance over the templates' "
                   "(an oracle, no search)")
    p.add_argument("--scales", default="0.84,0.92,1,1.09,1.19", metavar="S1,S2,...",
                   help="scale factors searched: relative to the box's estimate with --scale "
                   "box, absolute with search (default 2^(k/8), k = -2..2)")
    p.add_argument("--margin", type=float, default=0.25, metavar="F",
                   help="the template's centre may lie this share of the visible box's larger "
                   "side outside the box (default 0.25)")
    p.add_argument("--threshold", type=float, default=50.0, metavar="PCT",
                   help="match() similarity threshold, %% (default 50)")
    p.add_argument("--limit", type=int, default=0, metavar="N", help="first N instances only")
    p.add_argument("--rows", action="store_true", help="also store per-instance rows in --out")
    a = p.parse_args(argv)
    if not os.path.isdir(a.bop):
        p.error(f"--bop {a.bop}: not a directory")
    if not os.access(a.acch, os.X_OK):
        p.error(f"--acch {a.acch}: not an executable")
    if a.roll_range_deg is not None and not (0 <= a.roll_range_deg <= 180):
        p.error("--roll-range-deg must be in [0, 180]")
    if not (0 < a.roll_step_deg <= 180):
        p.error("--roll-step-deg must be in (0, 180]")
    if not (0 < a.phi_step_deg <= 360):
        p.error("--phi-step-deg must be in (0, 360]")
    try:
        a.scales = [float(s) for s in a.scales.split(",")]
    except ValueError:
        p.error(f"--scales {a.scales!r}: want comma-separated numbers like 0.8,1,1.25")
    if not a.scales or min(a.scales) <= 0:
        p.error("--scales: every factor must be > 0")
    if a.margin < 0:
        p.error("--margin must be >= 0")
    if not (0 <= a.threshold <= 100):
        p.error("--threshold is a percentage in [0, 100]")
    if a.out and not os.path.isdir(os.path.dirname(os.path.abspath(a.out))):
        p.error(f"--out {a.out}: its directory does not exist")
    return a


def main(argv=None):
    a = parse_args(argv)
    line2d.self_check()
    cv2.setNumThreads(1)
    t_start = time.perf_counter()
    doc_acch, rows = read_acch(a.acch_json, a.object)
    all_rows = rows
    if a.limit:
        rows = rows[:a.limit]
    symmetric = a.symmetry == "z:2"
    scenes = sorted({r["ids"][0] for r in rows})
    if len(scenes) != 1:
        fail(f"{a.acch_json}: instances of scenes {scenes}; this script reads one scene")
    scene = scenes[0]
    scene_dir = os.path.join(a.bop, "test", f"{scene:06d}")
    if not os.path.isdir(scene_dir):
        fail(f"{scene_dir}: no such scene directory (from {a.acch_json}'s bop_ids)")
    own = os.path.join(scene_dir, "mask_visib")
    mask_dir, gt_info = find_masks(a.masks or (scene_dir if os.path.isdir(own) else None), scene)
    fx, fy, cam_path = read_camera(scene_dir, a.bop)
    model = find_model(a.bop, scene_dir, a.object)
    work = a.work or f"/tmp/line2d_bop/obj_{a.object}"
    os.makedirs(work, exist_ok=True)

    radius = object_radius_m(a.acch, model, work)
    lowest, dist_r, roll_recipe = acch_recipe(all_rows, radius)
    roll_range = roll_recipe if a.roll_range_deg is None else a.roll_range_deg
    rolls = line2d.roll_list(roll_range, a.roll_step_deg) if roll_range > 0 else [0.0]
    focal = (fx + fy) / 2.0
    tdir = os.path.join(work, f"templates-from{lowest}-at{dist_r:g}r-phi{a.phi_step_deg:g}")
    render_cmd, render_s = render_templates(a.acch, model, tdir, lowest, dist_r, focal,
                                            a.phi_step_deg)
    template_distance_m = dist_r * radius
    trows = line2d.read_labels(tdir)
    template_diag = float(np.median([math.hypot(t["bbox"][2], t["bbox"][3]) for t in trows]))

    detector = line2d.make_detector(None)
    templates, train_info = line2d.train(detector, tdir, rolls)
    if not templates:
        fail(f"{tdir}: LINE-2D accepted no template")
    tsize = (0, 0)
    for cid, tid in templates:
        t = detector.getTemplates(cid, tid)[0]
        tsize = (max(tsize[0], t.width), max(tsize[1], t.height))
    print(f"obj {a.object}: {train_info['templates']} templates ({train_info['views']} views x "
          f"{len(rolls)} rolls, {train_info['rejected_too_few_features']} rejected) in "
          f"{train_info['train_s']:.1f} s; largest {tsize[0]}x{tsize[1]} px", file=sys.stderr)

    images = {}
    out_rows = []
    match_s = []
    for k, r in enumerate(rows):
        s_id, im_id, g = r["ids"]
        if im_id not in images:
            images.clear()
            path = os.path.join(scene_dir, "rgb", f"{im_id:06d}.png")
            img = cv2.imread(path, cv2.IMREAD_COLOR) if os.path.isfile(path) else None
            if img is None:
                fail(f"{path}: missing or unreadable (instance {r['ids']} of {a.acch_json})")
            images[im_id] = img
        img = images[im_id]
        mpath = os.path.join(mask_dir, "mask_visib", f"{im_id:06d}_{g:06d}.png")
        mask = cv2.imread(mpath, cv2.IMREAD_GRAYSCALE) if os.path.isfile(mpath) else None
        if mask is None:
            fail(f"{mpath}: missing or unreadable visible mask of instance {r['ids']}")
        mask = np.where(mask > 127, 255, 0).astype(np.uint8)
        info = gt_info.get(str(im_id), [])
        if g >= len(info):
            fail(f"{mask_dir}/scene_gt_info.json: no entry {g} for image {im_id}")
        bbox = [int(v) for v in info[g]["bbox_visib"]]
        ys, xs = np.nonzero(mask)
        if len(xs):
            mb = [int(xs.min()), int(ys.min()), int(xs.max() - xs.min() + 1), int(ys.max() - ys.min() + 1)]
            if mb != bbox:
                fail(f"{mpath}: box {mb} differs from scene_gt_info's bbox_visib {bbox}")
        rec = {"ids": r["ids"], "visib": r["visib_fract"], "dist": r["distance_m"], "acch_failure": r["acch_failure"],
               "acch_accepted": r["acch_accepted"], "sim": None, "failed": True,
               "rot_err": 180.0, "phi_err": 0.0, "est": None, "scale": None, "k": None}
        if bbox[2] > 0 and bbox[3] > 0:
            if a.scale == "truth":
                scales = [r["distance_m"] / template_distance_m]
            elif a.scale == "box":
                s_box = template_diag / math.hypot(bbox[2], bbox[3])
                scales = [s_box * f for f in a.scales]
            else:
                scales = a.scales
            best, secs = match_instance(detector, templates, tsize, img, bbox, scales,
                                        a.margin, a.threshold)
            match_s.append(secs)
            if best is not None:
                sc = score(best["est"], truths_of(r["truth"], symmetric))
                rec.update({"sim": best["similarity"], "failed": sc["failed"],
                            "rot_err": sc["rot_err"], "phi_err": sc["phi_err"],
                            "est": best["est"], "scale": best["scale"], "k": best["k"]})
        out_rows.append(rec)
        if (k + 1) % 25 == 0:
            done = out_rows
            print(f"  {k + 1}/{len(rows)}: failures {sum(x['failed'] for x in done)}, "
                  f"{np.mean(match_s):.2f} s/instance", file=sys.stderr)

    m = summarise(out_rows, symmetric)
    acch_m = acch_summary(out_rows)
    total_s = time.perf_counter() - t_start
    doc = {
        "method": "LINE-2D (cv2.linemod ColorGradient, getDefaultLINE: T 5,8, 63 features), "
                  "templates rendered from the mesh by acch, best-similarity match",
        "command": shlex.join([os.path.basename(sys.executable)] + sys.argv),
        "opencv": cv2.__version__, "numpy": np.__version__, "python": platform.python_version(),
        "dataset": {"bop": os.path.abspath(a.bop), "scene": scene, "camera": cam_path,
                    "masks": mask_dir, "model": model, "object": a.object,
                    "symmetry": a.symmetry, "acch_json": os.path.abspath(a.acch_json),
                    "acch_source": doc_acch.get("source")},
        "settings": {
            "views": f"theta {lowest}..90 step 10, phi step {a.phi_step_deg:g}",
            "template_distance_radii": dist_r, "object_radius_m": round(radius, 5),
            "template_distance_m": round(template_distance_m, 4), "focal_px": round(focal, 3),
            "render_command": shlex.join(render_cmd), "render_s": round(render_s, 2),
            "roll_range_deg": roll_range, "roll_recipe_deg": roll_recipe,
            "roll_step_deg": a.roll_step_deg, "rolls": len(rolls),
            "scale": a.scale, "scales": a.scales if a.scale != "truth" else "annotated distance / template distance",
            "template_median_box_diagonal_px": round(template_diag, 2),
            "margin": a.margin, "threshold_pct": a.threshold,
            "threads": cv2.getNumThreads(), "limit": a.limit or None,
            "failure_rule": {"theta_deg": FAIL_THETA_DEG, "phi_deg": FAIL_PHI_DEG},
            "flip_phi_deg": FLIP_PHI_DEG, "rotation_ok_deg": ROT_OK_DEG},
        "train": {"views": train_info["views"], "templates": train_info["templates"],
                  "rejected_too_few_features": train_info["rejected_too_few_features"],
                  "train_s": train_info["train_s"], "largest_template_px": list(tsize)},
        "timing": {"match_s_per_instance_mean": round(float(np.mean(match_s)), 3) if match_s else None,
                   "match_s_per_instance_median": round(float(np.median(match_s)), 3) if match_s else None,
                   "total_s": round(total_s, 1)},
        "line2d": m,
        "acch": acch_m,
        "acch_failure_rule_check": check_symmetry_rule(rows, symmetric),
    }
    if a.scale != "truth" and out_rows:
        ks = [x["k"] for x in out_rows if x["k"] is not None]
        doc["line2d"]["chosen_scale_factor_counts"] = {f"{f:g}": ks.count(k) for k, f in enumerate(a.scales)}
    # The scale the estimate was matched at over the annotated one (1: the
    # object at the templates' size).
    ratio = [x["scale"] / (x["dist"] / template_distance_m) for x in out_rows if x["scale"]]
    if ratio:
        doc["line2d"]["matched_over_true_scale_quantiles_5_50_95"] = [
            round(float(np.quantile(ratio, q)), 3) for q in (0.05, 0.5, 0.95)]
    if a.rows:
        doc["rows_columns"] = ["scene", "image", "instance", "visib_fract", "est_theta", "est_phi",
                               "est_roll", "similarity", "scale", "failed", "rot_err_deg",
                               "acch_failure", "acch_accepted"]
        doc["rows"] = [[*x["ids"], None if x["visib"] is None else round(x["visib"], 3),
                        *(x["est"] or (None, None, None)),
                        None if x["sim"] is None else round(x["sim"], 2),
                        None if x["scale"] is None else round(x["scale"], 3),
                        int(x["failed"]), round(x["rot_err"], 1),
                        int(x["acch_failure"]), int(x["acch_accepted"])] for x in out_rows]
    rj = m["rejection"]
    pr = lambda v: "-" if v is None else f"{100 * v:.1f} %"  # noqa: E731
    print(f"obj {a.object} (n {m['n']}): LINE-2D failures {pr(m['failure_rate'])}, flips "
          f"{pr(m['flip_rate'])}, rot<=10 {pr(m['rot10_rate'])}, wrong among top 25 % "
          f"{pr(rj['keep25'] and rj['keep25']['wrong_share'])}, top 50 % "
          f"{pr(rj['keep50'] and rj['keep50']['wrong_share'])}, AUC {rj['auc_similarity_right']}; "
          f"acch failures {pr(acch_m['failure_rate'])}, accepted {acch_m['accepted']} "
          f"({pr(acch_m['accepted_rate'])}), wrong among accepted {acch_m['wrong_among_accepted']}; "
          f"{doc['timing']['match_s_per_instance_mean']} s/instance, total {total_s:.0f} s")
    if a.out:
        line2d.write_json(a.out, doc, "line2d_bop")


if __name__ == "__main__":
    main()
