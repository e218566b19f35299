#include "capture/open3d_folder.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <sstream>

#include "capture/checks.h"
#include "capture/error.h"
#include "capture/image_io.h"
#include "capture/json_io.h"

namespace fs = std::filesystem;

namespace mrgi::capture {

namespace {

/// The colour folder of an Open3D RGB-D folder: color/, else image/ (the reconstruction system's two names).
std::optional<fs::path> colourFolder(const fs::path& dir) {
  std::error_code ec;
  for (const char* name : {"color", "image"})
    if (fs::is_directory(dir / name, ec)) return dir / name;
  return std::nullopt;
}

/// The image files of a folder, sorted by name.
std::vector<fs::path> images(const fs::path& dir) {
  std::vector<fs::path> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    std::string ext = e.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    if (ext == ".png" || ext == ".jpg" || ext == ".jpeg") out.push_back(e.path());
  }
  if (ec) throw CaptureError(dir.string(), "cannot list the folder (" + ec.message() + ")");
  std::sort(out.begin(), out.end());
  return out;
}

/// How far apart two posed depth images put the same surface under intrinsics `k`: the median depth
/// difference of every 16th pixel of `da` carried into `db` through the poses (metres; 1e300 when none lands).
double posedDepthDisagreement(const cv::Mat& da, const Pose& T_world_a, const cv::Mat& db, const Pose& T_world_b,
                              const Intrinsics& k) {
  const Pose T_b_a = inversePose(T_world_b) * T_world_a;
  std::vector<double> e;
  for (int y = 0; y < da.rows; y += 4)
    for (int x = (y / 4) % 4; x < da.cols; x += 4) {
      const float z = da.at<float>(y, x);
      if (!(z > 0)) continue;
      const cv::Vec3d q = transformPoint(T_b_a, cv::Vec3d((x - k.cx) * z / k.fx, (y - k.cy) * z / k.fy, z));
      if (!(q[2] > 0)) continue;
      const int u = static_cast<int>(std::lround(k.fx * q[0] / q[2] + k.cx)),
                v = static_cast<int>(std::lround(k.fy * q[1] / q[2] + k.cy));
      if (u < 0 || v < 0 || u >= db.cols || v >= db.rows) continue;
      const float zb = db.at<float>(v, u);
      if (zb > 0) e.push_back(std::abs(zb - q[2]));
    }
  if (e.empty()) return 1e300;
  std::nth_element(e.begin(), e.begin() + static_cast<std::ptrdiff_t>(e.size() / 2), e.end());
  return e[e.size() / 2];
}

}  // namespace

bool isOpen3dFolder(const std::string& directory) {
  std::error_code ec;
  const fs::path dir(directory);
  return fs::is_directory(dir / "depth", ec) && colourFolder(dir).has_value();
}

Intrinsics readOpen3dIntrinsics(const std::string& path) {
  const nlohmann::json j = parseJson(readFileBounded(path, kMaxTextFileBytes, "camera intrinsics"), path);
  if (!j.is_object()) throw CaptureError(path, "expected a JSON object with width, height and intrinsic_matrix");
  Intrinsics k;
  k.width = jsonInt(j, "width", path), k.height = jsonInt(j, "height", path);
  const nlohmann::json& m = jsonKey(j, "intrinsic_matrix", path);
  if (!m.is_array() || m.size() != 9)
    throw CaptureError(path, "key 'intrinsic_matrix' must hold 9 numbers (a 3x3 matrix, column-major)");
  double v[9];
  for (size_t i = 0; i < 9; ++i) {
    if (!m[i].is_number() || !std::isfinite(m[i].get<double>()))
      throw CaptureError(path, "key 'intrinsic_matrix' must hold finite numbers");
    v[i] = m[i].get<double>();
  }
  k.fx = v[0], k.fy = v[4], k.cx = v[6], k.cy = v[7];
  if (k.width <= 0 || k.height <= 0 || k.width > 1 << 15 || k.height > 1 << 15 || !k.valid())
    throw CaptureError(path, "needs a positive width and height and positive focal lengths");
  return k;
}

Intrinsics readFolderIntrinsics(const std::string& path, int width, int height) {
  const Intrinsics k = readOpen3dIntrinsics(path);
  if (k.width != width || k.height != height)
    throw CaptureError(path, "is for " + std::to_string(k.width) + "x" + std::to_string(k.height) +
                                 " images, the frames are " + std::to_string(width) + "x" + std::to_string(height));
  return k;
}

RgbdFrame readFolderFrame(const std::string& colour, const std::string& depth, double unitsPerMetre,
                          const Intrinsics& k, const std::string& first) {
  RgbdFrame r;
  r.colour = readColour(colour);
  r.depth = readDepth(depth, 1.0 / unitsPerMetre);
  if (r.colour.cols != k.width || r.colour.rows != k.height)
    throw CaptureError(colour, "image size differs from " + first);
  if (r.depth.cols != k.width || r.depth.rows != k.height)
    throw CaptureError(depth, "depth size differs from the colour image");
  r.colourIntrinsics = r.depthIntrinsics = k;
  r.depthRegistered = true;  // TUM's Kinect driver and Open3D's RGBDImage pair depth with colour pixel for pixel
  return r;
}

std::vector<std::pair<int64_t, Pose>> readOpen3dTrajectory(const std::string& path) {
  std::istringstream in(readFileBounded(path, kMaxTextFileBytes, "trajectory"));
  std::vector<std::pair<int64_t, Pose>> out;
  std::string line;
  int lineNo = 0;
  auto nextLine = [&]() -> bool {
    while (std::getline(in, line)) {
      ++lineNo;
      if (line.find_first_not_of(" \t\r") != std::string::npos) return true;
    }
    return false;
  };
  while (nextLine()) {
    const std::string where = path + ":" + std::to_string(lineNo);
    std::istringstream head(line);
    double id = 0;
    if (!(head >> id) || !std::isfinite(id) || id < 0 || id > 1e9 || id != std::floor(id))
      throw CaptureError(where,
                         "a pose block starts with its frame id (a whole number), not '" + excerpt(line, 60) + "'");
    cv::Matx44d T;
    for (int r = 0; r < 4; ++r) {
      if (!nextLine()) throw CaptureError(where, "the pose block ends before its 4 matrix rows");
      std::istringstream row(line);
      for (int c = 0; c < 4; ++c)
        if (!(row >> T(r, c)) || !std::isfinite(T(r, c)))
          throw CaptureError(path + ":" + std::to_string(lineNo), "a matrix row needs 4 finite numbers");
    }
    const cv::Matx33d R(T(0, 0), T(0, 1), T(0, 2), T(1, 0), T(1, 1), T(1, 2), T(2, 0), T(2, 1), T(2, 2));
    if (cv::norm(R.t() * R - cv::Matx33d::eye()) > 1e-3 ||
        std::abs(T(3, 0)) + std::abs(T(3, 1)) + std::abs(T(3, 2)) > 1e-6 || std::abs(T(3, 3) - 1) > 1e-6)
      throw CaptureError(where, "the pose is not a rigid transform (rotation and translation)");
    out.emplace_back(static_cast<int64_t>(id), makePose(R, cv::Vec3d(T(0, 3), T(1, 3), T(2, 3))));
  }
  return out;
}

Open3dFolderSource::Open3dFolderSource(const std::string& directory, const OpenOptions& options) {
  quietOpenCv();
  const fs::path dir(directory);
  const auto colourDir = colourFolder(dir);
  if (!colourDir) throw CaptureError(directory, "an Open3D RGB-D folder needs color/ (or image/) beside depth/");
  const auto colours = images(*colourDir), depths = images(dir / "depth");
  if (colours.empty()) throw CaptureError(colourDir->string(), "holds no .png or .jpg images");
  if (depths.size() != colours.size())
    throw CaptureError(directory, colourDir->filename().string() + "/ holds " + std::to_string(colours.size()) +
                                      " images and depth/ " + std::to_string(depths.size()) +
                                      ": they are paired in name order and must be as many");
  for (size_t i = 0; i < colours.size(); ++i) items_.push_back({colours[i].string(), depths[i].string(), std::nullopt});

  std::error_code ec;
  const fs::path trajectory = dir / "trajectory.log";
  if (fs::exists(trajectory, ec)) {
    for (const auto& [id, pose] : readOpen3dTrajectory(trajectory.string())) {
      if (id >= static_cast<int64_t>(items_.size()))
        throw CaptureError(trajectory.string(), "a pose for frame " + std::to_string(id) + ", but the folder holds " +
                                                    std::to_string(items_.size()) + " frames");
      items_[static_cast<size_t>(id)].pose = pose;
    }
    info_.hasGroundTruth = std::any_of(items_.begin(), items_.end(), [](const Item& i) { return i.pose.has_value(); });
  }
  unitsPerMetre_ = folderDepthUnits(directory, options, kOpen3dDepthUnitsPerMetre);

  const cv::Mat first = readColour(items_.front().colour);
  // The calibration files beside the frames (Open3D's reconstruction system names its camera_intrinsic.json;
  // its test folders carry camera.json and camera_primesense.json side by side, which disagree).
  std::vector<std::pair<std::string, Intrinsics>> candidates;
  for (const char* name : {"camera_intrinsic.json", "camera.json", "camera_primesense.json"})
    if (fs::exists(dir / name, ec)) {
      const Intrinsics k = readFolderIntrinsics((dir / name).string(), first.cols, first.rows);
      if (std::none_of(candidates.begin(), candidates.end(), [&](const auto& c) { return c.second == k; }))
        candidates.emplace_back(name, k);
    }
  std::optional<Intrinsics> fromFile;
  if (!candidates.empty()) fromFile = candidates.front().second;
  if (candidates.size() > 1 && !options.intrinsics) {
    // Several that disagree: the one under which the first two posed frames' depths agree through their
    // poses (the trajectory's), else the first.
    std::vector<const Item*> posed;
    for (const Item& it : items_)
      if (it.pose && posed.size() < 2) posed.push_back(&it);
    std::string chosen = candidates.front().first, why;
    if (posed.size() == 2) {
      const Item &a = *posed[0], &b = *posed[1];
      const cv::Mat da = readDepth(a.depth, 1.0 / unitsPerMetre_), db = readDepth(b.depth, 1.0 / unitsPerMetre_);
      double best = 1e300;
      for (const auto& [name, k] : candidates)
        if (const double e = posedDepthDisagreement(da, *a.pose, db, *b.pose, k); e < best)
          best = e, fromFile = k, chosen = name;
      why = ", its depths agreeing best through trajectory.log's poses";
    }
    info_.calibrationNote = directory + ": " + std::to_string(candidates.size()) + " calibration files disagree; " +
                            chosen + " takes" + why + " (give --intrinsics fx,fy,cx,cy to choose)";
  }
  // Open3D's own default camera (PrimeSense), scaled to the frames' size.
  const Intrinsics primeSense{first.cols,
                              first.rows,
                              525.0 * first.cols / 640.0,
                              525.0 * first.rows / 480.0,
                              (first.cols - 1) / 2.0,
                              (first.rows - 1) / 2.0};
  info_.uri = directory;
  info_.kind = "open3d";
  info_.frameCount = static_cast<int64_t>(items_.size());
  std::string fallbackNote;
  info_.colourIntrinsics =
      folderIntrinsics(directory, options, fromFile, primeSense, first.cols, first.rows, fallbackNote);
  if (!fallbackNote.empty()) info_.calibrationNote = fallbackNote;
  info_.depthIntrinsics = info_.colourIntrinsics;
  info_.hasRgbd = true;
  info_.fps = kOpen3dFrameRate;
}

std::optional<Frame> Open3dFolderSource::next() {
  if (cursor_ >= items_.size()) return std::nullopt;
  const Item& it = items_[cursor_];
  Frame f;
  f.index = static_cast<int64_t>(cursor_++);
  f.timestamp = static_cast<double>(f.index) / kOpen3dFrameRate;
  f.groundTruthT_world_camera = it.pose;
  f.rgbd = readFolderFrame(it.colour, it.depth, unitsPerMetre_, info_.colourIntrinsics, "the folder's first frame");
  return f;
}

}  // namespace mrgi::capture
