#!/usr/bin/env bash
# Installs every build and test dependency of mrgi from Debian packages.
# Idempotent: safe to run again; it only adds what is missing.
set -euo pipefail
SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
PACKAGES=(
  build-essential cmake ninja-build pkg-config python3 khronos-api
  libopencv-dev libopencv-contrib-dev libpng-dev libjpeg-dev libopenexr-dev
  libopenni2-dev libapriltag-dev libv4l-dev
  libglfw3-dev libosmesa6-dev libegl-dev libgl-dev libegl-mesa0 libgl1-mesa-dri
  libembree-dev libassimp-dev libimgui-dev libnanoflann-dev libopen3d-dev
  nlohmann-json3-dev libcli11-dev libgtest-dev libgmock-dev libbenchmark-dev
  xvfb xauth clang-format
  chromium fonts-dejavu-core  # the bench report rendered headless (Cli.TheBenchReportReads…)
)
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${PACKAGES[@]}"
