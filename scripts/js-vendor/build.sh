#!/usr/bin/env bash
# Rebuild the vendored report viewer from the npm registry (build time only; the output is committed).
set -euo pipefail
cd "$(dirname "$0")"
npm install --no-audit --no-fund --silent
out=../../src/coastforge/report/static
mkdir -p "$out"
npx esbuild entry.js --bundle --minify --format=iife --legal-comments=none --outfile="$out/viewer.bundle.js"
{ echo "three.js $(node -p "JSON.parse(require('fs').readFileSync('node_modules/three/package.json')).version") — bundled into viewer.bundle.js"; echo;
  cat node_modules/three/LICENSE; } > "$out/THREE_LICENSE.txt"
ls -l "$out"
