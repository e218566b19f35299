// Fisheye calibrations (ROS camera_calibration YAML).
#include "capture/v4l2_source.h"
#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = mrgi::fuzz::scratchFile(data, size, ".yaml");
  mrgi::fuzz::expectInputErrorOnly([&] { mrgi::capture::readFisheyeCalibration(path); });
  return 0;
}
