#include "lighting/techniques/kinect_val/real_vals.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <tuple>
#include <unordered_map>

namespace mrgi::lighting {
namespace {

float lum(const cv::Vec3f& c) { return 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2]; }

uint64_t voxelKey(const cv::Vec3f& p, float voxel) {
  auto c = [&](float v) {
    return static_cast<uint64_t>(static_cast<int64_t>(std::floor(v / voxel)) + (1 << 20)) & 0x1fffff;
  };
  return c(p[0]) | (c(p[1]) << 21) | (c(p[2]) << 42);
}

}  // namespace

std::vector<Val> valsFromRgbd(const cv::Mat& positions, const cv::Mat& normals, const cv::Mat& linearColour,
                              const capture::Intrinsics& k, const capture::Pose& T_world_camera, int stride) {
  CV_Assert(positions.type() == CV_32FC3 && normals.type() == CV_32FC3 && linearColour.type() == CV_32FC3);
  std::vector<Val> out;
  const cv::Matx33f R(capture::rotationOf(T_world_camera));
  const cv::Vec3f t(capture::translationOf(T_world_camera));
  stride = std::max(stride, 1);
  for (int y = stride / 2; y < positions.rows; y += stride)
    for (int x = stride / 2; x < positions.cols; x += stride) {
      const cv::Vec3f p = positions.at<cv::Vec3f>(y, x), n = normals.at<cv::Vec3f>(y, x);
      if (!(p[2] > 0.f) || n == cv::Vec3f(0, 0, 0)) continue;
      const cv::Vec3f L = linearColour.at<cv::Vec3f>(y, x);
      // Footprint of the pixel: solid angle cos³α / (fx fy) at range z / cos α, tilted by the surface:
      // a = (z/fx)(z/fy) cos α / cos θ (θ between the normal and the view ray, clamped at 0.1).
      const float range = static_cast<float>(cv::norm(p));
      const float cosV = std::max(-n.dot(p) / range, 0.1f);
      Val v;
      v.area = static_cast<float>((p[2] / k.fx) * (p[2] / k.fy)) * static_cast<float>(stride * stride) *
               (p[2] / range) / cosV;
      v.position = R * p + t;
      v.normal = R * n;
      v.flux = L * (std::numbers::pi_v<float> * v.area);
      out.push_back(v);
    }
  setValWeights(out);
  return out;
}

std::vector<Val> valsFromRoom(const reconstruction::RoomMesh& room, float cell, size_t maxVals,
                              const std::vector<uint32_t>* indicesIn) {
  const std::vector<uint32_t>& indices = indicesIn ? *indicesIn : room.indices;
  // Each vertex's share of the surface: a third of the area of every triangle it belongs to.
  std::vector<float> area(room.positions.size(), 0.f);
  for (size_t t = 0; t + 2 < indices.size(); t += 3) {
    const cv::Vec3f &a = room.positions[indices[t]], &b = room.positions[indices[t + 1]],
                    &c = room.positions[indices[t + 2]];
    const float third = static_cast<float>(cv::norm((b - a).cross(c - a))) / 6.f;
    for (int k = 0; k < 3; ++k) area[indices[t + static_cast<size_t>(k)]] += third;
  }
  std::vector<Val> out;
  for (cell = std::max(cell, 1e-3f);; cell *= 2) {
    struct Sum {
      cv::Vec3d position{0, 0, 0}, normal{0, 0, 0}, flux{0, 0, 0};
      double area = 0;
    };
    std::unordered_map<uint64_t, Sum> cells;
    for (size_t i = 0; i < room.positions.size(); ++i) {
      if (!(area[i] > 0) || (i < room.saturated.size() && room.saturated[i])) continue;
      Sum& s = cells[voxelKey(room.positions[i], cell)];
      const double a = area[i];
      s.position += a * cv::Vec3d(room.positions[i]);
      s.normal += a * cv::Vec3d(room.normals[i]);
      s.flux += (std::numbers::pi_v<float> * a) * cv::Vec3d(room.radiance[i]);
      s.area += a;
    }
    if (cells.size() > maxVals) continue;
    out.clear();
    out.reserve(cells.size());
    for (const auto& [key, s] : cells) {
      const double n = cv::norm(s.normal);
      if (!(n > 0.5 * s.area)) continue;  // the normals cancel
      Val v;
      v.position = cv::Vec3f(s.position / s.area);
      v.normal = cv::Vec3f(s.normal / n);
      v.area = static_cast<float>(s.area);
      v.flux = cv::Vec3f(s.flux);
      out.push_back(v);
    }
    break;
  }
  // A fixed order (the cells' hash order is not).
  std::sort(out.begin(), out.end(), [](const Val& a, const Val& b) {
    return std::tie(a.position[0], a.position[1], a.position[2]) <
           std::tie(b.position[0], b.position[1], b.position[2]);
  });
  setValWeights(out);
  return out;
}

void setValWeights(std::vector<Val>& vals) {
  double sum = 0, area = 0;
  for (const Val& v : vals) sum += lum(v.flux), area += v.area;
  const double n = static_cast<double>(std::max<size_t>(vals.size(), 1));
  const double mean = sum / n, meanArea = area / n;
  for (Val& v : vals) v.weight = static_cast<float>((mean > 0 ? lum(v.flux) / mean : 1.0) * meanArea);
}

void SurfelMap::integrate(const std::vector<Val>& vals, const cv::Mat& depth, const capture::Intrinsics& k,
                          const capture::Pose& T_world_camera) {
  const capture::Pose T_camera_world = capture::inversePose(T_world_camera);
  auto shouldSee = [&](const cv::Vec3f& p) {
    if (depth.empty()) return true;
    const cv::Vec3d c = capture::transformPoint(T_camera_world, cv::Vec3d(p));
    if (!(c[2] > 0)) return false;
    const int u = static_cast<int>(std::lround(k.fx * c[0] / c[2] + k.cx)),
              v = static_cast<int>(std::lround(k.fy * c[1] / c[2] + k.cy));
    if (u < 0 || v < 0 || u >= depth.cols || v >= depth.rows) return false;
    const float z = depth.at<float>(v, u);
    return z > 0.f && z > c[2] - 2.0 * o_.voxel;
  };
  struct Bin {
    cv::Vec3f position{0, 0, 0}, normal{0, 0, 0}, exitance{0, 0, 0};
    float area = 0;
  };
  std::unordered_map<uint64_t, Bin> frame;
  for (const Val& v : vals) {
    if (!(v.area > 0.f)) continue;
    Bin& b = frame[voxelKey(v.position, o_.voxel)];
    b.position += v.area * v.position;
    b.normal += v.area * v.normal;
    b.exitance += v.flux;  // Σ φ; divided by Σ a below
    b.area += v.area;
  }
  for (auto it = map_.begin(); it != map_.end();) {
    if (frame.count(it->first) || !shouldSee(it->second.position)) {
      ++it;
      continue;
    }
    it->second.confidence *= o_.decay;
    it = it->second.confidence < o_.minConfidence ? map_.erase(it) : std::next(it);
  }
  for (const auto& [key, b] : frame) {
    Surfel& s = map_[key];
    const cv::Vec3f pos = b.position / b.area, exitance = b.exitance / b.area;
    cv::Vec3f n = b.normal;
    const float len = static_cast<float>(cv::norm(n));
    n = len > 0.f ? n / len : cv::Vec3f(0, 0, 1);
    const float c = std::min(s.confidence + 1.f, o_.maxConfidence);
    const float a = s.confidence > 0.f ? 1.f / c : 1.f;  // running mean over the last ~maxConfidence frames
    s.position += a * (pos - s.position);
    s.normal += a * (n - s.normal);
    s.exitance += a * (exitance - s.exitance);
    s.area += a * (b.area - s.area);
    s.confidence = c;
  }
}

std::vector<Val> SurfelMap::vals() const {
  std::vector<Val> out;
  out.reserve(map_.size());
  for (const auto& [key, s] : map_) {
    Val v;
    v.position = s.position;
    const float len = static_cast<float>(cv::norm(s.normal));
    v.normal = len > 0.f ? s.normal / len : cv::Vec3f(0, 0, 1);
    v.area = s.area;
    v.flux = s.exitance * s.area;
    out.push_back(v);
  }
  setValWeights(out);
  return out;
}

nlohmann::json RealVals::facts() const {
  nlohmann::json j = {{"real_vals", vals.size()}};
  if (surfels > 0) j["surfels"] = surfels;
  return j;
}

RealValBuilder::RealValBuilder(int stride, bool fusion, const SurfelOptions& surfels) : stride_(stride) {
  if (fusion) surfels_.emplace(surfels);
}

std::shared_ptr<const TechniqueInput> RealValBuilder::fromFrame(const InputFrame& f) {
  // Real surfaces as area lights: the seen radiance of every stride-th filtered pixel, fused over frames when
  // asked for (surfels out of view keep their light).
  auto out = std::make_shared<RealVals>();
  out->vals = valsFromRgbd(f.positions, f.normals, f.radiance, f.intrinsics, f.T_world_camera, stride_);
  if (surfels_) {
    cv::Mat depth;
    cv::extractChannel(f.positions, depth, 2);
    surfels_->integrate(out->vals, depth, f.intrinsics, f.T_world_camera);
    out->vals = surfels_->vals();
    out->surfels = surfels_->size();
  }
  return out;
}

std::shared_ptr<const TechniqueInput> RealValBuilder::fromRoom(const reconstruction::RoomMesh& room,
                                                               const std::vector<uint32_t>& indices) {
  // Every surface the room holds, in view or not.
  auto out = std::make_shared<RealVals>();
  out->vals = valsFromRoom(room, 0.04f, 16384, &indices);
  return out;
}

}  // namespace mrgi::lighting
