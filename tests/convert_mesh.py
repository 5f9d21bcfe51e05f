"""Converts a textured OBJ with trimesh, an independent writer, into the
formats acch reads: GLB with the texture embedded, and binary and ASCII PLY
with vertex colours baked from the texture (each vertex takes the texel
under its texture coordinate).

Usage: python convert_mesh.py MESH.obj OUT_DIR
"""

import sys
from pathlib import Path

import trimesh

mesh = trimesh.load(sys.argv[1], process=False)
out = Path(sys.argv[2])
out.mkdir(parents=True, exist_ok=True)
stem = Path(sys.argv[1]).stem
mesh.export(out / f"{stem}.glb")
coloured = mesh.copy()
coloured.visual = mesh.visual.to_color()
coloured.export(out / f"{stem}_vc.ply", encoding="binary")
coloured.export(out / f"{stem}_vc_ascii.ply", encoding="ascii")
print(len(mesh.vertices), len(mesh.faces))
