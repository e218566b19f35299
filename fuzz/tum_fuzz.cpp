// Recorded folders' text files: TUM RGB-D lists (rgb.txt, depth.txt, groundtruth.txt) and Open3D's
// trajectory.log and camera intrinsic JSON, each read by every reader.
#include "capture/open3d_folder.h"
#include "capture/tum.h"
#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = mrgi::fuzz::scratchFile(data, size, ".txt");
  mrgi::fuzz::expectInputErrorOnly([&] { mrgi::capture::readTumList(path); });
  mrgi::fuzz::expectInputErrorOnly([&] { mrgi::capture::readOpen3dTrajectory(path); });
  mrgi::fuzz::expectInputErrorOnly([&] { mrgi::capture::readOpen3dIntrinsics(path); });
  return 0;
}
