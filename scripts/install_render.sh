#!/usr/bin/env bash
# Offscreen rendering for `jointctl run --video` and the demo report's videos: Mesa's software EGL
# (MuJoCo draws through it, no display needed) and ffmpeg (the MP4s), from Debian's packages.
# And for `--view`'s tests, a virtual display (Xvfb) and xdotool to find its window.
# Installs only what is missing. Run by make (targets render, demo and test).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/apt_packages.sh
install_missing render libegl1 libegl-mesa0 libgl1-mesa-dri libgles2 ffmpeg xvfb xauth xdotool libglfw3
