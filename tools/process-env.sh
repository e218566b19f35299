# Sourced by tools/test.sh and tools/sanitize.sh: exports the process settings mrgi starts itself again with when
# the environment lacks them (runtime/threads.h, kOmpWaitPolicy and kGlibcTunables), so the tests' own processes
# run with them and the mrgi each test runs starts once (a second start costs about 0.3 s here, 0.6 s under ASan).
# ctest sets OMP_WAIT_POLICY for every test as well (tests/CMakeLists.txt). A variable the caller set stays.
threads_h="$(dirname "${BASH_SOURCE[0]}")/../runtime/threads.h"
# Each constant's string literals (it may span lines), joined.
constant() { awk -v name="$1 =" 'index($0, name) { f = 1 } f { printf "%s", $0 } f && /;/ { exit }' "$threads_h" |
  grep -o '"[^"]*"' | tr -d '"\n'; }
export OMP_WAIT_POLICY="${OMP_WAIT_POLICY:-$(constant kOmpWaitPolicy)}"
export GLIBC_TUNABLES="${GLIBC_TUNABLES:-$(constant kGlibcTunables)}"
if [[ -z "$OMP_WAIT_POLICY" || -z "$GLIBC_TUNABLES" ]]; then
  echo "tools/process-env.sh: could not read the process settings from $threads_h" >&2
  return 1 2> /dev/null || exit 1
fi
unset threads_h
unset -f constant
