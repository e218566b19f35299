# Sourced by tools/test.sh and tools/sanitize.sh: exports the process settings mrgi starts itself again with when
# the environment lacks them (runtime/threads.h, kOmpWaitPolicy and kGlibcTunables), so the tests' own processes
# run with them and the mrgi each test runs starts once (a second start costs about 0.3 s here, 0.6 s under ASan).
# ctest sets OMP_WAIT_POLICY for every test as well (tests/CMakeLists.txt). A variable the caller set stays.
threads_h="$(dirname "${BASH_SOURCE[0]}")/../runtime/threads.h"
export OMP_WAIT_POLICY="${OMP_WAIT_POLICY:-$(sed -n 's/.*kOmpWaitPolicy = "\(.*\)";/\1/p' "$threads_h")}"
export GLIBC_TUNABLES="${GLIBC_TUNABLES:-$(sed -n 's/.*kGlibcTunables = "\(.*\)";/\1/p' "$threads_h")}"
unset threads_h
