// Frame images: colour and depth PNGs (our libpng decoder), other formats through OpenCV.
#include "capture/image_io.h"
#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const std::string path = mrgi::fuzz::scratchFile(data + 1, size - 1, ".png");
  mrgi::fuzz::expectInputErrorOnly([&] {
    if (data[0] & 1)
      mrgi::capture::readDepth(path, 0.001);
    else
      mrgi::capture::readColour(path);
  });
  return 0;
}
