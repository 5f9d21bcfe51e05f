"""Independent zenoh subscriber for tests/pipeline_e2e.rs.

Connects to the pipeline's zenoh peer, collects every message on
acch/<object>/result and acch/<object>/seed until `count` results arrived
or `timeout` seconds passed, and compares each accepted seed's rotation with
the renderer's ground truth carried in the result. Prints one JSON line.
"""
import json
import math
import sys
import time

import zenoh

def angle_deg(q1, q2):
    """Angle between two rotations given as [x, y, z, w] quaternions."""
    dot = abs(sum(a * b for a, b in zip(q1, q2)))
    n1 = math.sqrt(sum(a * a for a in q1))
    n2 = math.sqrt(sum(a * a for a in q2))
    return math.degrees(2.0 * math.acos(min(1.0, dot / (n1 * n2))))


def main():
    endpoint, obj, count, timeout = sys.argv[1], sys.argv[2], int(sys.argv[3]), float(sys.argv[4])
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    # The test starts this subscriber first, listening; the pipeline connects.
    conf.insert_json5("listen/endpoints", json.dumps([endpoint]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("scouting/gossip/enabled", "false")
    results, seeds = {}, {}
    with zenoh.open(conf) as session:
        sub_r = session.declare_subscriber(f"acch/{obj}/result")
        sub_s = session.declare_subscriber(f"acch/{obj}/seed")
        print(json.dumps({"ready": True}), flush=True)
        deadline = time.time() + timeout
        while time.time() < deadline and len(results) < count:
            got = False
            for sub, store in ((sub_r, results), (sub_s, seeds)):
                s = sub.try_recv()
                while s is not None:
                    got = True
                    m = json.loads(s.payload.to_bytes())
                    store[m["sequence"]] = m
                    s = sub.try_recv()
            if not got:
                time.sleep(0.01)
    errors = []
    for seq, seed in seeds.items():
        r = results.get(seq)
        if r is None or r.get("truth") is None:
            continue
        errors.append(angle_deg(seed["rotation_xyzw"], r["truth"]["rotation_xyzw"]))
    # The pose fused over time (carried by the arm's motion): its rotation
    # against the truth, on every frame once the filter has started.
    fused_errors = [
        angle_deg(r["fused"]["rotation_xyzw"], r["truth"]["rotation_xyzw"])
        for r in results.values()
        if r.get("fused") is not None and r.get("truth") is not None
    ]
    accepted = sum(1 for r in results.values() if r["accepted"])
    # Each verdict against its own bars, from the message alone (the bars
    # travel with every verdict). An estimate the shape chose (verified 1)
    # is accepted when its contour lies on the region's edge, its
    # silhouette covers the region, it beats its rival by the margin, its
    # contour lies in the frame (for a region recognition found), its
    # elevation is not below the database's bar, and it was found at or
    # above recognition's threshold. Otherwise the colour rules: rated at or above the
    # threshold, no rival above its bar, no broad crest, no view placing
    # its region better, not faint; and when the shape fitted the colours'
    # estimate (verified 2), its contour on the region's edge too. An
    # accepted result is seeded (on the seed topic too); a rejected one has
    # no seed.
    bad_verdicts = []
    rejected = 0
    for seq, r in results.items():
        conf, thr = r.get("confidence"), r.get("threshold")
        margin, value = r.get("detection_margin"), r.get("match_value")
        rated = r.get("rating") in ("accepted", "rejected")
        if rated:
            under = margin is not None and margin < r["min_accepted_detection_margin"]
            faint = under or (margin is not None and margin < r["min_clear_detection_margin"]
                              and (value is None or not value >= r["min_clear_match_value"]))
        else:
            under = faint = False
        plateau, limit = r.get("phi_plateau_deg"), r.get("phi_plateau_limit_deg")
        broad = plateau is None or limit is None or not plateau < limit
        # A null map rival: nothing weighed (accepted), or not measurable
        # (rejected): the message's own flag tells which.
        map_rival, max_map_rival = r.get("map_rival"), r.get("max_map_rival")
        if map_rival is not None and max_map_rival is not None:
            misplaced = map_rival > max_map_rival
            consistent = r.get("misplaced") is misplaced
        else:
            misplaced = r.get("misplaced") is True
            consistent = r.get("misplaced") is not None or conf is None
        rival, max_rival = r.get("rival"), r.get("max_rival")
        colour = (conf is not None and thr is not None and conf >= thr
                  and rival is not None and max_rival is not None and rival <= max_rival
                  and not broad and not misplaced and not faint)
        verified = r.get("verified") or 0
        edge, min_edge = r.get("region_edge"), r.get("min_region_edge")
        agrees = edge is not None and min_edge is not None and edge >= min_edge
        overlap, min_overlap = r.get("overlap"), r.get("min_overlap")
        covers = overlap is not None and min_overlap is not None and overlap >= min_overlap
        # No distinct candidate: no margin to fall short of.
        shape_margin = r.get("shape_margin")
        clear = shape_margin is None or (r.get("min_shape_margin") is not None
                                         and shape_margin >= r["min_shape_margin"])
        # The contour in the frame, for a region recognition found (the
        # bar is sent only then).
        in_frame, min_in_frame = r.get("in_frame"), r.get("min_in_frame")
        framed = min_in_frame is None or (in_frame is not None and in_frame >= min_in_frame)
        # No lower than the database's views (the bar is sent when the
        # shape chose the pose and the database's lowest view is known).
        min_theta, est = r.get("min_theta_deg"), r.get("estimate_deg")
        in_range = min_theta is None or (
            est is not None and est[0] is not None and est[0] >= min_theta)
        # No farther than the distance bar (sent when the shape chose the
        # pose), judged on the fitted pose's translation.
        max_distance, fitted = r.get("max_distance_m"), r.get("fitted_pose")
        near = max_distance is None or (
            fitted is not None and math.dist(fitted[0], (0.0, 0.0, 0.0)) <= max_distance)
        if verified == 1:
            should = (agrees and covers and clear and framed and in_range and near
                      and not under)
        elif verified == 2:
            should = colour and agrees
        else:
            should = colour
        if not rated:
            ok = not r["accepted"] and r.get("seed") is None and seq not in seeds
        elif r["accepted"]:
            ok = (should and r.get("rating") == "accepted" and consistent
                  and r.get("faint") is faint
                  and r.get("seed") is not None and seq in seeds)
        else:
            rejected += 1
            ok = (not should and consistent and r.get("faint") is faint
                  and r.get("seed") is None and seq not in seeds)
        if not ok:
            bad_verdicts.append(seq)
    seeds_without_acceptance = sorted(s for s in seeds if not results.get(s, {}).get("accepted"))
    print(json.dumps({
        "results": len(results),
        "seeds": len(seeds),
        "accepted": accepted,
        "rejected": rejected,
        "bad_verdicts": bad_verdicts,
        "seeds_without_acceptance": seeds_without_acceptance,
        "compared": len(errors),
        "within_15deg": sum(1 for e in errors if e <= 15.0),
        "median_err_deg": sorted(errors)[len(errors) // 2] if errors else None,
        "fused": len(fused_errors),
        "fused_within_15deg": sum(1 for e in fused_errors if e <= 15.0),
        "fused_median_err_deg": sorted(fused_errors)[len(fused_errors) // 2] if fused_errors else None,
    }), flush=True)


if __name__ == "__main__":
    main()
