#!/usr/bin/env python3
"""Checks that the tests can fail: each mutation below breaks the product
(or a test's input) the way a real bug would, runs the tests that should
catch it, and restores the file. A mutation the tests let pass is a test
that checks less than it says. Prints one line per mutation and exits 1
if any was missed.

Runs in a clean work tree only (it restores each file with git); takes
about 15 minutes on two cores, so it is not part of scripts/test. See
docs/tests.md.
"""

import argparse
import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TEST = "cargo test --release --features gstreamer --workspace"

# (name, file, text, replacement, the tests that must fail)
MUTATIONS = [
    ("ros2-bag-loses-images", "pipeline/src/ros2.rs",
     "        let f = &h.envelope.frame;\n        self.header.stamp = Time::from_ns(f.stamp_ns);",
     "        let f = &h.envelope.frame;\n        if f.sequence % 3 == 0 {\n            return Ok(());\n        }\n"
     "        self.header.stamp = Time::from_ns(f.stamp_ns);",
     TEST + " --test ros2_interop"),
    ("broad-crest-accepted", "pipeline/src/stages/confidence.rs",
     "            && !v.broad()\n", "\n", TEST + " --lib broad"),
    ("network-accepts-everything", "stages/confidence/src/model.rs",
     "Rating::new(self.rate(response, slices, views), self.threshold)",
     "Rating::new(self.rate(response, slices, views), 0.0)", TEST + " --test model"),
    ("recognition-never-finds", "stages/recognition/src/detector.rs",
     "pub const MIN_FOUND_MARGIN: f32 = 0.7;", "pub const MIN_FOUND_MARGIN: f32 = 1e9;",
     TEST + " --test multi_objects a_lane_computes"),
    ("obj-reader-loses-texture-coordinates", "stages/capture/src/mesh/obj.rs",
     ".map(|t| Vec2::new(t[0], 1.0 - t[1]))", ".map(|_t| Vec2::new(0.5, 0.5))",
     TEST + " --test mesh_formats"),
    ("shape-accepted-under-threshold", "pipeline/src/stages/confidence.rs",
     "                    && !v.under_threshold()\n", "", TEST + " --lib shape_chose"),
    ("shape-accepted-beyond-distance", "pipeline/src/stages/confidence.rs",
     "                    && v.shape_near()\n", "", TEST + " --lib distance_bar"),
    ("histograms-bias-azimuth", "stages/pose/src/lib.rs",
     "            phi_deg: phi_deg.rem_euclid(360.0),\n            best_view: best,",
     "            phi_deg: (phi_deg + 8.0).rem_euclid(360.0),\n            best_view: best,",
     TEST + " --test mesh_formats the_duck_as_glb"),
    ("capture-loses-every-other-frame", "pipeline/src/node.rs",
     "        tracing::trace!(\"frame {i}: source took {taken_ns} ns\");",
     "        tracing::trace!(\"frame {i}: source took {taken_ns} ns\");\n"
     "        if header.envelope.frame.sequence % 2 == 1 {\n"
     "            let _ = recycle_tx.send(pixels);\n            i += 1;\n            continue;\n        }",
     TEST + " --test cpu_latency"),
    ("gstreamer-drops-uncounted", "pipeline/src/gst.rs",
     "            self.counters.dropped += missed.saturating_sub(1);", "",
     TEST + " --test gst_source a_live_camera"),
    ("duck-mesh-missing", "stages/capture/tests/mesh_formats.rs",
     'const DUCK: &str = "/work/shared/data/duck/duck.obj";',
     'const DUCK: &str = "/work/shared/data/duck/missing.obj";',
     TEST + " --test mesh_formats the_duck_survives"),
    ("percentiles-unsorted", "bench/src/lib.rs",
     "fn q_ms(v: &[u64], q: f64) -> f64 {\n    let mut s = v.to_vec();\n    s.sort_unstable();", "fn q_ms(v: &[u64], q: f64) -> f64 {\n    let s = v.to_vec();",
     TEST + " --test bench_cli"),
    ("rate-over-one-frame-too-many", "eval/src/sequence.rs",
     "single_failure_rate: ratio(count(&single_fails), n),",
     "single_failure_rate: ratio(count(&single_fails), n + 1),", TEST + " --test sequence_cli"),
]


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("names", nargs="*", help="mutations to run (default: all)")
    p.add_argument("--list", action="store_true", help="list the mutations and the tests they run")
    args = p.parse_args()
    chosen = [m for m in MUTATIONS if not args.names or m[0] in args.names]
    unknown = set(args.names) - {m[0] for m in MUTATIONS}
    if unknown:
        sys.exit(f"unknown mutation(s): {', '.join(sorted(unknown))} (see --list)")
    if args.list:
        for name, path, _, _, cmd in chosen:
            print(f"{name}: {path} -> {cmd}")
        return
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                           cwd=ROOT, capture_output=True, text=True).stdout
    if dirty.strip():
        sys.exit("scripts/mutations.py restores files with git: commit or stash these first:\n" + dirty)
    env = dict(os.environ)
    env.setdefault("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
    venv = os.environ.get("ACCH_VENV", os.path.join(env["CARGO_TARGET_DIR"], "acch-venv"))
    env["PATH"] = os.path.join(venv, "bin") + os.pathsep + env["PATH"]
    if "ACCH_LMO" not in env:
        env["ACCH_LMO"] = subprocess.run([os.path.join(ROOT, "scripts/lmo")], capture_output=True,
                                         text=True, check=True).stdout.strip()
    missed = []
    for i, (name, path, old, new, cmd) in enumerate(chosen, 1):
        full = os.path.join(ROOT, path)
        text = open(full).read()
        if text.count(old) != 1:
            sys.exit(f"{name}: the text to mutate is not in {path} exactly once; update this script")
        open(full, "w").write(text.replace(old, new))
        start = time.time()
        try:
            run = subprocess.run(cmd, shell=True, cwd=ROOT, env=env, capture_output=True, text=True)
        finally:
            subprocess.run(["git", "checkout", "--", path], cwd=ROOT, check=True)
        failed = [line for line in (run.stdout + run.stderr).splitlines()
                  if line.startswith("test ") and line.endswith("FAILED")]
        caught = run.returncode != 0 and bool(failed)
        if not caught:
            missed.append(name)
        print(f"[{i}/{len(chosen)}] {name}: {'caught by ' + ', '.join(l[5:-10] for l in failed) if caught else 'MISSED'}"
              f" ({time.time() - start:.0f} s)", flush=True)
    if missed:
        sys.exit(f"missed: {', '.join(missed)}")


if __name__ == "__main__":
    main()
