#!/usr/bin/env bash
# README command 1: install dependencies, build, and run the main job on the default bundled recording
# (headless, OSMesa): composited frames and summary.json land in out/replay/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/install-deps.sh
bash tools/build.sh
build/app/mrgi replay recordings/tabletop-synth --scene recordings/scenes/tabletop.json --out out/replay
