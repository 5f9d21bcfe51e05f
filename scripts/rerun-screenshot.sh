#!/bin/sh
# Records a run to rerun and MCAP and screenshots the rerun viewer showing
# it in the layout the viz process sends (docs/rerun-viewer.png). Needs the
# PyPI rerun-sdk==0.36.3 CLI, Xvfb, xdotool and a Vulkan software
# rasteriser (Debian: xvfb mesa-vulkan-drivers); the GL backend of
# llvmpipe cannot render to R32Float, which the viewer needs.
#
# The run is the built-in fruitbox with the camera sweeping 0-50° of
# elevation, mostly below the database's lowest θ slice (45°): the
# confidence network rejects a stretch of frames and accepts the rest
# (the last ones among them), so every element of the layout (rejected
# marks, threshold, seed axes) has something to show. The viewer shows the
# last frame (the time panel follows the newest data). 10 fps for 8 s
# keeps the file small enough for the viewer to load it whole before
# --screenshot-to takes its picture (240 frames were still loading).
#
# Usage: scripts/rerun-screenshot.sh [OUT.png] [KEEP_DIR]
#   KEEP_DIR keeps run.rrd and run.mcap (scripts/foxglove-screenshot.sh
#   takes the MCAP).
set -eu
out=${1:-docs/rerun-viewer.png}
keep=${2:-}
tmp=$(mktemp -d)
xvfb=
trap '[ -n "$xvfb" ] && kill "$xvfb" 2>/dev/null; rm -rf "$tmp"' EXIT
cargo run --release -- run --elevation 0,50 --fps 10 \
  --frames 80 --rerun "save:$tmp/run.rrd" --record "$tmp/run.mcap"
rerun rrd verify "$tmp/run.rrd"
Xvfb :99 -screen 0 3200x2000x24 >/dev/null 2>&1 &
xvfb=$!
sleep 2
# Xvfb's pointer sits in the middle of the screen and cannot be moved
# (it has no input device for xdotool); the viewer renders at 2 pixels a
# point here, so on a 1600x1000 screen the pointer hovers over the camera
# view and its tooltips cover the frame. A screen the size of the window
# puts the pointer at the window's centre: empty space in the 3-D view.
# --screenshot-to: the viewer renders one frame, saves it and quits (exit 102).
DISPLAY=:99 RERUN_ANALYTICS=0 WGPU_BACKEND=vulkan XDG_RUNTIME_DIR=$tmp \
  rerun "$tmp/run.rrd" --window-size 1600x1000 --screenshot-to "$tmp/shot.png" || true
python3 -c "from PIL import Image; Image.open('$tmp/shot.png').resize((1600, 1000), Image.LANCZOS).save('$out', optimize=True)"
if [ -n "$keep" ]; then
  mkdir -p "$keep"
  cp "$tmp/run.rrd" "$tmp/run.mcap" "$keep/"
fi
echo "wrote $out"
