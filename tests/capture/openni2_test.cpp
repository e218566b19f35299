// OpenNI2: no device and bad .oni files are reported as one-line errors, never crashes. (No .oni sample
// exists in ../shared/data, so playback of a real recording is not tested here.)
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "capture/error.h"
#include "capture/frame_source.h"

using namespace mrgi::capture;

namespace {
std::string errorOf(const std::string& uri) {
  try {
    open(uri);
  } catch (const CaptureError& e) {
    return e.what();
  }
  return "no error";
}
}  // namespace

TEST(OpenNI2, NoDeviceIsReported) {
  const std::string msg = errorOf("openni2://");
  // CI machines have no sensor; on a machine with one this test is meaningless, so accept success too.
  if (msg != "no error") {
    EXPECT_EQ(msg, "openni2://: no depth sensor connected");
  }
  EXPECT_NE(errorOf("openni2://usb/no-such-device").find("openni2://usb/no-such-device: cannot open device"),
            std::string::npos);
}

TEST(OpenNI2, MissingAndCorruptOniFiles) {
  EXPECT_EQ(errorOf("/nonexistent/take.oni"), "/nonexistent/take.oni: .oni file does not exist");
  const auto path = std::filesystem::temp_directory_path() / "mrgi_corrupt.oni";
  std::ofstream(path) << "definitely not an ONI recording";
  const std::string msg = errorOf(path.string());
  EXPECT_EQ(msg.rfind(path.string() + ": cannot open .oni file", 0), 0u) << msg;
  EXPECT_EQ(msg.find_first_of("\n\t"), std::string::npos) << msg;
  std::filesystem::remove(path);
}
