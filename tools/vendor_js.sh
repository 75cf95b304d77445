#!/usr/bin/env bash
# Install the viewer page's JavaScript libraries (three.js) from the npm registry, pinned by
# tools/js/package-lock.json (integrity hashes checked by `npm ci`), and copy the files the page
# loads, with their licences, into the package data: src/shprobe/viewer/static/vendor/.
# Run once after checkout (.ci/run does); nothing is fetched at run time or from a CDN, and the
# vendored files are not committed (they are produced here).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
js="$root/tools/js"
dest="$root/src/shprobe/viewer/static/vendor"
(cd "$js" && npm ci --ignore-scripts --no-audit --no-fund --loglevel=error)
three="$js/node_modules/three"
rm -rf "$dest.tmp" && mkdir -p "$dest.tmp/three/addons/controls"
cp "$three/build/three.module.js" "$three/build/three.core.js" "$dest.tmp/three/"
cp "$three/examples/jsm/controls/OrbitControls.js" "$dest.tmp/three/addons/controls/"
cp "$three/LICENSE" "$dest.tmp/three/LICENSE"
ver="$(node -p "require('$three/package.json').version")"
printf 'three %s (npm, MIT, see three/LICENSE)\n' "$ver" > "$dest.tmp/VERSIONS"
rm -rf "$dest" && mv "$dest.tmp" "$dest"
echo "vendored three.js $ver into ${dest#$root/}"
