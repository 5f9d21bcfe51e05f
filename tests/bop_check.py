"""An independent check of a BOP dataset against the format's spec
(bop_toolkit's docs/bop_datasets_format.md), written without acch's code:
projects the model's vertices with cam_K, cam_R_m2c and cam_t_m2c (mm) and
checks that they land on the visible mask, that bbox_visib and
px_count_visib describe the mask, and that the model's models_info.json
matches its vertices.

Usage: python bop_check.py DATASET_DIR SPLIT OBJ_ID
Prints one JSON line of what it checked; exits non-zero on a violation.
"""

import json
import struct
import sys
from pathlib import Path

import numpy as np
from PIL import Image


def check(ok, what):
    """An assert that python -O keeps: fails the check, saying what."""
    if not ok:
        sys.exit(f"check failed: {what}")


def read_ply_vertices(path):
    """x, y, z of every vertex of a binary little-endian or ASCII PLY."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    check(header[0] == "ply", f"{path}: not a PLY file")
    fmt = header[1].split()[1]
    elements, current = [], None
    for line in header[2:]:
        words = line.split()
        if words[0] == "element":
            current = (words[1], int(words[2]), [])
            elements.append(current)
        elif words[0] == "property":
            current[2].append(words[1:])
    name, count, props = elements[0]
    check(name == "vertex", f"{path}: the first element is {name}")
    sizes = {"float": "f", "float32": "f", "double": "d", "float64": "d",
             "uchar": "B", "uint8": "B", "char": "b", "int8": "b",
             "ushort": "H", "uint16": "H", "short": "h", "int16": "h",
             "uint": "I", "uint32": "I", "int": "i", "int32": "i"}
    names = [p[-1] for p in props]
    check(all(p[0] != "list" for p in props), f"{path}: a list property on vertices")
    if fmt == "ascii":
        lines = data[end:].decode("ascii").split("\n")[:count]
        rows = np.array([[float(v) for v in l.split()[: len(names)]] for l in lines])
    else:
        check(fmt == "binary_little_endian", f"{path}: format {fmt}")
        row = "<" + "".join(sizes[p[0]] for p in props)
        stride = struct.calcsize(row)
        rows = np.array([struct.unpack_from(row, data, end + i * stride) for i in range(count)])
    return rows[:, [names.index("x"), names.index("y"), names.index("z")]]


def main():
    root, split, obj_id = Path(sys.argv[1]), sys.argv[2], int(sys.argv[3])
    camera = json.loads((root / "camera.json").read_text())
    for key in ["cx", "cy", "fx", "fy", "width", "height", "depth_scale"]:
        check(key in camera, f"camera.json: no {key}")
    info = json.loads((root / "models" / "models_info.json").read_text())[str(obj_id)]
    v = read_ply_vertices(root / "models" / f"obj_{obj_id:06d}.ply")
    lo, size = v.min(axis=0), v.max(axis=0) - v.min(axis=0)
    for i, axis in enumerate("xyz"):
        check(abs(info[f"min_{axis}"] - lo[i]) < 1e-3, (axis, info, lo))
        check(abs(info[f"size_{axis}"] - size[i]) < 1e-3, (axis, info, size))
    # The diameter: no pair farther apart than it, and one pair near it.
    sub = v[:: max(1, len(v) // 1500)]
    far = np.linalg.norm(sub[:, None, :] - sub[None, :, :], axis=2).max()
    check(far <= info["diameter"] + 1e-3 and far > 0.9 * info["diameter"], (far, info))

    images = inside_all = 0
    for scene in sorted(p for p in (root / split).iterdir() if p.is_dir()):
        gt = json.loads((scene / "scene_gt.json").read_text())
        cams = json.loads((scene / "scene_camera.json").read_text())
        gt_info = json.loads((scene / "scene_gt_info.json").read_text())
        for im_id, instances in gt.items():
            k = np.array(cams[im_id]["cam_K"], dtype=float).reshape(3, 3)
            rgb = Image.open(scene / "rgb" / f"{int(im_id):06d}.png")
            check(rgb.mode == "RGB" and rgb.size == (camera["width"], camera["height"]), 'rgb.mode == "RGB" and rgb.size == (camera["width"], camera["height"])')
            for g, inst in enumerate(instances):
                if inst["obj_id"] != obj_id:
                    continue
                r = np.array(inst["cam_R_m2c"], dtype=float).reshape(3, 3)
                check(np.allclose(r @ r.T, np.eye(3), atol=1e-9), "cam_R_m2c is not a rotation")
                check(abs(np.linalg.det(r) - 1) < 1e-9, "cam_R_m2c is a reflection")
                t = np.array(inst["cam_t_m2c"], dtype=float)
                p = (k @ (v @ r.T + t).T).T
                check((p[:, 2] > 0).all(), f"{scene.name}/{im_id}: model behind the camera")
                uv = np.rint(p[:, :2] / p[:, 2:3]).astype(int)
                mask = np.array(Image.open(scene / "mask_visib" / f"{int(im_id):06d}_{g:06d}.png"))
                check(mask.shape == (camera["height"], camera["width"]), mask.shape)
                on = mask > 0
                h, w = on.shape
                ok = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
                check(ok.all(), f"{scene.name}/{im_id}: vertices project outside the image")
                # Every vertex lies on the object's silhouette, so within a
                # pixel of the visible mask (no occluders in these scenes).
                grown = on.copy()
                grown[1:, :] |= on[:-1, :]
                grown[:-1, :] |= on[1:, :]
                grown[:, 1:] |= grown[:, :-1].copy()
                grown[:, :-1] |= grown[:, 1:].copy()
                inside = grown[uv[:, 1], uv[:, 0]].mean()
                check(inside > 0.99, f"{scene.name}/{im_id}: only {inside:.3f} of the vertices on the mask")
                inside_all += inside
                info_i = gt_info[im_id][g]
                check(info_i["px_count_visib"] == int(on.sum()), (info_i, int(on.sum())))
                ys, xs = np.nonzero(on)
                bbox = [int(xs.min()), int(ys.min()), int(xs.max() - xs.min() + 1), int(ys.max() - ys.min() + 1)]
                check(info_i["bbox_visib"] == bbox, (info_i["bbox_visib"], bbox))
                images += 1
    check(images > 0, "no instance of the object")
    print(json.dumps({"instances": images, "mean_vertices_on_mask": inside_all / images}))


if __name__ == "__main__":
    main()
