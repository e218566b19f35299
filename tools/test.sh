#!/usr/bin/env bash
# README command 2: build (if needed) and run the whole test suite. Needs ../shared/data beside the repo.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/build.sh
# The process settings mrgi starts itself again with, set here once: the tests' own processes run with them, and the
# mrgi a test starts does not start again.
source tools/process-env.sh
ctest --test-dir build -j2 --output-on-failure --timeout 600
