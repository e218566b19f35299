#!/usr/bin/env bash
# The unit tests once under AddressSanitizer + UBSan (clang-15), in the fuzzers' build directory
# (build-fuzz/, the same instrumented libraries). CI runs it after the fuzzers.
#   tools/sanitize.sh          the suite without the GL-only tests and the slowest numerical ones
#   tools/sanitize.sh --all    everything (about 7 minutes here instead of 4)
# Leak checking is off here: Mesa's llvmpipe keeps allocations to process exit; the fuzzers check leaks.
set -euo pipefail
cd "$(dirname "$0")/.."
all=0
[[ "${1:-}" == "--all" ]] && all=1
if ! command -v clang++-15 > /dev/null; then
  SUDO=""
  [[ $(id -u) -ne 0 ]] && SUDO="sudo"
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends clang-15 libfuzzer-15-dev
fi
CC=clang-15 CXX=clang++-15 cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMRGI_FUZZ=ON \
  -DMRGI_BUILD_TESTS=ON -DMRGI_BUILD_BENCHMARKS=OFF > /dev/null
cmake --build build-fuzz
# The process settings mrgi starts itself again with: with them set, it does not.
source tools/process-env.sh
export ASAN_OPTIONS="detect_leaks=0:abort_on_error=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
[[ -x /usr/bin/llvm-symbolizer ]] && export ASAN_SYMBOLIZER_PATH=/usr/bin/llvm-symbolizer
# Skipped by default: GL-only tests (their work is Mesa's; the CLI tests still drive every GL path of ours
# under ASan) and the numerical tests of a minute or more each under ASan (sweeps, path tracing, HDR maps,
# fusing or tracking whole recordings against rooms, 1-3 minutes each: the RoomModel tests, frame-to-model
# alignment on one session and the smaller Tracking tests run the same fusion and alignment under ASan; the
# prepare worker's replay and the bench report's layout, 30-60 s each, whose code the other Cli tests drive;
# odometry's parity with Open3D and the returning marker,
# 10-20 s each, whose code the smaller Odometry and Tracking tests run; the objects' shadow of a room against
# the path tracer, whose C++ the other ObjectShadow tests run; the sweeps over every receiver of the objects' shadow
# footprint, every normal of a light split and the power of every median cut, 10-25 s each, whose code every replay
# with an object, the fisheye Cli tests and the other MedianCut tests run).
exclude="^GL[./]|^ShadowFootprint\.EveryReceiver|^LightSplit\.EveryNormal|^MedianCut\.TotalPower|^AllTechniques/|Window|^Lpv\.DirectionalLobe|^Cli\.InsertSnaps|^Cli\.SynthPathTraces|^Cli\.ReferencePathTraces|^MedianCut\.Irradiance|^LightSplit\.Lights|^Cli\.ReplayEstimatesLightsFromTheSessionFisheye|^Cli\.Bench|^BenchRun\.|^Cli\.RoomFuses|^Cli\.ReplayBuildsTheRoom|^Tracking\.TheDefaultRoom|^Tracking\.ALookAround|^Tracking\.ARoomFusedAsTheFramesCome|^Tracking\.AnOptimisedTrajectoryFuses|^Cli\.ABareRecordingIsLitFromItsRoom|^Cli\.AnObjectInsertedIntoARecordingWithoutAMarker|^Cli\.ABareOniRecordingIsRoomed|^Cli\.ReplayPreparesTheNextFrame|^Cli\.TheBenchReportReads|^Odometry\.ParityWithOpen3Ds|^Tracking\.TheReturningMarker|^ObjectShadow\.UnderARoom"
if [[ $all -eq 1 ]]; then
  ctest --test-dir build-fuzz -j2 --output-on-failure --timeout 900 -E "Window"
else
  ctest --test-dir build-fuzz -j2 --output-on-failure --timeout 900 -E "$exclude"
fi
