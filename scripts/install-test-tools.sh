#!/usr/bin/env bash
# Tools some tests use to check outputs with real readers. Best effort: each test skips with a clear
# message when its tool is missing, so a machine without root or npm still runs the rest.
#  - gltf-validator (npm, pinned in tests/js/package.json): the Khronos glTF validator
#  - chromium (Debian): headless browser for the report test (driven by playwright's Python API)
#  - libsdformat-dev (Debian): the SDFormat parser the SDF test compiles a tiny checker against
set -uo pipefail
cd "$(dirname "$0")/.."
if command -v npm >/dev/null 2>&1; then
  if [ ! -d tests/js/node_modules/gltf-validator ]; then
    npm install --prefix tests/js --no-audit --no-fund --silent || echo "note: npm install of gltf-validator failed; glTF validation tests will skip"
  fi
else
  echo "note: npm not found; glTF validation tests will skip"
fi
missing=()
command -v chromium >/dev/null 2>&1 || missing+=(chromium)
[ -f /usr/include/sdformat-12/sdf/sdf.hh ] || ls /usr/include/sdformat-*/sdf/sdf.hh >/dev/null 2>&1 || missing+=(libsdformat-dev)
if [ ${#missing[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "installing ${missing[*]} (Debian packages, for the report and SDF tests)"
    apt-get update -qq >/dev/null 2>&1 || true
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null 2>&1 \
      || echo "note: could not install ${missing[*]}; the tests that need them will skip"
  else
    echo "note: ${missing[*]} not installed (needs root: apt-get install ${missing[*]}); those tests will skip"
  fi
fi
exit 0
