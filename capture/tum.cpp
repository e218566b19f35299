#include "capture/tum.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/core/quaternion.hpp>
#include <sstream>

#include "capture/checks.h"
#include "capture/error.h"
#include "capture/image_io.h"
#include "capture/open3d_folder.h"

namespace fs = std::filesystem;

namespace mrgi::capture {

std::vector<TumEntry> readTumList(const std::string& path) {
  std::istringstream in(readFileBounded(path, kMaxTextFileBytes, "TUM list"));
  std::vector<TumEntry> out;
  std::string line;
  int lineNo = 0;
  while (std::getline(in, line)) {
    ++lineNo;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream ls(line);
    TumEntry e{};
    std::string rest;
    if (!(ls >> e.t) || !std::isfinite(e.t)) throw CaptureError(path + ":" + std::to_string(lineNo), "bad timestamp");
    std::getline(ls, rest);
    const auto b = rest.find_first_not_of(" \t"), en = rest.find_last_not_of(" \t\r");
    if (b == std::string::npos)
      throw CaptureError(path + ":" + std::to_string(lineNo), "missing value after timestamp");
    e.value = rest.substr(b, en - b + 1);
    e.line = lineNo;
    if (!out.empty() && !(e.t > out.back().t))
      throw CaptureError(path + ":" + std::to_string(lineNo), "timestamp " + formatNumber(e.t) + " does not increase");
    out.push_back(std::move(e));
  }
  return out;
}

std::vector<std::pair<size_t, size_t>> associateTimestamps(const std::vector<double>& a, const std::vector<double>& b,
                                                           double maxGap) {
  // All candidate pairs within maxGap, best first; greedy one-to-one matching (as associate.py does).
  std::vector<std::tuple<double, size_t, size_t>> candidates;
  for (size_t i = 0; i < a.size(); ++i) {
    auto lo = std::lower_bound(b.begin(), b.end(), a[i] - maxGap);
    for (auto it = lo; it != b.end() && *it <= a[i] + maxGap; ++it)
      candidates.emplace_back(std::abs(*it - a[i]), i, static_cast<size_t>(it - b.begin()));
  }
  std::sort(candidates.begin(), candidates.end());
  std::vector<char> usedA(a.size(), 0), usedB(b.size(), 0);
  std::vector<std::pair<size_t, size_t>> pairs;
  for (const auto& [d, i, j] : candidates) {
    if (usedA[i] || usedB[j]) continue;
    usedA[i] = usedB[j] = 1;
    pairs.emplace_back(i, j);
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

Intrinsics tumIntrinsics(const std::string& name, int width, int height) {
  Intrinsics k{width, height, 525.0, 525.0, 319.5, 239.5};
  if (name.find("freiburg1") != std::string::npos) k = {width, height, 517.3, 516.5, 318.6, 255.3};
  if (name.find("freiburg2") != std::string::npos) k = {width, height, 520.9, 521.0, 325.1, 249.7};
  if (name.find("freiburg3") != std::string::npos) k = {width, height, 535.4, 539.2, 320.1, 247.6};
  return k;
}

TumSource::TumSource(const std::string& directory, const OpenOptions& options) : dir_(directory) {
  quietOpenCv();
  const fs::path dir(directory);
  // Each image list names one file per line, every one of them present.
  auto imageList = [&](const char* name) {
    const std::string list = (dir / name).string();
    auto entries = readTumList(list);
    if (entries.empty()) throw CaptureError(list, "lists no frames");
    for (const TumEntry& e : entries) {
      const std::string where = list + ":" + std::to_string(e.line);
      if (e.value.find_first_of(" \t") != std::string::npos)
        throw CaptureError(where, "expected one image path after the timestamp, not '" + excerpt(e.value, 60) + "'");
      std::error_code ec;
      if (!fs::is_regular_file(dir / e.value, ec))
        throw CaptureError(where, "names " + excerpt(e.value, 120) + ", which is missing");
    }
    return entries;
  };
  const auto rgb = imageList("rgb.txt");
  const auto depth = imageList("depth.txt");
  std::vector<double> tr, td;
  for (const auto& e : rgb) tr.push_back(e.t);
  for (const auto& e : depth) td.push_back(e.t);
  const auto pairs = associateTimestamps(tr, td, kTumMaxAssociationGap);
  if (pairs.empty())
    throw CaptureError((dir / "depth.txt").string(), "no depth frame lies within 20 ms of a colour frame");

  std::vector<TumEntry> gt;
  std::vector<double> tg;
  const fs::path gtPath = dir / "groundtruth.txt";
  if (fs::exists(gtPath)) {
    gt = readTumList(gtPath.string());
    for (const auto& e : gt) tg.push_back(e.t);
  }
  for (const auto& [i, j] : pairs) {
    Item it{tr[i], (dir / rgb[i].value).string(), (dir / depth[j].value).string(), std::nullopt};
    if (!gt.empty()) {
      auto lo = std::lower_bound(tg.begin(), tg.end(), tr[i]);
      size_t best = lo == tg.end() ? tg.size() - 1 : static_cast<size_t>(lo - tg.begin());
      if (best > 0 && std::abs(tg[best - 1] - tr[i]) < std::abs(tg[best] - tr[i])) --best;
      if (std::abs(tg[best] - tr[i]) <= kTumMaxAssociationGap) {
        std::istringstream ps(gt[best].value);
        double v[7];
        for (double& x : v)
          if (!(ps >> x) || !std::isfinite(x))
            throw CaptureError(gtPath.string() + ":" + std::to_string(gt[best].line),
                               "a pose line needs 7 finite numbers, not '" + excerpt(gt[best].value, 80) + "'");
        const cv::Quatd q(v[6], v[3], v[4], v[5]);  // TUM order qx qy qz qw
        if (!(q.norm() > 0.5))
          throw CaptureError(gtPath.string() + ":" + std::to_string(gt[best].line),
                             "the pose's quaternion is not of unit length");
        it.pose = makePose(q.normalize().toRotMat3x3(), cv::Vec3d(v[0], v[1], v[2]));
      }
    }
    items_.push_back(std::move(it));
  }
  // Resolution from the first colour image; every later frame must match it.
  const cv::Mat first = readColour(items_.front().colour);
  info_.uri = directory;
  info_.kind = "tum";
  info_.frameCount = static_cast<int64_t>(items_.size());
  const std::string name = fs::absolute(dir).lexically_normal().string();
  std::optional<Intrinsics> known;
  std::error_code ec;
  for (const char* file : {"camera_intrinsic.json", "camera.json"})
    if (fs::exists(dir / file, ec)) {
      known = readFolderIntrinsics((dir / file).string(), first.cols, first.rows);
      break;
    }
  if (!known && name.find("freiburg") != std::string::npos) known = tumIntrinsics(name, first.cols, first.rows);
  info_.colourIntrinsics = folderIntrinsics(directory, options, known, tumIntrinsics(name, first.cols, first.rows),
                                            first.cols, first.rows, info_.calibrationNote);
  unitsPerMetre_ = folderDepthUnits(directory, options, kTumDepthUnitsPerMetre);
  info_.depthIntrinsics = info_.colourIntrinsics;
  info_.hasRgbd = true;
  info_.hasGroundTruth = !gt.empty();
  std::vector<double> ts;
  for (const Item& it : items_) ts.push_back(it.t);
  info_.fps = medianRate(ts);
}

std::optional<Frame> TumSource::next() {
  if (cursor_ >= items_.size()) return std::nullopt;
  const Item& it = items_[cursor_];
  Frame f;
  f.index = static_cast<int64_t>(cursor_++);
  f.timestamp = it.t;
  f.groundTruthT_world_camera = it.pose;
  f.rgbd = readFolderFrame(it.colour, it.depth, unitsPerMetre_, info_.colourIntrinsics, "the sequence's first frame");
  return f;
}

}  // namespace mrgi::capture
