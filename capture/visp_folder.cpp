#include "capture/visp_folder.h"

#include <cstdio>
#include <filesystem>

#include "capture/checks.h"
#include "capture/error.h"
#include "capture/image_io.h"
#include "capture/json_io.h"
#include "capture/npz.h"

namespace fs = std::filesystem;

namespace mrgi::capture {

VispFolder::VispFolder(const std::string& directory) : directory_(directory) {
  const std::string camFile = (fs::path(directory) / "cam.json").string();
  const nlohmann::json cam = readJsonFile(camFile);
  intrinsics_ = {jsonInt(cam, "w", camFile),     jsonInt(cam, "h", camFile),     jsonNumber(cam, "px", camFile),
                 jsonNumber(cam, "py", camFile), jsonNumber(cam, "u0", camFile), jsonNumber(cam, "v0", camFile)};
  if (!intrinsics_.valid()) throw CaptureError(camFile, "intrinsics out of range");
  depthScale_ = jsonNumberOr(cam, "depthScale", 0.001, camFile);
  checkNumber(depthScale_, 1e-6, 1.0, camFile, "depthScale");
}

double VispFolder::tagSize() const {
  const std::string tagFile = (fs::path(directory_) / "apriltag_data.json").string();
  const nlohmann::json tags = readJsonFile(tagFile);
  const double size = jsonNumber(tags, "tag_size", tagFile);
  checkNumber(size, kMinTagSizeM, kMaxTagSizeM, tagFile, "tag_size");
  return size;
}

std::optional<Frame> VispFolder::frame(int i, double fps) const {
  char name[64];
  std::snprintf(name, sizeof name, "color_image_%04d.png", i);
  const fs::path colourPath = fs::path(directory_) / name;
  if (!fs::exists(colourPath)) return std::nullopt;
  std::snprintf(name, sizeof name, "depth_image_%04d.npz", i);
  const std::string depthPath = (fs::path(directory_) / name).string();
  const cv::Mat raw = readNpzArray(depthPath, "data.npy");
  const Intrinsics& k = intrinsics_;
  if (raw.type() != CV_16UC1 || raw.cols != k.width || raw.rows != k.height)
    throw CaptureError(
        depthPath, "expected a " + std::to_string(k.width) + "x" + std::to_string(k.height) + " uint16 depth array");
  Frame f;
  f.index = i;
  f.timestamp = i / fps;
  RgbdFrame rgbd;
  rgbd.colour = readColour(colourPath.string());
  if (rgbd.colour.cols != k.width || rgbd.colour.rows != k.height)
    throw CaptureError(colourPath.string(), "not the size cam.json gives");
  raw.convertTo(rgbd.depth, CV_32F, depthScale_);
  rgbd.colourIntrinsics = rgbd.depthIntrinsics = k;
  f.rgbd = rgbd;
  return f;
}

}  // namespace mrgi::capture
