#!/bin/sh
# Records a short run to rerun and screenshots the rerun viewer showing it
# (docs/rerun-viewer.png). Needs the PyPI rerun-sdk==0.36.3 CLI, Xvfb and a
# Vulkan software rasteriser (Debian: xvfb mesa-vulkan-drivers); the GL
# backend of llvmpipe cannot render to R32Float, which the viewer needs.
set -eu
out=${1:-docs/rerun-viewer.png}
tmp=$(mktemp -d)
trap 'kill $xvfb 2>/dev/null; rm -rf "$tmp"' EXIT
cargo run --release -- run --frames 40 --rerun "save:$tmp/run.rrd"
Xvfb :99 -screen 0 1600x1000x24 >/dev/null 2>&1 &
xvfb=$!
sleep 2
# --screenshot-to: the viewer renders one frame, saves it and quits (exit 102).
DISPLAY=:99 RERUN_ANALYTICS=0 WGPU_BACKEND=vulkan XDG_RUNTIME_DIR=$tmp \
  rerun "$tmp/run.rrd" --window-size 1600x1000 --screenshot-to "$tmp/shot.png" || true
python3 -c "from PIL import Image; Image.open('$tmp/shot.png').resize((1600, 1000), Image.LANCZOS).save('$out', optimize=True)"
echo "wrote $out"
