#include "runtime/threads.h"

#include <unistd.h>

#include <cstdlib>

namespace mrgi::runtime {

void shareCoresWithGl(char** argv) {
  if (std::getenv("OMP_WAIT_POLICY") || std::getenv("OMP_NUM_THREADS")) return;
  if (setenv("OMP_WAIT_POLICY", "PASSIVE", 1) != 0) return;
  execv("/proc/self/exe", argv);  // only returns when it failed
}

}  // namespace mrgi::runtime
