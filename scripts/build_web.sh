#!/usr/bin/env bash
# Build the tuning page's front-end files into the Python package: uPlot, pinned in
# web/package-lock.json, from the npm registry (the page is served locally, never from a CDN).
# Installs Debian's nodejs and npm first when npm is missing. Run by make (target web) when
# web/package-lock.json is newer than the built files.
set -euo pipefail
cd "$(dirname "$0")/.."
VENDOR=src/jointctl/tuning/static/vendor
as_root() {
  if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else
    echo "build_web: need root to run: $*" >&2; return 1; fi
}
if ! command -v npm >/dev/null; then
  echo "build_web: installing Debian's nodejs and npm"
  as_root apt-get update -q
  DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -q --no-install-recommends nodejs npm
fi
npm ci --prefix web --no-audit --no-fund --loglevel=error
mkdir -p "$VENDOR"
cp web/node_modules/uplot/dist/uPlot.iife.min.js web/node_modules/uplot/dist/uPlot.min.css "$VENDOR/"
cp web/node_modules/uplot/LICENSE "$VENDOR/uPlot.LICENSE"
echo "build_web: uPlot $(node -p 'require("./web/node_modules/uplot/package.json").version') -> $VENDOR"
