#!/usr/bin/env bash
# Install the viewer page's JavaScript libraries (three.js, and esbuild to bundle it) from the npm
# registry, pinned by tools/js/package-lock.json (integrity hashes checked by `npm ci`), and put
# what the page loads, with its licence, into the package data: src/shprobe/viewer/static/vendor/
# — one tree-shaken, minified ES module of the three.js parts the page uses (tools/js/entry.js),
# three/three.min.js: ~0.5 MB to parse instead of 2 MB before the first frame.
# Run once after checkout (.ci/run does); nothing is fetched at run time or from a CDN, and the
# vendored files are not committed (they are produced here).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
js="$root/tools/js"
dest="$root/src/shprobe/viewer/static/vendor"
(cd "$js" && npm ci --ignore-scripts --no-audit --no-fund --loglevel=error)
three="$js/node_modules/three"
rm -rf "$dest.tmp" && mkdir -p "$dest.tmp/three"
"$js/node_modules/.bin/esbuild" "$js/entry.js" --bundle --format=esm --minify \
  --legal-comments=inline --log-level=warning --outfile="$dest.tmp/three/three.min.js"
cp "$three/LICENSE" "$dest.tmp/three/LICENSE"
ver="$(node -p "require('$three/package.json').version")"
esb="$(node -p "require('$js/node_modules/esbuild/package.json').version")"
printf 'three %s (npm, MIT, see three/LICENSE), bundled by esbuild %s from tools/js/entry.js\n' \
  "$ver" "$esb" > "$dest.tmp/VERSIONS"
rm -rf "$dest" && mv "$dest.tmp" "$dest"
echo "vendored three.js $ver into ${dest#$root/}"
