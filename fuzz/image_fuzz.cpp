// Frame images as the readers get them: colour (8-bit), depth (16-bit or float) and fisheye (any, HDR
// included). The first byte picks the reader; the format comes from the bytes (PNG by libpng, JPEG by
// libjpeg, EXR by OpenEXR, Radiance HDR by our decoder, BMP/PNM/TIFF by OpenCV, anything else refused).
#include "capture/image_io.h"
#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const std::string path = mrgi::fuzz::scratchFile(data + 1, size - 1, ".img");
  mrgi::fuzz::expectInputErrorOnly([&] {
    switch (data[0] % 3) {
      case 0:
        mrgi::capture::readColour(path);
        break;
      case 1:
        mrgi::capture::readDepth(path, 0.001);
        break;
      default:
        mrgi::capture::readAny(path);
        break;
    }
  });
  return 0;
}
