#!/usr/bin/env python3
"""Times scikit-image's graycomatrix on the image and offsets of the ACCH bench.

The Rust benchmark (stages/core/benches/acch.rs) extracts ACCHs from the
top-left 64/128/256 px corners of a 256x256 index image with C = 40 colours
and polar offset sampling (4 rings at radii 11.25, 13.75, 16.25, 18.75 px x
48 angles (k + 0.5) * pi / 48). This script rebuilds the same image from the
same integer formula (checked by CRC-32), gives graycomatrix the same
distances, angles and levels (symmetric=False, normed=False), reports the
median time per call and the ratio to the Rust figures, and writes
bench/results/acch_vs_graycomatrix.json.

Rust figures come from --rust-json FILE (a previous output of this script or
{"acch_stride1_ms": {"64": ms, ...}, "acch_stride2_ms": {...}}), else from
criterion's estimates under --criterion-dir (default
$CARGO_TARGET_DIR/criterion, else target/criterion).

--rust-dump FILE (written by `ACCH_BENCH_DUMP=FILE cargo bench -p acch-core
--bench acch`) additionally checks that graycomatrix's matrices, folded into
12 orientation bins, equal the Rust stride-1 ACCH counts of the 128 px ROI.

Requires numpy and scikit-image (pip install scikit-image==0.26.0).
"""

import argparse
import json
import math
import os
import platform
import statistics
import sys
import time
import zlib
from pathlib import Path

import numpy as np

try:
    import skimage
    from skimage.feature import graycomatrix
except ImportError:  # pragma: no cover
    sys.exit("scikit-image is missing: pip install scikit-image==0.26.0")

SIDE = 256
ROIS = (64, 128, 256)
COLOURS = 40
BINS = 12
IMAGE_CRC32 = 0xBDC063DA  # Same constant as IMAGE_CRC32 in benches/acch.rs.
R_MIN, R_MAX, RINGS, ANGLES = 10.0, 20.0, 4, 48
REPO = Path(__file__).resolve().parent.parent
DEFAULT_OUT = REPO / "bench" / "results" / "acch_vs_graycomatrix.json"


def test_image():
    """`texture(x, y)` of benches/acch.rs for the whole 256x256 image."""
    y, x = np.mgrid[0:SIDE, 0:SIDE].astype(np.uint32)
    h = (x * np.uint32(0x9E3779B1)) ^ (y * np.uint32(0x85EBCA77))
    h ^= h >> np.uint32(15)
    h = h * np.uint32(0xC2B2AE3D)
    h ^= h >> np.uint32(13)
    bx, by = x // 8, y // 8
    block = (bx * 7 + by * 13 + bx * by) % COLOURS
    img = np.where(h % 4 == 0, (h >> np.uint32(8)) % COLOURS, block).astype(np.uint8)
    crc = zlib.crc32(img.tobytes())
    assert crc == IMAGE_CRC32, f"image CRC-32 {crc:08x} != {IMAGE_CRC32:08x}"
    return img


def polar_params():
    """Distances and angles of the default polar sampling.

    graycomatrix offsets a pixel by (row, col) = (round(sin(a) * d),
    round(cos(a) * d)), rows pointing down; the Rust offsets are
    (dx, dy) = (round(r cos a), -round(r sin a)) with a counter-clockwise angle
    and y pointing down. Both round half away from zero, so passing -a gives
    exactly the Rust vectors (and the same cost as +a).
    """
    distances = [R_MIN + (R_MAX - R_MIN) * (i + 0.5) / RINGS for i in range(RINGS)]
    angles = [-(k + 0.5) * math.pi / ANGLES for k in range(ANGLES)]
    return np.array(distances), np.array(angles)


def skimage_round(v):
    """skimage/_shared/interpolation.pxd round: half away from zero."""
    return int(v + 0.5) if v > 0.0 else int(v - 0.5)


def graycomatrix_offsets(distances, angles):
    """(dx, dy, ring, k) for every (distance, angle) graycomatrix visits."""
    return [
        (skimage_round(math.cos(a) * d), skimage_round(math.sin(a) * d), ring, k)
        for ring, d in enumerate(distances)
        for k, a in enumerate(angles)
    ]


def rust_offsets_f32():
    """HistogramParams::offsets(1.0) for the default params, in float32.

    Returns (offsets, borderline): borderline lists products within 1e-3 of
    a .5 rounding edge, where float32 and float64 could disagree.
    """
    f = np.float32
    pi = f(math.pi)
    out, seen, borderline = [], set(), []
    for ring in range(RINGS):
        r = f(R_MIN) + (f(R_MAX) - f(R_MIN)) * (f(ring) + f(0.5)) / f(RINGS)
        for k in range(ANGLES):
            a = (f(k) + f(0.5)) * pi / f(ANGLES)
            cx, sy = r * np.cos(a), r * np.sin(a)
            for v in (cx, sy):
                if abs(abs(float(v)) % 1.0 - 0.5) < 1e-3:
                    borderline.append((ring, k, float(v)))
            dx, dy = skimage_round(float(cx)), -skimage_round(float(sy))
            if (dx, dy) == (0, 0) or (dx, dy) in seen:
                continue
            seen.add((dx, dy))
            out.append((dx, dy, min(int(a / pi * f(BINS)), BINS - 1)))
    return out, borderline


def time_calls(fn, min_samples=30, min_seconds=2.0, warmup=2):
    for _ in range(warmup):
        fn()
    samples = []
    start = time.perf_counter()
    while len(samples) < min_samples or time.perf_counter() - start < min_seconds:
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return statistics.median(samples) * 1e3, len(samples)


def rust_from_criterion(directory):
    """Median ms of acch_extract/{stride1,stride2}/{64,128,256} and extras."""
    def median_ms(*parts):
        p = Path(directory, *parts, "new", "estimates.json")
        if not p.is_file():
            return None
        return json.loads(p.read_text())["median"]["point_estimate"] / 1e6

    out = {}
    for stride in ("stride1", "stride2"):
        vals = {str(n): median_ms("acch_extract", stride, str(n)) for n in ROIS}
        if all(v is not None for v in vals.values()):
            out[f"acch_{stride}_ms"] = vals
    for key, parts in (
        ("intersection_19200_ms", ("intersection_19200",)),
        ("response_into_216_ms", ("response_into_216",)),
    ):
        v = median_ms(*parts)
        if v is not None:
            out[key] = v
    return out or None


def load_rust(args):
    if args.rust_json:
        data = json.loads(Path(args.rust_json).read_text())
        rust = data.get("rust", data)
        return rust, str(args.rust_json)
    candidates = [args.criterion_dir] if args.criterion_dir else []
    if os.environ.get("CARGO_TARGET_DIR"):
        candidates.append(Path(os.environ["CARGO_TARGET_DIR"]) / "criterion")
    candidates.append(REPO / "target" / "criterion")
    for c in candidates:
        rust = rust_from_criterion(c)
        if rust:
            return rust, str(c)
    return None, None


def check_dump(path, img, distances, angles):
    """Folds graycomatrix's 128 px matrices into the Rust ACCH and compares."""
    dump = json.loads(Path(path).read_text())
    assert dump["image_crc32"] == IMAGE_CRC32, "dump is of another image"
    n = dump["roi"]
    rust_offsets = [tuple(o) for o in dump["offsets"]]
    p = graycomatrix(img[:n, :n], distances, angles, levels=COLOURS)
    acch = np.zeros((BINS, COLOURS, COLOURS), dtype=np.int64)
    first = {}
    for dx, dy, ring, k in graycomatrix_offsets(distances, angles):
        first.setdefault((dx, dy), (ring, k))
    missing = [o for o in rust_offsets if (o[0], o[1]) not in first]
    extra = sorted(set(first) - {(o[0], o[1]) for o in rust_offsets} - {(0, 0)})
    for dx, dy, d in rust_offsets:
        if (dx, dy) in first:
            ring, k = first[(dx, dy)]
            acch[d] += p[:, :, ring, k]
    counts = np.array(dump["counts"], dtype=np.int64).reshape(BINS, COLOURS, COLOURS)
    return {
        "roi": n,
        "rust_pairs": dump["pairs"],
        "graycomatrix_pairs_unique_offsets": int(acch.sum()),
        "offsets_missing_in_graycomatrix": missing,
        "offsets_extra_in_graycomatrix": extra,
        "histograms_equal": bool(np.array_equal(acch, counts)),
    }


def cpu_model():
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rust-json", type=Path, help="Rust medians (see module doc)")
    ap.add_argument("--criterion-dir", type=Path, help="criterion output directory")
    ap.add_argument("--rust-dump", type=Path, help="ACCH_BENCH_DUMP file to verify")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT, help="JSON to write")
    ap.add_argument("--seconds", type=float, default=2.0, help="min time per size")
    args = ap.parse_args()

    img = test_image()
    distances, angles = polar_params()
    g_offsets = graycomatrix_offsets(distances, angles)
    g_unique = {(dx, dy) for dx, dy, _, _ in g_offsets}
    r_offsets, borderline = rust_offsets_f32()
    r_set = {(dx, dy) for dx, dy, _ in r_offsets}
    offsets = {
        "graycomatrix_offsets": len(g_offsets),
        "graycomatrix_unique_offsets": len(g_unique),
        "rust_offsets_float32_model": len(r_offsets),
        "same_vector_set": g_unique - {(0, 0)} == r_set,
        "rounding_borderline_products": borderline,
        "note": "graycomatrix visits every (distance, angle) pair, duplicates "
        "included; the Rust polar sampling drops the duplicate integer vectors",
    }

    gray = {}
    pairs = {}
    for n in ROIS:
        sub = np.ascontiguousarray(img[:n, :n])

        def call(sub=sub):
            return graycomatrix(
                sub, distances, angles, levels=COLOURS, symmetric=False, normed=False
            )

        ms, samples = time_calls(call, min_seconds=args.seconds)
        gray[str(n)] = ms
        pairs[str(n)] = int(call().sum())
        print(f"graycomatrix {n}x{n}: median {ms:.3f} ms over {samples} calls",
              file=sys.stderr)

    rust, rust_source = load_rust(args)
    result = {
        "machine": {
            "nproc": os.cpu_count(),
            "cpu": cpu_model(),
            "python": platform.python_version(),
            "numpy": np.__version__,
            "scikit_image": skimage.__version__,
        },
        "image": {"side": SIDE, "colours": COLOURS, "crc32": f"{IMAGE_CRC32:08x}"},
        "graycomatrix_call": "graycomatrix(img[:n, :n], distances, angles, levels=40, "
        "symmetric=False, normed=False)",
        "distances": distances.tolist(),
        "angles_rad": "-(k + 0.5) * pi / 48, k = 0..47",
        "offsets": offsets,
        "graycomatrix_ms": gray,
        "graycomatrix_pairs": pairs,
        "rust": rust,
        "rust_source": rust_source,
    }
    if args.rust_dump:
        result["verification"] = check_dump(args.rust_dump, img, distances, angles)

    print(f"\nmachine: {result['machine']['nproc']} x {result['machine']['cpu']}, "
          f"scikit-image {skimage.__version__}, numpy {np.__version__}")
    print(f"offsets: graycomatrix {len(g_offsets)} ({len(g_unique)} distinct), "
          f"Rust polar {len(r_offsets)}; same vectors: {offsets['same_vector_set']}")
    if "verification" in result:
        v = result["verification"]
        print(f"check ({v['roi']} px, stride 1): histograms equal: "
              f"{v['histograms_equal']} ({v['rust_pairs']} pairs)")
    header = "| ROI | graycomatrix (ms) |"
    rule = "|---|---|"
    if rust:
        header += (" ACCH stride 1 (ms) | ACCH stride 2 (ms) |"
                   " graycomatrix / stride 1 | graycomatrix / stride 2 |")
        rule += "---|---|---|---|"
        ratios = {}
    print()
    print(header)
    print(rule)
    for n in ROIS:
        k = str(n)
        row = f"| {n}x{n} | {gray[k]:.2f} |"
        if rust:
            s1, s2 = rust["acch_stride1_ms"][k], rust["acch_stride2_ms"][k]
            r1, r2 = gray[k] / s1, gray[k] / s2
            ratios[k] = {"vs_stride1": r1, "vs_stride2": r2}
            row += f" {s1:.3f} | {s2:.3f} | {r1:.1f}x | {r2:.1f}x |"
        print(row)
    if rust:
        result["ratios_graycomatrix_over_rust"] = ratios
    else:
        print("\n(no Rust figures: run `cargo bench -p acch-core --bench acch` "
              "or pass --rust-json)", file=sys.stderr)

    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"\nwrote {args.out}", file=sys.stderr)
    if "verification" in result and not result["verification"]["histograms_equal"]:
        sys.exit("graycomatrix and the Rust ACCH disagree")


if __name__ == "__main__":
    main()
