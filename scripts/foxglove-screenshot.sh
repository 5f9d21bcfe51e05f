#!/bin/sh
# Screenshots docs/foxglove-layout.json in Lichtblick (the open-source fork
# of Foxglove Studio, same panels and layout format) showing an MCAP
# recording, in headless Chromium: docs/foxglove-viewer.png.
#
# Usage: scripts/foxglove-screenshot.sh FILE.mcap [OUT.png]
#   FILE.mcap: e.g. the run.mcap `scripts/rerun-screenshot.sh OUT KEEP_DIR`
#   keeps (the same run as the rerun screenshot).
#
# Needs:
# - LICHTBLICK_DIR: a Lichtblick checkout whose web app is built
#   (`yarn install` then `yarn web:build:dev`: web/.webpack) and whose
#   node_modules hold playwright-core and serve-handler (Lichtblick's own
#   dev dependencies). Foxglove Studio itself cannot be installed here;
#   docs/observers.md says how the build was made from npm packages.
# - chromium (Debian package) as the browser playwright drives.
#
# The app opens the file through its remote-file source (HTTP range
# requests), imports the layout from `layoutUrl`, and starts at the
# recording's last frame (`time`), as the rerun screenshot does.
set -eu
mcap=$1
out=${2:-docs/foxglove-viewer.png}
lb=${LICHTBLICK_DIR:?set LICHTBLICK_DIR to a built Lichtblick checkout}
layout=$(pwd)/docs/foxglove-layout.json
tmp=$(mktemp -d)
server=
trap '[ -n "$server" ] && kill "$server" 2>/dev/null; rm -rf "$tmp"' EXIT
mkdir "$tmp/site"
cp -r "$lb/web/.webpack/." "$tmp/site/"
ln -s "$(realpath "$mcap")" "$tmp/site/run.mcap"
cp "$layout" "$tmp/site/foxglove-layout.json"
# The recording's last message time, RFC 3339 with nanoseconds.
time=$(python3 -c "
import sys, datetime
from mcap.reader import make_reader
s = make_reader(open(sys.argv[1], 'rb')).get_summary().statistics
ns = s.message_end_time
t = datetime.datetime.fromtimestamp(ns // 10**9, datetime.timezone.utc)
print(t.strftime('%Y-%m-%dT%H:%M:%S') + '.%09dZ' % (ns % 10**9))
" "$mcap")
port=8765
cat > "$tmp/serve.cjs" <<EOF
const http = require("http");
const handler = require("$lb/node_modules/serve-handler");
http.createServer((req, res) => {
  res.setHeader("Access-Control-Allow-Origin", "*");
  return handler(req, res, { public: "$tmp/site", symlinks: true });
}).listen($port, "127.0.0.1");
EOF
node "$tmp/serve.cjs" &
server=$!
sleep 1
base="http://127.0.0.1:$port"
url="$base/?ds=remote-file&ds.url=$base/run.mcap&layoutUrl=$base/foxglove-layout.json&time=$time"
cat > "$tmp/shot.cjs" <<EOF
const { chromium } = require("$lb/node_modules/playwright-core");
(async () => {
  const browser = await chromium.launch({
    executablePath: "/usr/bin/chromium",
    args: ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
  });
  const page = await browser.newPage({ viewport: { width: 1600, height: 1000 } });
  page.on("pageerror", (e) => console.error("page error:", e.message));
  await page.goto("$url");
  // Loading the file, decoding it and filling the plots' full ranges.
  await page.waitForTimeout(40000);
  // Close the settings sidebar the app opens with (its X, top left), and
  // park the pointer on the title bar so no panel shows a hover.
  await page.mouse.click(304, 58);
  await page.mouse.move(1100, 20);
  await page.waitForTimeout(5000);
  await page.screenshot({ path: "$out" });
  await browser.close();
})();
EOF
node "$tmp/shot.cjs"
echo "wrote $out"
