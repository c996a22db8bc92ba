#!/usr/bin/env bash
# Build the tuning page's front-end files into the Python package: uPlot and three.js, pinned in
# web/package-lock.json, from the npm registry (the page is served locally, never from a CDN).
# Installs Debian's nodejs and npm first when npm is missing. Run by make (target web) when
# web/package-lock.json is newer than the built files.
set -euo pipefail
cd "$(dirname "$0")/.."
VENDOR=src/jointctl/tuning/static/vendor
if ! command -v npm >/dev/null; then
  source scripts/apt_packages.sh
  install_missing build_web nodejs npm
fi
npm ci --prefix web --no-audit --no-fund --loglevel=error
mkdir -p "$VENDOR"
cp web/node_modules/uplot/dist/uPlot.iife.min.js web/node_modules/uplot/dist/uPlot.min.css "$VENDOR/"
cp web/node_modules/uplot/LICENSE "$VENDOR/uPlot.LICENSE"
cp web/node_modules/three/build/three.module.js web/node_modules/three/build/three.core.js "$VENDOR/"
cp web/node_modules/three/LICENSE "$VENDOR/three.LICENSE"
echo "build_web: uPlot $(node -p 'require("./web/node_modules/uplot/package.json").version'), three.js $(node -p 'require("./web/node_modules/three/package.json").version') -> $VENDOR"
