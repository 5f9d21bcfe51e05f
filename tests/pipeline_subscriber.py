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

# acch_confidence::faint_and_weak: an estimate whose detection cleared its
# threshold by less than this and whose best match is below that is
# rejected whatever its confidence.
MIN_CLEAR_DETECTION_MARGIN = 1.3
MIN_CLEAR_MATCH_VALUE = 0.75


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
    # Each verdict against its own threshold, from the message alone: an
    # accepted result is rated at or above the threshold, with no rival
    # above its bar, no broad crest, no view placing its region better
    # (map rival at most its bar), not both faintly detected and weakly
    # matched, and seeded (on the seed topic too); a rejected one is rated
    # below it, has such a rival, crest or placement or is faint, and has
    # no seed, there or on the seed topic.
    bad_verdicts = []
    rejected = 0
    for seq, r in results.items():
        conf, thr = r.get("confidence"), r.get("threshold")
        margin, value = r.get("detection_margin"), r.get("match_value")
        faint = (margin is not None and margin < MIN_CLEAR_DETECTION_MARGIN
                 and (value is None or not value >= MIN_CLEAR_MATCH_VALUE))
        plateau, limit = r.get("phi_plateau_deg"), r.get("phi_plateau_limit_deg")
        broad = plateau is not None and limit is not None and not plateau < limit
        # A null map rival: nothing weighed (accepted), or not measurable
        # (rejected): the message's own flag tells which.
        map_rival, max_map_rival = r.get("map_rival"), r.get("max_map_rival")
        if map_rival is not None and max_map_rival is not None:
            misplaced = map_rival > max_map_rival
            consistent = r.get("misplaced") is misplaced
        else:
            misplaced = r.get("misplaced") is True
            consistent = r.get("misplaced") is not None or conf is None
        if r["accepted"]:
            ok = (r.get("rating") == "accepted" and conf is not None and thr is not None
                  and conf >= thr and r.get("rival") is not None
                  and r.get("max_rival") is not None and r["rival"] <= r["max_rival"]
                  and plateau is not None and limit is not None and not broad
                  and max_map_rival is not None and not misplaced and consistent
                  and not faint and r.get("faint") is False
                  and r.get("seed") is not None and seq in seeds)
        elif r.get("rating") == "rejected":
            rejected += 1
            rival, max_rival = r.get("rival"), r.get("max_rival")
            ok = (conf is not None and thr is not None
                  and (conf < thr or (rival is not None and max_rival is not None
                                      and rival > max_rival) or broad or misplaced
                      or faint)
                  and consistent and r.get("faint") is faint
                  and r.get("seed") is None and seq not in seeds)
        else:
            ok = r.get("seed") is None and seq not in seeds
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
