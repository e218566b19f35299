// TUM RGB-D lists (rgb.txt, depth.txt, groundtruth.txt).
#include "capture/tum.h"
#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = mrgi::fuzz::scratchFile(data, size, ".txt");
  mrgi::fuzz::expectInputErrorOnly([&] { mrgi::capture::readTumList(path); });
  return 0;
}
