#!/usr/bin/env bash
# Build the viewer page's JavaScript bundle from the npm registry and put it, with its licence,
# into the package data: src/shprobe/viewer/static/vendor/ — one tree-shaken, minified ES module
# of the three.js parts the page uses (tools/js/entry.js), three/three.min.js: ~0.5 MB to parse
# instead of three.js's 2 MB of modules before the first frame.
#
# The bundle is committed, so installing or running shprobe never needs Node. This script is
# how it was made: three.js and esbuild are pinned by tools/js/package-lock.json (integrity
# hashes checked by `npm ci`), and tools/js/vendor.sha256 records the sha256 of every file it
# writes. Run it after changing tools/js/ (then commit the bundle and vendor.sha256).
#
#   tools/vendor_js.sh           rebuild into the package data, rewrite tools/js/vendor.sha256
#   tools/vendor_js.sh --check   rebuild into a temporary folder; fail unless it reproduces the
#                                committed files byte for byte and they match vendor.sha256
#                                (tests/packaging/test_packaging_vendor.py runs this where npm exists)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
js="$root/tools/js"
dest="$root/src/shprobe/viewer/static/vendor"
sums="$js/vendor.sha256"
check=0
[ "${1:-}" = "--check" ] && check=1

# npm ci into a private copy of tools/js for --check, so a check never touches the checkout
if [ "$check" = 1 ]; then
  work="$(mktemp -d)"
  trap 'rm -rf "$work"' EXIT
  cp "$js/package.json" "$js/package-lock.json" "$js/entry.js" "$work/"
  js="$work"
  out="$work/vendor"
else
  out="$dest.tmp"
fi
(cd "$js" && npm ci --ignore-scripts --no-audit --no-fund --loglevel=error >/dev/null)
three="$js/node_modules/three"
rm -rf "$out" && mkdir -p "$out/three"
"$js/node_modules/.bin/esbuild" "$js/entry.js" --bundle --format=esm --minify \
  --legal-comments=inline --log-level=warning --outfile="$out/three/three.min.js"
cp "$three/LICENSE" "$out/three/LICENSE"
ver="$(node -p "require('$three/package.json').version")"
esb="$(node -p "require('$js/node_modules/esbuild/package.json').version")"
printf 'three %s (npm, MIT, see three/LICENSE), bundled by esbuild %s from tools/js/entry.js\n' \
  "$ver" "$esb" > "$out/VERSIONS"

if [ "$check" = 1 ]; then
  diff -r "$out" "$dest" >/dev/null \
    || { echo "vendor_js.sh --check: the rebuilt bundle differs from ${dest#$root/}" >&2; exit 1; }
  (cd "$dest" && sha256sum --quiet -c "$sums") \
    || { echo "vendor_js.sh --check: ${dest#$root/} does not match tools/js/vendor.sha256" >&2
         exit 1; }
  echo "the bundle rebuilds byte for byte (three.js $ver, esbuild $esb)"
else
  rm -rf "$dest" && mv "$out" "$dest"
  (cd "$dest" && find . -type f | LC_ALL=C sort | sed 's|^\./||' | xargs sha256sum) > "$sums"
  echo "vendored three.js $ver into ${dest#$root/} (sha256 in tools/js/vendor.sha256)"
fi
