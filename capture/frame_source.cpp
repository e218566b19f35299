#include "capture/frame_source.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "capture/error.h"
#include "capture/open3d_folder.h"
#include "capture/openni2_source.h"
#include "capture/session.h"
#include "capture/tum.h"
#include "capture/v4l2_source.h"

namespace fs = std::filesystem;

namespace mrgi::capture {

double medianRate(const std::vector<double>& timestamps) {
  std::vector<double> dt;
  for (size_t i = 1; i < timestamps.size(); ++i)
    if (timestamps[i] > timestamps[i - 1]) dt.push_back(timestamps[i] - timestamps[i - 1]);
  if (dt.empty()) return 0.0;
  std::nth_element(dt.begin(), dt.begin() + dt.size() / 2, dt.end());
  const double rate = 1.0 / dt[dt.size() / 2];
  // Timestamps 1e-300 or 1e308 apart are no frame rate: unknown rather than a rate nothing can encode.
  return std::isfinite(rate) && rate >= kMinFrameRate && rate <= kMaxFrameRate ? rate : 0.0;
}

Intrinsics folderIntrinsics(const std::string& folder, const OpenOptions& options,
                            const std::optional<Intrinsics>& fromFolder, const Intrinsics& fallback, int width,
                            int height, std::string& note) {
  note.clear();
  if (options.intrinsics) {
    const auto& v = *options.intrinsics;
    const Intrinsics k{width, height, v[0], v[1], v[2], v[3]};
    if (!k.valid() || !(k.cx >= 0 && k.cx <= width && k.cy >= 0 && k.cy <= height))
      throw CaptureError(folder,
                         "--intrinsics fx,fy,cx,cy must be positive focal lengths and a principal point "
                         "inside the " +
                             std::to_string(width) + "x" + std::to_string(height) + " image");
    return k;
  }
  if (fromFolder) return *fromFolder;
  Intrinsics k = fallback;
  k.width = width, k.height = height;
  note = folder + ": no calibration beside the frames; intrinsics fall back to fx " + formatNumber(k.fx) + ", fy " +
         formatNumber(k.fy) + ", cx " + formatNumber(k.cx) + ", cy " + formatNumber(k.cy) +
         " (give the camera's with --intrinsics fx,fy,cx,cy or a camera_intrinsic.json beside the frames)";
  return k;
}

double folderDepthUnits(const std::string& folder, const OpenOptions& options, double formatDefault) {
  if (options.depthUnitsPerMetre == 0) return formatDefault;
  if (!(std::isfinite(options.depthUnitsPerMetre) && options.depthUnitsPerMetre > 0))
    throw CaptureError(folder, "--depth-scale must be a positive number of depth units per metre");
  return options.depthUnitsPerMetre;
}

std::unique_ptr<FrameSource> open(const std::string& uri, const OpenOptions& options) {
  if (uri.rfind("openni2://", 0) == 0) return std::make_unique<OpenNI2Source>(uri.substr(10), options);
  if (uri.rfind("v4l2://", 0) == 0) return std::make_unique<V4l2Source>(uri.substr(7), options);
  std::error_code ec;
  const fs::path p(uri);
  if (uri.size() > 4 && uri.compare(uri.size() - 4, 4, ".oni") == 0) {
    if (!fs::is_regular_file(p, ec)) throw CaptureError(uri, ".oni file does not exist");
    return std::make_unique<OpenNI2Source>(uri, options);
  }
  if (!fs::exists(p, ec)) throw CaptureError(uri, "does not exist");
  if (fs::is_directory(p, ec)) {
    if (fs::exists(p / "manifest.json", ec) || fs::exists(p / "frames.jsonl", ec))
      return std::make_unique<SessionSource>(uri);
    if (fs::exists(p / "rgb.txt", ec) && fs::exists(p / "depth.txt", ec))
      return std::make_unique<TumSource>(uri, options);
    if (isOpen3dFolder(uri)) return std::make_unique<Open3dFolderSource>(uri, options);
    if (fs::exists(p / "color_image_0000.png", ec) && fs::exists(p / "depth_image_0000.npz", ec))
      throw CaptureError(
          uri, "a ViSP RGB-D sequence: convert it into a session with mrgi import-visp " + uri + " --out SESSION");
    throw CaptureError(uri,
                       "neither an mrgi session (manifest.json), a TUM RGB-D sequence (rgb.txt, depth.txt) nor an "
                       "Open3D RGB-D folder (color/, depth/)");
  }
  throw CaptureError(uri, "not a session directory, TUM directory, .oni file or device URI");
}

}  // namespace mrgi::capture
