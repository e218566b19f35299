#include "reconstruction/room_model.h"

#include <open3d/core/Tensor.h>
#include <open3d/core/hashmap/HashMap.h>
#include <open3d/geometry/TriangleMesh.h>
#include <open3d/io/TriangleMeshIO.h>
#include <open3d/t/geometry/Image.h>
#include <open3d/t/geometry/TriangleMesh.h>
#include <open3d/t/geometry/VoxelBlockGrid.h>
#include <open3d/utility/Logging.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <unordered_set>

#include "capture/checks.h"
#include "capture/colour.h"
#include "capture/error.h"
#include "capture/image_io.h"
#include "capture/json_io.h"
#include "capture/npz.h"
#include "capture/ply_check.h"
#include "capture/view_factor.h"
#include "reconstruction/mesh_rays.h"
#include "reconstruction/open3d_pose.h"

namespace fs = std::filesystem;
namespace o3d = open3d;

namespace mrgi::reconstruction {

namespace {

constexpr int kBlockResolution = 16;  // voxels per block edge (Open3D's voxel block)
constexpr int kBlockVoxels = kBlockResolution * kBlockResolution * kBlockResolution;
/// Blocks touched by a frame are found from every kSamplingStride-th pixel in each direction.
constexpr int kSamplingStride = 4;
/// The voxel grid's first capacity in blocks; it doubles as the room grows.
constexpr int64_t kFirstCapacity = 1024;

Eigen::Vector3i floorDiv(const Eigen::Vector3i& a, int b) {
  Eigen::Vector3i q;
  for (int k = 0; k < 3; ++k) q[k] = static_cast<int>(std::floor(static_cast<double>(a[k]) / b));
  return q;
}

/// Cells in lexicographic order (x, then y, then z).
bool cellLess(const cv::Vec3i& a, const cv::Vec3i& b) {
  return a[0] != b[0] ? a[0] < b[0] : a[1] != b[1] ? a[1] < b[1] : a[2] < b[2];
}

struct Hash {
  size_t operator()(const Eigen::Vector3i& v) const {
    return (static_cast<size_t>(v[0]) * 73856093u) ^ (static_cast<size_t>(v[1]) * 19349663u) ^
           (static_cast<size_t>(v[2]) * 83492791u);
  }
};

/// Open3D prints its warnings through its own logger; ours is the one-line error.
void quietOpen3d() {
  static const bool once = [] {
    o3d::utility::SetVerbosityLevel(o3d::utility::VerbosityLevel::Error);
    return true;
  }();
  (void)once;
}

}  // namespace

void RoomOptions::validate(const std::string& where) const {
  auto check = [&](bool ok, const std::string& key, const std::string& range) {
    if (!ok) throw capture::InputError(where, key + " must be " + range);
  };
  check(std::isfinite(voxelM) && voxelM >= 0.002 && voxelM <= 0.2, "voxel_m", "in [0.002, 0.2]");
  check(std::isfinite(truncM) && truncM >= 2 * voxelM && truncM <= 1.0, "trunc_m", "at least 2 voxels and at most 1 m");
  check(maxBlocks >= 1 && maxBlocks <= (1 << 20), "max_blocks", "in [1, 1048576]");
  check(std::isfinite(maxDepthM) && maxDepthM > 0.1 && maxDepthM <= 20, "max_depth_m", "in (0.1, 20]");
  check(std::isfinite(outlierM) && outlierM > 0 && outlierM <= 1, "outlier_m", "in (0, 1]");
  check(std::isfinite(outlierFraction) && outlierFraction > 0 && outlierFraction <= 1, "outlier_fraction", "in (0, 1]");
  check(std::isfinite(minOverlap) && minOverlap >= 0 && minOverlap <= 1, "min_overlap", "in [0, 1]");
  check(appearanceStride >= 0 && appearanceStride <= 64, "appearance_stride", "in [0, 64]");
  check(std::isfinite(grazingCos) && grazingCos >= 0 && grazingCos < 1, "grazing_cos", "in [0, 1)");
  check(clipLevel >= 1 && clipLevel <= 256, "clip_level", "in [1, 256]");
  check(appearanceMemory >= 1 && appearanceMemory <= 65535, "appearance_memory", "in [1, 65535]");
}

/// The signed distance lives in Open3D's voxel block grid (t::geometry::VoxelBlockGrid on the CPU): blocks of
/// 16^3 voxels holding a float tsdf (in units of the truncation distance) and a float weight, 8 bytes a voxel.
/// Its voxel (i, j, k) sits at (i, j, k) * voxel in the grid's frame; the grid's frame is the world shifted by
/// half a voxel, so voxel centres lie at (i + 1/2) * voxel in the world and block b spans [16 b, 16 b + 16)
/// voxels. The grid's hash map has a fixed capacity; it is rebuilt twice as large when a frame needs more.
struct RoomModel::Impl {
  explicit Impl(const RoomOptions& o) : voxelM(o.voxelM) { allocate(kFirstCapacity); }
  double voxelM;
  o3d::t::geometry::VoxelBlockGrid grid;
  int64_t capacity = 0;
  /// Each block's buffer index in the grid, kept beside Open3D's hash map for lookups from C++ one voxel at a
  /// time; the tsdf and weight of block b's voxel v are tsdf[index[b] * 16^3 + v], v = x + 16 (y + 16 z).
  std::unordered_map<Eigen::Vector3i, int64_t, Hash> index;
  float* tsdf = nullptr;
  float* weight = nullptr;

  /// A grid for this many blocks. Its first buffer goes to a block of no weight far from any room: Open3D's
  /// marching cubes (0.16) asserts that a neighbour voxel's buffer offset is positive, which fails for the first
  /// voxel of the first buffer.
  void allocate(int64_t blocks) {
    grid = o3d::t::geometry::VoxelBlockGrid({"tsdf", "weight"}, {o3d::core::Float32, o3d::core::Float32}, {{1}, {1}},
                                            static_cast<float>(voxelM), kBlockResolution, blocks + 1);
    capacity = blocks;
    tsdf = grid.GetAttribute("tsdf").GetDataPtr<float>();
    weight = grid.GetAttribute("weight").GetDataPtr<float>();
    if (buffersFor({kSentinel}) != std::vector<int64_t>{0})
      throw std::logic_error("RoomModel: the voxel grid's first buffer went elsewhere");
    clear(0);
  }
  static inline const Eigen::Vector3i kSentinel = Eigen::Vector3i::Constant(-(1 << 24));

  static o3d::core::Tensor keysOf(const std::vector<Eigen::Vector3i>& blocks) {
    o3d::core::Tensor t({static_cast<int64_t>(blocks.size()), 3}, o3d::core::Int32);
    int32_t* p = t.GetDataPtr<int32_t>();
    for (size_t i = 0; i < blocks.size(); ++i)
      for (int k = 0; k < 3; ++k) p[3 * i + k] = blocks[i][k];
    return t;
  }

  /// Adds these blocks (none of them held yet) with zero weight, growing the grid first if it must. Open3D's
  /// integration of `integrated` blocks next would rehash the grid itself if the blocks held and those it is
  /// given could outnumber its capacity (moving every buffer): the grid is made large enough first.
  void add(const std::vector<Eigen::Vector3i>& blocks, size_t integrated) {
    const int64_t needed = static_cast<int64_t>(index.size() + blocks.size() + integrated);
    if (needed > capacity) {
      // A new grid twice as large (or as large as needed), the old blocks copied into it.
      std::vector<Eigen::Vector3i> old;
      std::vector<int64_t> from;
      for (const auto& [b, i] : index) old.push_back(b), from.push_back(i);
      const float* oldTsdf = tsdf;
      const float* oldWeight = weight;
      o3d::t::geometry::VoxelBlockGrid keep = grid;  // holds the old buffers until they are copied
      allocate(std::max(needed, 2 * capacity));
      index.clear();
      const auto to = activate(old);
      for (size_t i = 0; i < old.size(); ++i) {
        std::memcpy(tsdf + to[i] * kBlockVoxels, oldTsdf + from[i] * kBlockVoxels, sizeof(float) * kBlockVoxels);
        std::memcpy(weight + to[i] * kBlockVoxels, oldWeight + from[i] * kBlockVoxels, sizeof(float) * kBlockVoxels);
      }
    }
    if (blocks.empty()) return;
    // Open3D's hash map leaves a new block's values as the buffer held them.
    for (const int64_t i : activate(blocks)) clear(i);
  }

  /// Buffers for these blocks, none of them in the grid yet (through a copy of the grid's hash map, which
  /// shares its storage: it never grows here, the grid being large enough).
  std::vector<int64_t> buffersFor(const std::vector<Eigen::Vector3i>& blocks) {
    o3d::core::HashMap map = grid.GetHashMap();
    o3d::core::Tensor buf, masks;
    map.Activate(keysOf(blocks), buf, masks);
    const int32_t* b = buf.GetDataPtr<int32_t>();
    const bool* m = masks.GetDataPtr<bool>();
    std::vector<int64_t> out(blocks.size());
    for (size_t i = 0; i < blocks.size(); ++i) {
      if (!m[i]) throw std::logic_error("RoomModel: a voxel block was added twice");
      out[i] = b[i];
    }
    return out;
  }

  /// buffersFor, each block entered in `index`.
  std::vector<int64_t> activate(const std::vector<Eigen::Vector3i>& blocks) {
    const auto out = buffersFor(blocks);
    for (size_t i = 0; i < blocks.size(); ++i) index.emplace(blocks[i], out[i]);
    return out;
  }

  /// A buffer's voxels unobserved (tsdf and weight 0).
  void clear(int64_t buffer) {
    std::fill_n(tsdf + buffer * kBlockVoxels, kBlockVoxels, 0.f);
    std::fill_n(weight + buffer * kBlockVoxels, kBlockVoxels, 0.f);
  }

  /// The camera's pose in the grid's frame (camera from grid) for the world's camera pose T_camera_world.
  capture::Pose cameraFromGrid(const capture::Pose& T_camera_world) const {
    capture::Pose T_world_grid = capture::identityPose();
    for (int k = 0; k < 3; ++k) T_world_grid(k, 3) = 0.5 * voxelM;
    return T_camera_world * T_world_grid;
  }

  /// Fused appearance per voxel (key: floor(p / voxel), as the TSDF's voxels): confidence-weighted sum of
  /// accepted observations' radiance, and for clipped ones a lower bound.
  struct Appearance {
    float sum[3] = {0, 0, 0};
    float weight = 0;
    float lower[3] = {0, 0, 0};
    /// Clipped observations next to unclipped pixels (at the sampling stride) in their frame: brighter texture
    /// among darker (a tag's white cells among its black ones), finer than the voxels. Their confidence
    /// (faded with the rest) and largest bound.
    float mixedWeight = 0;
    float mixedLower[3] = {0, 0, 0};
    uint16_t count = 0, clipped = 0;
  };
  std::unordered_map<Eigen::Vector3i, Appearance, Hash> appearance;

  /// RoomOpenings: the cells crossed by rays through 8 x 8 pixel tiles (at 640 pixels across; scaled with the
  /// width) nine tenths of whose pixels hold no depth, and so do the 24 tiles around them, out to kOpeningReachM
  /// past the range. Whole regions, so that the depth lost along objects' edges (a structured-light sensor's
  /// shadow) and in small blobs opens nothing. Each
  /// cell keeps the mean radiance its rays saw (what lies beyond: the sky through a window) and how many of them
  /// were clipped.
  struct OpeningSeen {
    float sum[3] = {0, 0, 0};
    uint32_t rays = 0, clipped = 0;
  };
  std::unordered_map<Eigen::Vector3i, OpeningSeen, Hash> openings;
  static constexpr double kOpeningCellM = 0.1, kOpeningReachM = 4.0;
  static constexpr size_t kMaxOpeningCells = size_t{1} << 22;

  void recordOpenings(const cv::Mat& raw, const cv::Mat& colour, const capture::Intrinsics& K, const capture::Pose& T,
                      double maxDepthM, double exposure, int clipLevel) {
    float lut[256];
    for (int i = 0; i < 256; ++i) lut[i] = static_cast<float>(capture::srgbToLinear(i / 255.f) / exposure);
    const int tile = std::max(2, static_cast<int>(std::lround(K.width / 80.0)));
    const cv::Vec3d origin = capture::translationOf(T);
    const cv::Matx33d R = capture::rotationOf(T);
    const double step = 0.5 * kOpeningCellM;
    const int tilesX = raw.cols / tile, tilesY = raw.rows / tile;
    // Per tile: its pixels with no depth at all, and what they saw. (Depth past the range is a surface seen, not
    // an opening: a far wall is not the sky.)
    struct Tile {
      int empty = 0, clipped = 0;
      float seen[3] = {0, 0, 0};
    };
    std::vector<Tile> tiles(static_cast<size_t>(tilesX * tilesY));
    for (int ty = 0; ty < tilesY; ++ty)
      for (int tx = 0; tx < tilesX; ++tx) {
        Tile& here = tiles[static_cast<size_t>(ty * tilesX + tx)];
        for (int y = ty * tile; y < (ty + 1) * tile; ++y) {
          const float* row = raw.ptr<float>(y);
          const cv::Vec3b* rgb = colour.ptr<cv::Vec3b>(y);
          for (int x = tx * tile; x < (tx + 1) * tile; ++x) {
            if (std::isfinite(row[x]) && row[x] > 0) continue;
            ++here.empty;
            for (int k = 0; k < 3; ++k) here.seen[k] += lut[rgb[x][k]];
            here.clipped += rgb[x][0] >= clipLevel || rgb[x][1] >= clipLevel || rgb[x][2] >= clipLevel;
          }
        }
      }
    const auto open = [&](int tx, int ty) {
      return tx >= 0 && ty >= 0 && tx < tilesX && ty < tilesY &&
             10 * tiles[static_cast<size_t>(ty * tilesX + tx)].empty >= 9 * tile * tile;
    };
    const double reach = maxDepthM + kOpeningReachM;
    for (int ty = 0; ty < tilesY; ++ty)
      for (int tx = 0; tx < tilesX; ++tx) {
        // An opening is a region: the tile and the 24 around it, 40 pixels across at 640 (a sensor's depth drops
        // out in blobs a few tiles across on dark or shiny surfaces, and along edges).
        bool region = true;
        for (int dy = -2; dy <= 2 && region; ++dy)
          for (int dx = -2; dx <= 2 && region; ++dx) region = open(tx + dx, ty + dy);
        if (!region) continue;
        const Tile& here = tiles[static_cast<size_t>(ty * tilesX + tx)];
        const int empty = here.empty, clipped = here.clipped;
        const float* seen = here.seen;
        const bool tileClipped = 2 * clipped >= empty;
        const double u = (tx + 0.5) * tile - 0.5, v = (ty + 0.5) * tile - 0.5;
        const cv::Vec3d d = cv::normalize(R * cv::Vec3d((u - K.cx) / K.fx, (v - K.cy) / K.fy, 1.0));
        Eigen::Vector3i last(INT_MIN, INT_MIN, INT_MIN);
        for (double t = 0; t <= reach - step; t += step) {
          const cv::Vec3d p = origin + t * d;
          const Eigen::Vector3i cell(static_cast<int>(std::floor(p[0] / kOpeningCellM)),
                                     static_cast<int>(std::floor(p[1] / kOpeningCellM)),
                                     static_cast<int>(std::floor(p[2] / kOpeningCellM)));
          if (cell == last) continue;  // a ray counts once in each cell it crosses
          last = cell;
          auto it = openings.find(cell);
          if (it == openings.end()) {
            if (openings.size() >= kMaxOpeningCells) continue;
            it = openings.emplace(cell, OpeningSeen{}).first;
          }
          for (int k = 0; k < 3; ++k) it->second.sum[k] += seen[k] / static_cast<float>(empty);
          ++it->second.rays;
          it->second.clipped += tileClipped;
        }
      }
  }

  void observe(const cv::Mat& depth, const cv::Mat& colour, const capture::Intrinsics& K, const capture::Pose& T,
               double exposure, const RoomOptions& o) {
    float lut[256];
    for (int i = 0; i < 256; ++i) lut[i] = static_cast<float>(capture::srgbToLinear(i / 255.f) / exposure);
    const int s =
        o.appearanceStride > 0 ? o.appearanceStride : std::max(1, static_cast<int>(std::lround(K.fx / 131.0)));
    const double inv = 1.0 / o.voxelM;
    const float fade = static_cast<float>(o.appearanceMemory - 1) / static_cast<float>(o.appearanceMemory);
    auto point = [&](int x, int y, float d) { return cv::Vec3d((x - K.cx) * d / K.fx, (y - K.cy) * d / K.fy, d); };
    auto clippedAt = [&](int x, int y) {
      const cv::Vec3b c = colour.at<cv::Vec3b>(y, x);
      return std::max({c[0], c[1], c[2]}) >= o.clipLevel;
    };
    for (int y = s; y + s < depth.rows; y += s)
      for (int x = s; x + s < depth.cols; x += s) {
        const float d = depth.at<float>(y, x);
        if (!(d > 0)) continue;
        const float l = depth.at<float>(y, x - s), r = depth.at<float>(y, x + s), u = depth.at<float>(y - s, x),
                    b = depth.at<float>(y + s, x);
        // A depth edge mixes two surfaces' colours: no observation of either.
        const float tol = 0.05f * d;
        if (!(l > 0 && r > 0 && u > 0 && b > 0) || std::abs(l - d) > tol || std::abs(r - d) > tol ||
            std::abs(u - d) > tol || std::abs(b - d) > tol)
          continue;
        const cv::Vec3d pc = point(x, y, d);
        cv::Vec3d n = (point(x + s, y, r) - point(x - s, y, l)).cross(point(x, y + s, b) - point(x, y - s, u));
        const double nn = cv::norm(n);
        if (!(nn > 0)) continue;
        const double cosView = std::abs(n.dot(pc)) / (nn * cv::norm(pc));
        if (cosView < o.grazingCos) continue;
        const cv::Vec3d p = capture::transformPoint(T, pc);
        const Eigen::Vector3i key(static_cast<int>(std::floor(p[0] * inv)), static_cast<int>(std::floor(p[1] * inv)),
                                  static_cast<int>(std::floor(p[2] * inv)));
        Appearance& a = appearance[key];
        const cv::Vec3b c = colour.at<cv::Vec3b>(y, x);
        const float w = static_cast<float>(cosView / (static_cast<double>(d) * d));
        if (a.count >= o.appearanceMemory) {
          for (float& v : a.sum) v *= fade;
          a.weight *= fade;
          a.mixedWeight *= fade;
        } else {
          ++a.count;
        }
        if (std::max({c[0], c[1], c[2]}) >= o.clipLevel) {
          for (int k = 0; k < 3; ++k) a.lower[k] = std::max(a.lower[k], lut[c[k]]);
          if (a.clipped < 65535) ++a.clipped;
          // Clipped pixels carry no radiance of their own; next to unclipped ones they are the brighter part
          // of a texture, and their bound keeps the neighbourhood's mean from darkening (lookup()).
          if (!clippedAt(x - s, y) || !clippedAt(x + s, y) || !clippedAt(x, y - s) || !clippedAt(x, y + s)) {
            a.mixedWeight += w;
            for (int k = 0; k < 3; ++k) a.mixedLower[k] = std::max(a.mixedLower[k], lut[c[k]]);
          }
          continue;
        }
        for (int k = 0; k < 3; ++k) a.sum[k] += w * lut[c[k]];
        a.weight += w;
      }
  }

  /// Confidence-weighted average of the 27 voxels around p with a tent kernel 1.5 voxels wide per axis
  /// (every one of them counts: a vertex on a voxel's centre plane still sees its neighbours' observations,
  /// which sparse sampling may have put only there): radiance, confidence, saturated.
  bool lookup(const Eigen::Vector3d& p, double voxel, cv::Vec3f& radiance, float& confidence, bool& saturated) const {
    const Eigen::Vector3d g = p / voxel;
    const Eigen::Vector3i centre(static_cast<int>(std::floor(g[0])), static_cast<int>(std::floor(g[1])),
                                 static_cast<int>(std::floor(g[2])));
    // Per voxel its radiance and confidence: the unclipped mean, with the clipped observations that lay
    // next to unclipped pixels (brighter texture finer than the voxels) counted at max(their bound, that
    // mean); a voxel with only such clipped observations, at their bound. Clipped pixels among clipped ones
    // (a lamp, an over-exposed frame) count for nothing here: a voxel seen only so is saturated.
    double sum[3] = {0, 0, 0}, weight = 0, unclipped = 0;
    float lower[3] = {0, 0, 0};
    bool any = false;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const Eigen::Vector3i key = centre + Eigen::Vector3i(dx, dy, dz);
          const auto it = appearance.find(key);
          if (it == appearance.end()) continue;
          any = true;
          const Appearance& a = it->second;
          double t = 1;
          for (int k = 0; k < 3; ++k) t *= 1.5 - std::abs(g[k] - (key[k] + 0.5));
          for (int k = 0; k < 3; ++k) lower[k] = std::max(lower[k], a.lower[k]);
          if (a.weight > 0) {
            for (int k = 0; k < 3; ++k) {
              const double mean = a.sum[k] / a.weight;
              sum[k] += t * (a.sum[k] + a.mixedWeight * std::max<double>(a.mixedLower[k], mean));
            }
            weight += t * (a.weight + a.mixedWeight);
            unclipped += t * a.weight;
          } else if (a.mixedWeight > 0) {
            for (int k = 0; k < 3; ++k) sum[k] += t * a.mixedWeight * a.mixedLower[k];
            weight += t * a.mixedWeight;
          }
        }
    if (!any) return false;
    saturated = !(unclipped > 0);
    confidence = static_cast<float>(unclipped);
    for (int k = 0; k < 3; ++k) radiance[k] = saturated ? lower[k] : static_cast<float>(sum[k] / weight);
    return true;
  }

  /// The voxel at global voxel coordinates, or -1 where no block holds it.
  int64_t voxel(const Eigen::Vector3i& global) const {
    const Eigen::Vector3i block = floorDiv(global, kBlockResolution);
    const auto it = index.find(block);
    if (it == index.end()) return -1;
    const Eigen::Vector3i l = global - block * kBlockResolution;
    return it->second * kBlockVoxels + l[0] + kBlockResolution * (l[1] + kBlockResolution * l[2]);
  }

  /// The blocks a frame's surface touches: every block within the truncation distance of the point seen at
  /// every kSamplingStride-th pixel each way.
  std::unordered_set<Eigen::Vector3i, Hash> touched(const cv::Mat& depth, const capture::Intrinsics& K,
                                                    const capture::Pose& T, double trunc) const {
    std::unordered_set<Eigen::Vector3i, Hash> out;
    const double unit = voxelM * kBlockResolution;
    for (int y = 0; y < depth.rows; y += kSamplingStride)
      for (int x = 0; x < depth.cols; x += kSamplingStride) {
        const float d = depth.at<float>(y, x);
        if (!(d > 0)) continue;
        const cv::Vec3d pc((x - K.cx) * d / K.fx, (y - K.cy) * d / K.fy, d);
        const cv::Vec3d p = capture::transformPoint(T, pc);
        Eigen::Vector3i lo, hi;
        for (int k = 0; k < 3; ++k) {
          lo[k] = static_cast<int>(std::floor((p[k] - trunc) / unit));
          hi[k] = static_cast<int>(std::floor((p[k] + trunc) / unit));
        }
        for (int i = lo[0]; i <= hi[0]; ++i)
          for (int j = lo[1]; j <= hi[1]; ++j)
            for (int k = lo[2]; k <= hi[2]; ++k) out.insert({i, j, k});
      }
    return out;
  }
};

RoomModel::RoomModel(const RoomOptions& options) : options_(options) {
  options_.validate("room model");
  quietOpen3d();
  impl_ = std::make_unique<Impl>(options_);
}
RoomModel::~RoomModel() = default;
RoomModel::RoomModel(RoomModel&&) noexcept = default;
RoomModel& RoomModel::operator=(RoomModel&&) noexcept = default;

double RoomModel::signedDistance(const cv::Vec3d& p) const {
  // Voxel centres sit at (i + 0.5) * voxel: trilinear over the 8 around p, all of them observed.
  const double v = options_.voxelM;
  const cv::Vec3d g(p[0] / v - 0.5, p[1] / v - 0.5, p[2] / v - 0.5);
  const Eigen::Vector3i base(static_cast<int>(std::floor(g[0])), static_cast<int>(std::floor(g[1])),
                             static_cast<int>(std::floor(g[2])));
  const cv::Vec3d f(g[0] - base[0], g[1] - base[1], g[2] - base[2]);
  double sum = 0;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3i o(c & 1, (c >> 1) & 1, (c >> 2) & 1);
    const int64_t vox = impl_->voxel(base + o);
    if (vox < 0 || !(impl_->weight[vox] > 0)) return std::numeric_limits<double>::quiet_NaN();
    const double w = (o[0] ? f[0] : 1 - f[0]) * (o[1] ? f[1] : 1 - f[1]) * (o[2] ? f[2] : 1 - f[2]);
    sum += w * impl_->tsdf[vox];
  }
  return sum * options_.truncM;
}

RoomIntegration RoomModel::checkPose(const cv::Mat& depth, const capture::Intrinsics& K,
                                     const capture::Pose& T_world_camera) const {
  RoomIntegration r;
  int valid = 0, observed = 0, far = 0;
  // About 80 x 60 samples whatever the resolution (every 4th pixel at 320 x 240, every 8th at 640 x 480):
  // enough to tell a fraction of 30 % within a few per cent.
  const int step = std::max(4, depth.cols / 80);
  for (int y = 0; y < depth.rows; y += step)
    for (int x = 0; x < depth.cols; x += step) {
      const float d = depth.at<float>(y, x);
      if (!(d > 0) || d > options_.maxDepthM) continue;
      ++valid;
      const cv::Vec3d p =
          capture::transformPoint(T_world_camera, cv::Vec3d((x - K.cx) * d / K.fx, (y - K.cy) * d / K.fy, d));
      const double s = signedDistance(p);
      if (std::isnan(s)) continue;
      ++observed;
      if (std::abs(s) > options_.outlierM) ++far;
    }
  r.overlap = valid > 0 ? static_cast<double>(observed) / valid : 0.0;
  r.inconsistent = observed > 0 ? static_cast<double>(far) / observed : 0.0;
  if (valid == 0)
    r.refused = "no valid depth";
  else if (integrated_ > 0 && r.overlap >= options_.minOverlap && r.inconsistent > options_.outlierFraction)
    r.refused = "pose disagrees with the model";
  return r;
}

namespace {

/// Space carving. A running average forgets slowly: an object seen for n frames and then gone needs about
/// n frames of free space before its surface's zero crossing leaves (half-carved, it stays as a ghost
/// surface in the middle of where it was). A voxel the model holds inside a surface (tsdf < 0) that this
/// frame sees in front of its surface — all the depth around its pixel (5 x 5, at least half of it valid)
/// lies more than the truncation distance beyond it — contradicts the model: what was there has gone, and
/// the voxel restarts as free space (tsdf 1, weight 1). Within the truncation distance of the surface seen,
/// the running average decides. Requiring the whole window keeps silhouettes, where a voxel's pixel may see
/// past an object's edge, from eroding objects that stay.
void carveFreeSpace(float* tsdf, float* weight, const std::vector<Eigen::Vector3i>& blocks,
                    const std::vector<int64_t>& buffers, double voxel, const cv::Mat& depth,
                    const capture::Intrinsics& K, const capture::Pose& T_camera_world, double trunc) {
  // The smallest valid depth of each 5 x 5 window; 0 where fewer than half of it is valid.
  cv::Mat valid = depth > 0, lifted = depth.clone(), nearest, share;
  lifted.setTo(std::numeric_limits<float>::max(), ~valid);
  cv::erode(lifted, nearest, cv::Mat::ones(5, 5, CV_8U), cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::boxFilter(valid, share, CV_32F, cv::Size(5, 5), cv::Point(-1, -1), true, cv::BORDER_CONSTANT);
  nearest.setTo(0, share < 0.5 * 255);
  const cv::Matx33d R = capture::rotationOf(T_camera_world);
  const cv::Vec3d t = capture::translationOf(T_camera_world);
  constexpr int n = kBlockResolution;
  cv::parallel_for_(cv::Range(0, static_cast<int>(blocks.size())), [&](const cv::Range& range) {
    for (int b = range.start; b < range.end; ++b) {
      const Eigen::Vector3i origin = blocks[static_cast<size_t>(b)] * n;
      float* ts = tsdf + buffers[static_cast<size_t>(b)] * kBlockVoxels;
      float* ws = weight + buffers[static_cast<size_t>(b)] * kBlockVoxels;
      for (int z = 0; z < n; ++z)
        for (int y = 0; y < n; ++y)
          for (int x = 0; x < n; ++x) {
            const int v = x + n * (y + n * z);
            if (!(ws[v] > 0) || !(ts[v] < 0)) continue;
            const cv::Vec3d p((origin[0] + x + 0.5) * voxel, (origin[1] + y + 0.5) * voxel,
                              (origin[2] + z + 0.5) * voxel);
            const cv::Vec3d pc = R * p + t;
            if (pc[2] <= 0) continue;
            const int u = static_cast<int>(std::lround(K.fx * pc[0] / pc[2] + K.cx)),
                      w = static_cast<int>(std::lround(K.fy * pc[1] / pc[2] + K.cy));
            if (u < 0 || w < 0 || u >= nearest.cols || w >= nearest.rows) continue;
            const float d = nearest.at<float>(w, u);
            if (d > 0 && pc[2] < d - trunc) {
              ts[v] = 1;
              ws[v] = 1;
            }
          }
    }
  });
}

}  // namespace

RoomIntegration RoomModel::integrate(const cv::Mat& depthIn, const cv::Mat& colour, const capture::Intrinsics& K,
                                     const capture::Pose& T_world_camera, double exposure) {
  if (!(exposure > 0) || !std::isfinite(exposure))
    throw std::invalid_argument("RoomModel::integrate: exposure must be positive");
  if (depthIn.type() != CV_32FC1 || colour.type() != CV_8UC3 || depthIn.size() != colour.size() ||
      depthIn.cols != K.width || depthIn.rows != K.height || !K.valid())
    throw std::invalid_argument(
        "RoomModel::integrate: depth (CV_32FC1) and colour (CV_8UC3) must match the intrinsics");
  // Depth past the range, and non-finite depth, is no observation.
  cv::Mat depth = depthIn.clone();
  for (int y = 0; y < depth.rows; ++y) {
    float* row = depth.ptr<float>(y);
    for (int x = 0; x < depth.cols; ++x)
      if (!std::isfinite(row[x]) || row[x] <= 0 || row[x] > options_.maxDepthM) row[x] = 0;
  }
  RoomIntegration r = checkPose(depth, K, T_world_camera);
  const auto touched = impl_->touched(depth, K, T_world_camera, options_.truncM);
  std::vector<Eigen::Vector3i> added;
  for (const auto& b : touched)
    if (!impl_->index.count(b)) added.push_back(b);
  r.newBlocks = added.size();
  if (r.refused.empty() && impl_->index.size() + r.newBlocks > static_cast<size_t>(options_.maxBlocks))
    r.refused = "memory budget (" + std::to_string(options_.maxBlocks) + " blocks) reached";
  if (!r.refused.empty()) {
    ++refused_;
    return r;
  }

  // The blocks integrated: those near this frame's points and, for carving, every other block in view.
  // Blocks farther in front of what the camera now sees (a box that has moved away, taller than the
  // truncation distance) would otherwise keep their old surface; integrated, free space seen through them
  // clears them. A block wholly behind everything the camera sees there (by more than the truncation) or over
  // no depth at all would not change (a voxel is updated only where depth is valid and the voxel lies less
  // than the truncation behind it): those are skipped, by the largest depth of 16 x 16 pixel tiles.
  const capture::Pose T_camera_world = capture::inversePose(T_world_camera);
  constexpr int kTile = 16;
  const int tilesX = (depth.cols + kTile - 1) / kTile, tilesY = (depth.rows + kTile - 1) / kTile;
  cv::Mat tileMax(tilesY, tilesX, CV_32FC1, cv::Scalar(0));
  for (int y = 0; y < depth.rows; ++y) {
    const float* row = depth.ptr<float>(y);
    float* t = tileMax.ptr<float>(y / kTile);
    for (int x = 0; x < depth.cols; ++x) t[x / kTile] = std::max(t[x / kTile], row[x]);
  }
  const double half = 0.5 * options_.voxelM * kBlockResolution;
  std::vector<Eigen::Vector3i> inView;
  for (const auto& [block, buffer] : impl_->index) {
    if (!touched.count(block)) {
      const cv::Vec3d centre((block[0] + 0.5) * 2 * half, (block[1] + 0.5) * 2 * half, (block[2] + 0.5) * 2 * half);
      const cv::Vec3d pc = capture::transformPoint(T_camera_world, centre);
      if (pc[2] <= half) continue;
      const double u = K.fx * pc[0] / pc[2] + K.cx, v = K.fy * pc[1] / pc[2] + K.cy;
      const double margin = K.fx * 1.8 * half / pc[2];
      if (u < -margin || v < -margin || u > K.width + margin || v > K.height + margin) continue;
      const int x0 = std::clamp(static_cast<int>(std::floor((u - margin) / kTile)), 0, tilesX - 1),
                x1 = std::clamp(static_cast<int>(std::floor((u + margin) / kTile)), 0, tilesX - 1),
                y0 = std::clamp(static_cast<int>(std::floor((v - margin) / kTile)), 0, tilesY - 1),
                y1 = std::clamp(static_cast<int>(std::floor((v + margin) / kTile)), 0, tilesY - 1);
      double seen = 0;
      for (int ty = y0; ty <= y1; ++ty)
        for (int tx = x0; tx <= x1; ++tx) seen = std::max(seen, static_cast<double>(tileMax.at<float>(ty, tx)));
      if (!(seen > 0) || pc[2] - 1.8 * half > seen + options_.truncM) continue;
    }
    inView.push_back(block);
  }
  inView.insert(inView.end(), added.begin(), added.end());
  impl_->add(added, inView.size());
  std::vector<int64_t> buffers;
  buffers.reserve(inView.size());
  for (const auto& b : inView) buffers.push_back(impl_->index.at(b));

  // Open3D integrates no colour here: the fused appearance below is the room's colour. It reads the depth at
  // pixel (int) u, the pixel whose centre (at integer u) is up to a pixel to the left; the principal point given
  // to it is half a pixel on, so that it reads the nearest pixel.
  capture::Intrinsics nearest = K;
  nearest.cx += 0.5, nearest.cy += 0.5;
  if (!inView.empty())
    impl_->grid.Integrate(Impl::keysOf(inView), o3d::t::geometry::Image(imageTensor(depth)), intrinsicsTensor(nearest),
                          poseTensor(impl_->cameraFromGrid(T_camera_world)), 1.0f,
                          static_cast<float>(options_.maxDepthM),
                          static_cast<float>(options_.truncM / options_.voxelM));
  if (impl_->grid.GetHashMap().GetCapacity() != impl_->capacity + 1)
    throw std::logic_error("RoomModel: Open3D's integration rehashed the voxel grid");
  carveFreeSpace(impl_->tsdf, impl_->weight, inView, buffers, options_.voxelM, depth, K, T_camera_world,
                 options_.truncM);
  impl_->observe(depth, colour, K, T_world_camera, exposure, options_);
  impl_->recordOpenings(depthIn, colour, K, T_world_camera, options_.maxDepthM, exposure, options_.clipLevel);
  r.integrated = true;
  ++integrated_;
  return r;
}

namespace {

/// The same mesh in an order that depends on its geometry alone. Open3D's marching cubes numbers vertices and
/// triangles in the order its threads reach them, which changes from run to run; the room's lighting must
/// not. Each triangle is turned (keeping its winding) to start at its least vertex (positions compared x, then
/// y, then z), triangles are sorted by their vertices' positions, and vertices are numbered as the sorted
/// triangles first use them.
o3d::geometry::TriangleMesh canonicalOrder(const o3d::geometry::TriangleMesh& in) {
  const auto& P = in.vertices_;
  const auto less = [&](int a, int b) {
    const Eigen::Vector3d &p = P[static_cast<size_t>(a)], &q = P[static_cast<size_t>(b)];
    return std::lexicographical_compare(p.data(), p.data() + 3, q.data(), q.data() + 3);
  };
  std::vector<Eigen::Vector3i> tris = in.triangles_;
  for (auto& t : tris) {
    const int first = less(t[1], t[0]) ? (less(t[2], t[1]) ? 2 : 1) : (less(t[2], t[0]) ? 2 : 0);
    t = Eigen::Vector3i(t[first], t[(first + 1) % 3], t[(first + 2) % 3]);
  }
  std::sort(tris.begin(), tris.end(), [&](const Eigen::Vector3i& a, const Eigen::Vector3i& b) {
    for (int k = 0; k < 3; ++k) {
      if (less(a[k], b[k])) return true;
      if (less(b[k], a[k])) return false;
    }
    return false;
  });
  o3d::geometry::TriangleMesh out;
  std::vector<int> renumber(P.size(), -1);
  out.vertices_.reserve(P.size());
  out.triangles_.reserve(tris.size());
  for (const auto& t : tris) {
    Eigen::Vector3i u;
    for (int k = 0; k < 3; ++k) {
      int& n = renumber[static_cast<size_t>(t[k])];
      if (n < 0) {
        n = static_cast<int>(out.vertices_.size());
        out.vertices_.push_back(P[static_cast<size_t>(t[k])]);
      }
      u[k] = n;
    }
    out.triangles_.push_back(u);
  }
  return out;
}

}  // namespace

RoomMesh RoomModel::mesh() const {
  RoomMesh out;
  if (impl_->index.empty()) return out;
  // Every voxel with weight takes part (weight > 0).
  const auto t = impl_->grid.ExtractTriangleMesh(0.0f);
  if (t.IsEmpty() || !t.HasVertexPositions() || t.GetVertexPositions().GetLength() == 0) return out;
  auto m = std::make_shared<o3d::geometry::TriangleMesh>(canonicalOrder(t.ToLegacy()));
  if (m->vertices_.empty()) return out;
  // Back from the grid's frame to the world's (half a voxel).
  for (auto& p : m->vertices_) p += Eigen::Vector3d::Constant(0.5 * options_.voxelM);
  m->ComputeVertexNormals();
  out.positions.reserve(m->vertices_.size());
  for (size_t i = 0; i < m->vertices_.size(); ++i) {
    const auto& p = m->vertices_[i];
    const auto& n = m->vertex_normals_[i];
    out.positions.emplace_back(static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2]));
    out.normals.emplace_back(static_cast<float>(n[0]), static_cast<float>(n[1]), static_cast<float>(n[2]));
    cv::Vec3f L;
    float confidence = 0;
    bool saturated = false;
    if (!impl_->lookup(p, options_.voxelM, L, confidence, saturated)) {
      // No accepted or clipped observation near the vertex (every one grazing or on an edge): its radiance
      // is unknown; a mid grey with no confidence (Open3D integrates no colour of its own).
      for (int k = 0; k < 3; ++k) L[k] = static_cast<float>(capture::srgbToLinear(0.5f));
    }
    out.radiance.push_back(L);
    out.confidence.push_back(confidence);
    out.saturated.push_back(saturated ? 1 : 0);
  }
  out.indices.reserve(m->triangles_.size() * 3);
  for (const auto& t : m->triangles_)
    for (int k = 0; k < 3; ++k) out.indices.push_back(static_cast<uint32_t>(t[k]));
  out.openings.cellM = Impl::kOpeningCellM;
  out.openings.recorded = true;
  std::vector<std::pair<cv::Vec3i, const Impl::OpeningSeen*>> cells;
  cells.reserve(impl_->openings.size());
  for (const auto& [c, seen] : impl_->openings) cells.emplace_back(cv::Vec3i(c[0], c[1], c[2]), &seen);
  std::sort(cells.begin(), cells.end(), [](const auto& a, const auto& b) { return cellLess(a.first, b.first); });
  for (const auto& [c, seen] : cells) {
    out.openings.cells.push_back(c);
    const float n = static_cast<float>(std::max<uint32_t>(seen->rays, 1));
    out.openings.radiance.emplace_back(seen->sum[0] / n, seen->sum[1] / n, seen->sum[2] / n);
    out.openings.clipped.push_back(2 * seen->clipped >= seen->rays ? 1 : 0);
  }
  return out;
}

int RoomOpenings::find(const cv::Vec3d& p) const {
  const cv::Vec3i c(static_cast<int>(std::floor(p[0] / cellM)), static_cast<int>(std::floor(p[1] / cellM)),
                    static_cast<int>(std::floor(p[2] / cellM)));
  const auto it = std::lower_bound(cells.begin(), cells.end(), c, cellLess);
  return it != cells.end() && *it == c ? static_cast<int>(it - cells.begin()) : -1;
}

int RoomOpenings::beyond(const cv::Vec3d& lo, const cv::Vec3d& hi, const cv::Vec3d& origin, const cv::Vec3d& w) const {
  if (!recorded || cells.empty()) return -1;
  // Where the ray leaves the box, a cell the cameras saw through, outside it: only a ray that met no surface goes
  // there (a window onto the sky, a surface past the sensor's range), not one that met the room.
  double tExit = 1e30;
  for (int k = 0; k < 3; ++k)
    if (std::abs(w[k]) > 1e-12) tExit = std::min(tExit, ((w[k] > 0 ? hi[k] : lo[k]) - origin[k]) / w[k]);
  if (!(tExit < 1e29)) return -1;
  tExit = std::max(tExit, 0.0);
  const double step = 0.5 * cellM;
  for (double t = tExit - 0.5 * step; t <= tExit + 6 * step; t += step)
    if (t > 0)
      if (const int cell = find(origin + t * w); cell >= 0) return cell;
  return -1;
}

size_t RoomModel::blocks() const { return impl_->index.size(); }
size_t RoomModel::appearanceBytes() const {
  // Entries plus the hash table's node and bucket overhead (libstdc++: a node holds the pair and a next
  // pointer and the cached hash; a bucket is a pointer).
  const size_t node = sizeof(std::pair<const Eigen::Vector3i, Impl::Appearance>) + 2 * sizeof(void*);
  return impl_->appearance.size() * node + impl_->appearance.bucket_count() * sizeof(void*);
}
size_t RoomModel::bytes() const { return blocks() * static_cast<size_t>(kBlockVoxels) * 2 * sizeof(float); }

// ---- shadow rays kept between meshes ---------------------------------------------------------------------

namespace {

/// The voxel edge a marching-cubes vertex lies on: the vertex sits between two voxel centres ((i + 1/2) voxels)
/// along one axis and on the centres' grid along the other two. 20 bits per axis (21 km at 2 cm), 2 for the
/// edge's axis.
uint64_t edgeKey(const cv::Vec3f& p, double voxel) {
  double q[3], off[3];
  int axis = 0;
  for (int k = 0; k < 3; ++k) {
    q[k] = p[k] / voxel - 0.5;
    off[k] = std::abs(q[k] - std::round(q[k]));
    if (off[k] > off[axis]) axis = k;
  }
  uint64_t key = static_cast<uint64_t>(axis);
  for (int k = 0; k < 3; ++k) {
    const int64_t c = k == axis ? static_cast<int64_t>(std::floor(q[k])) : static_cast<int64_t>(std::llround(q[k]));
    key = (key << 20) | (static_cast<uint64_t>(c + (int64_t{1} << 19)) & ((uint64_t{1} << 20) - 1));
  }
  return key;
}

/// Cells of a uniform grid holding points, for "is any point within r of x" (cell edge >= r).
class PointGrid {
 public:
  explicit PointGrid(double cell) : cell_(cell) {}
  void add(const cv::Vec3f& p) { cells_[keyOf(cellOf(p))].push_back(p); }
  bool empty() const { return cells_.empty(); }
  bool anyWithin(const cv::Vec3d& x, double r) const {
    const cv::Vec3i c = cellOf(x);
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const auto it = cells_.find(keyOf(c + cv::Vec3i(dx, dy, dz)));
          if (it == cells_.end()) continue;
          for (const auto& p : it->second)
            if (cv::norm(cv::Vec3d(p) - x) <= r) return true;
        }
    return false;
  }

 private:
  template <typename V>
  cv::Vec3i cellOf(const V& p) const {
    return {static_cast<int>(std::floor(p[0] / cell_)), static_cast<int>(std::floor(p[1] / cell_)),
            static_cast<int>(std::floor(p[2] / cell_))};
  }
  static uint64_t keyOf(const cv::Vec3i& c) {
    const auto u = [](int v) {
      return static_cast<uint64_t>(static_cast<int64_t>(v) + (int64_t{1} << 20)) & ((uint64_t{1} << 21) - 1);
    };
    return (u(c[0]) << 42) | (u(c[1]) << 21) | u(c[2]);
  }
  double cell_;
  std::unordered_map<uint64_t, std::vector<cv::Vec3f>> cells_;
};

}  // namespace

RoomAlbedoCache::RoomAlbedoCache(double voxelM) : voxelM_(voxelM > 0 ? voxelM : RoomOptions{}.voxelM) {}

std::vector<uint8_t> RoomAlbedoCache::shadows(const RoomMesh& mesh, const AlbedoLights& lights, const MeshRays* rays) {
  const size_t n = mesh.positions.size(), P = lights.points.size(), L = P + lights.distant.size();
  // The segment of a vertex's shadow ray to light l: origin a voxel's worth off the surface, unit direction, length.
  struct Ray {
    cv::Vec3d o, d;
    double far;
  };
  const auto rayOf = [&](size_t i, size_t l) {
    Ray r;
    r.o = cv::Vec3d(mesh.positions[i]) + 0.02 * cv::Vec3d(mesh.normals[i]);
    if (l < P) {
      r.d = lights.points[l].position - r.o;
      const double len = cv::norm(r.d);
      r.far = len * 0.999;
      r.d /= std::max(len, 1e-12);
    } else {
      r.d = lights.distant[l - P].direction;
      r.far = 1e4;
    }
    return r;
  };
  // Do the lights shadow as the cached ones did?
  std::vector<cv::Vec3d> keys(L);
  std::vector<uint8_t> distant(L);
  for (size_t l = 0; l < L; ++l) {
    keys[l] = l < P ? lights.points[l].position : cv::normalize(lights.distant[l - P].direction);
    distant[l] = l >= P;
  }
  bool same = keys.size() == lightKeys_.size() && distant == lightDistant_ && !entries_.empty();
  for (size_t l = 0; same && l < L; ++l)
    same = cv::norm(keys[l] - lightKeys_[l]) <= (distant[l] ? 0.005 : 0.5 * voxelM_);
  if (!same) entries_.clear();
  stats_ = {};
  stats_.vertices = n;
  stats_.full = !same;

  // Which vertices are as they were; the rest, and every earlier vertex not kept, mark what changed.
  std::vector<uint64_t> key(n);
  std::vector<const Entry*> kept(n, nullptr);
  const float moved = static_cast<float>(0.25 * voxelM_);
  std::unordered_map<uint64_t, uint8_t> keptKeys;
  for (size_t i = 0; i < n; ++i) {
    key[i] = edgeKey(mesh.positions[i], voxelM_);
    const auto it = entries_.find(key[i]);
    if (it != entries_.end() && it->second.blockedAt.size() == L &&
        cv::norm(it->second.position - mesh.positions[i]) <= moved) {
      kept[i] = &it->second;
      keptKeys[key[i]] = 1;
    }
  }
  PointGrid gone(1.5 * voxelM_);
  for (const auto& [k, e] : entries_)
    if (!keptKeys.count(k)) gone.add(e.position);
  std::vector<uint32_t> changedTriangles;
  for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3)
    if (!kept[mesh.indices[t]] || !kept[mesh.indices[t + 1]] || !kept[mesh.indices[t + 2]])
      changedTriangles.insert(changedTriangles.end(), mesh.indices.begin() + static_cast<std::ptrdiff_t>(t),
                              mesh.indices.begin() + static_cast<std::ptrdiff_t>(t + 3));
  // Rays against the whole mesh and against what changed in it, cast with Embree (Open3D's
  // RaycastingScene, built on it too, finds no hits in the Debian package); each built when first needed.
  std::unique_ptr<MeshRays> all, fresh;
  const auto whole = [&]() -> const MeshRays& {
    if (rays) return *rays;
    if (!all) all = std::make_unique<MeshRays>(mesh.positions, mesh.indices);
    return *all;
  };
  if (!changedTriangles.empty() && same) fresh = std::make_unique<MeshRays>(mesh.positions, changedTriangles);

  std::vector<uint8_t> blocked(n * L, 0);
  std::unordered_map<uint64_t, Entry> next;
  next.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    Entry e{mesh.positions[i], std::vector<float>(L, -1.f)};
    for (size_t l = 0; l < L; ++l) {
      const Ray r = rayOf(i, l);
      float at = -1.f;
      bool cast = !kept[i];
      if (!cast) {
        at = kept[i]->blockedAt[l];
        if (at < 0) {
          // Free before: blocked now only by something new or moved.
          if (fresh) {
            const auto h = fresh->intersect(r.o, r.d, r.far);
            ++stats_.raysRechecked;
            if (h.hit) at = static_cast<float>(h.t);
          } else {
            ++stats_.raysReused;
          }
        } else if (!gone.empty() && gone.anyWithin(r.o + static_cast<double>(at) * r.d, 1.5 * voxelM_)) {
          cast = true;  // what blocked it moved or went
        }
      }
      if (cast) {
        const auto h = whole().intersect(r.o, r.d, r.far);
        ++stats_.raysCast;
        at = h.hit ? static_cast<float>(h.t) : -1.f;
      } else if (at >= 0) {
        ++stats_.raysReused;
      }
      e.blockedAt[l] = at;
      blocked[i * L + l] = at >= 0;
    }
    if (!kept[i]) ++stats_.changedVertices;
    next.emplace(key[i], std::move(e));
  }
  entries_ = std::move(next);
  lightKeys_ = std::move(keys);
  lightDistant_ = std::move(distant);
  return blocked;
}

// ---- albedo ----------------------------------------------------------------------------------------

cv::Vec3f albedoDetail(const cv::Vec3b& rgb8, const cv::Vec3f& pixelRadiance, const cv::Vec3f& roomRadiance) {
  constexpr float kClip = 250, kDark = 1e-3f, kMin = 0.25f, kMax = 4.0f;
  bool clipped = false;
  for (int c = 0; c < 3; ++c) {
    if (!(roomRadiance[c] >= kDark) || !std::isfinite(pixelRadiance[c])) return {1, 1, 1};
    clipped = clipped || rgb8[c] >= kClip;
  }
  cv::Vec3f detail;
  for (int c = 0; c < 3; ++c) detail[c] = std::clamp(pixelRadiance[c] / roomRadiance[c], kMin, kMax);
  // A clipped pixel's radiance is a lower bound: so is its ratio, which only raises the room's albedo.
  if (clipped)
    for (int c = 0; c < 3; ++c) detail[c] = std::max(detail[c], 1.0f);
  return detail;
}

std::vector<std::vector<uint32_t>> meshNeighbours(const std::vector<uint32_t>& indices, size_t vertices) {
  std::vector<std::vector<uint32_t>> neighbours(vertices);
  for (size_t t = 0; t + 2 < indices.size(); t += 3)
    for (int a = 0; a < 3; ++a) {
      const uint32_t u = indices[t + a], v = indices[t + (a + 1) % 3];
      if (u < vertices && v < vertices) neighbours[u].push_back(v), neighbours[v].push_back(u);
    }
  return neighbours;
}

void fillFromNeighbours(std::vector<cv::Vec3f>& values, std::vector<uint8_t>& known,
                        const std::vector<std::vector<uint32_t>>& neighbours, int rings) {
  for (int ring = 0; ring < rings; ++ring) {
    std::vector<std::pair<size_t, cv::Vec3f>> filled;
    for (size_t i = 0; i < values.size(); ++i) {
      if (known[i]) continue;
      cv::Vec3f sum(0, 0, 0);
      int count = 0;
      for (uint32_t j : neighbours[i])
        if (known[j]) sum += values[j], ++count;
      if (count > 0) filled.emplace_back(i, sum / static_cast<float>(count));
    }
    if (filled.empty()) break;
    for (const auto& [i, v] : filled) values[i] = v, known[i] = 1;
  }
}

RoomAlbedo estimateRoomAlbedo(const RoomMesh& mesh, const AlbedoLights& lights, const AlbedoOptions& options,
                              RoomAlbedoCache* cache, const std::vector<cv::Vec3f>* bounce, const MeshRays* rays) {
  if (bounce && bounce->size() != mesh.positions.size())
    throw std::invalid_argument("estimateRoomAlbedo(): " + std::to_string(bounce->size()) + " bounce irradiances for " +
                                std::to_string(mesh.positions.size()) + " vertices");
  quietOpen3d();
  const size_t n = mesh.positions.size();
  RoomAlbedo out;
  out.albedo.assign(n, cv::Vec3f(0.5f, 0.5f, 0.5f));
  out.status.assign(n, AlbedoStatus::NoGeometry);
  out.inShadow.assign(n, 0);
  out.sent = out.albedo;
  if (n == 0 || mesh.indices.empty()) return out;
  const size_t L = lights.points.size() + lights.distant.size();
  std::vector<uint8_t> occluded(n * L, 0);
  if (options.shadowTest && L > 0) {
    RoomAlbedoCache once;
    occluded = (cache ? *cache : once).shadows(mesh, lights, rays);
  }
  const double saturated = capture::srgbToLinear(options.saturationLevel / 255.f);
  // pi L / E: the albedo where measured; where saturated (L a lower bound) a lower bound of it, which the
  // vertex takes after the fill if its neighbours' albedo is less (a white patch beside black ones).
  std::vector<cv::Vec3f> bound(n, cv::Vec3f(0, 0, 0));
  // E over what the lights and the ambient give (RoomAlbedo::sent).
  std::vector<cv::Vec3f> gain(n, cv::Vec3f(1, 1, 1));
  // In the shadow of a light (the sun through a window, a lamp the table hides from the floor): the albedo there is
  // measured under the other lights, as a surface the light never reaches is, away from the shadow's edges
  // (below). Rejecting such vertices instead left two thirds of a room
  // lit by a lamp and the sun to the fill (the window-sun room), their colour from wherever the fill came from, and
  // a sun measured from them 0.6x its power in the wrong colour.
  std::vector<uint8_t>& inShadow = out.inShadow;
  for (size_t i = 0; i < n; ++i) {
    const cv::Vec3d p(mesh.positions[i]), nrm(mesh.normals[i]);
    const cv::Vec3d Lr(mesh.radiance[i]);
    cv::Vec3d E = bounce ? cv::Vec3d((*bounce)[i]) : lights.ambientIrradiance, direct(0, 0, 0), normalSum(0, 0, 0);
    for (size_t l = 0; l < L; ++l) {
      cv::Vec3d e;
      double c;
      if (l < lights.points.size()) {
        const cv::Vec3d d = lights.points[l].position - p;
        const double r2 = std::max(d.dot(d), 1e-8);
        const double r = std::sqrt(r2);
        e = lights.points[l].intensity * (1.0 / r2);
        c = capture::capCosine(nrm.dot(d) / r, seenSine(lights.points[l], r));
      } else {
        const auto& dl = lights.distant[l - lights.points.size()];
        e = dl.power;
        c = capture::capCosine(nrm.dot(dl.direction), seenSine(dl));
      }
      if (c > 0 && occluded[i * L + l]) {
        inShadow[i] = 1;  // neither light nor blocked light: the vertex is measured without it
        continue;
      }
      normalSum += e;
      if (c > 0) direct += e * c;
    }
    E += direct;
    const double sumN = normalSum[0] + normalSum[1] + normalSum[2], sumD = direct[0] + direct[1] + direct[2];
    if (bounce && sumD > 0)
      for (int k = 0; k < 3; ++k)
        gain[i][k] = static_cast<float>(E[k] / std::max(direct[k] + lights.ambientIrradiance[k], 1e-9));
    AlbedoStatus st = AlbedoStatus::Measured;
    if (i < mesh.saturated.size() ? mesh.saturated[i] != 0 : std::max({Lr[0], Lr[1], Lr[2]}) >= saturated)
      st = AlbedoStatus::Saturated;
    else if (sumN > 0 && sumD < options.minEffectiveCos * sumN)
      st = AlbedoStatus::Grazing;
    else if (E[0] + E[1] + E[2] <= 1e-9)
      st = AlbedoStatus::Unlit;
    out.status[i] = st;
    if (st == AlbedoStatus::Measured || st == AlbedoStatus::Saturated)
      for (int k = 0; k < 3; ++k)
        bound[i][k] = static_cast<float>(std::clamp(CV_PI * Lr[k] / std::max(E[k], 1e-9), 0.0, 1.0));
    if (st == AlbedoStatus::Measured) out.albedo[i] = bound[i];
  }
  const std::vector<std::vector<uint32_t>> neighbours = meshNeighbours(mesh.indices, n);
  // A shadow's edge is blurred in the fused colour (voxels, and averaging over views): the two rings of
  // vertices around a shadow are rejected with it, or their darker colour would read as a darker albedo. The
  // edge of a light's shadow is rejected on both sides (the vertices either side of it), then its two rings.
  std::vector<size_t> shadowEdge;
  for (size_t i = 0; i < n; ++i)
    if (out.status[i] == AlbedoStatus::Measured)
      for (uint32_t j : neighbours[i])
        if (inShadow[j] != inShadow[i]) {
          shadowEdge.push_back(i);
          break;
        }
  for (size_t i : shadowEdge) out.status[i] = AlbedoStatus::Shadowed;
  for (int ring = 0; ring < 2; ++ring) {
    std::vector<size_t> edge;
    for (size_t i = 0; i < n; ++i)
      if (out.status[i] == AlbedoStatus::Measured)
        for (uint32_t j : neighbours[i])
          if (out.status[j] == AlbedoStatus::Shadowed) {
            edge.push_back(i);
            break;
          }
    for (size_t i : edge) out.status[i] = AlbedoStatus::Shadowed;
  }
  // Rejected vertices take the mean of their measured (or already filled) neighbours, pass by pass.
  if (options.fill) {
    std::vector<uint8_t> known(n);
    for (size_t i = 0; i < n; ++i) known[i] = out.status[i] == AlbedoStatus::Measured;
    fillFromNeighbours(out.albedo, known, neighbours);
  }
  for (size_t i = 0; i < n; ++i)
    if (out.status[i] == AlbedoStatus::Saturated)
      for (int k = 0; k < 3; ++k) out.albedo[i][k] = std::max(out.albedo[i][k], bound[i][k]);
  out.sent.resize(n);
  for (size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) out.sent[i][k] = std::min(1.0f, out.albedo[i][k] * gain[i][k]);
  return out;
}

// ---- saved rooms --------------------------------------------------------------------------------------

namespace {

constexpr int kAppearanceColumns = 5;  // r, g, b, confidence, saturated

/// ROOM/room_appearance.npy: float32 little-endian, C order, (vertices, 5).
/// A .npy preamble (version 1.0) for a (rows, cols) C-order array of type `descr`.
std::string npyPreamble(const char* descr, size_t rows, int cols) {
  std::string header = std::string("{'descr': '") + descr + "', 'fortran_order': False, 'shape': (" +
                       std::to_string(rows) + ", " + std::to_string(cols) + "), }";
  // Magic, version 1.0, header length; the whole preamble padded with spaces to a multiple of 64, ending in '\n'.
  const size_t preamble = 10;
  while ((preamble + header.size() + 1) % 64 != 0) header += ' ';
  header += '\n';
  std::string out("\x93NUMPY\x01\x00", 8);
  out += static_cast<char>(header.size() & 0xff);
  out += static_cast<char>(header.size() >> 8);
  return out + header;
}

std::string appearanceNpy(const RoomMesh& mesh) {
  const size_t n = mesh.positions.size();
  std::string out = npyPreamble("<f4", n, kAppearanceColumns);
  std::vector<float> rows(n * kAppearanceColumns);
  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) rows[i * kAppearanceColumns + k] = mesh.radiance[i][k];
    rows[i * kAppearanceColumns + 3] = i < mesh.confidence.size() ? mesh.confidence[i] : 0.f;
    rows[i * kAppearanceColumns + 4] = i < mesh.saturated.size() && mesh.saturated[i] ? 1.f : 0.f;
  }
  out.append(reinterpret_cast<const char*>(rows.data()), rows.size() * sizeof(float));
  return out;
}

/// ROOM/room_openings.npy: float32 little-endian, (cells, 7): the cell's i, j, k (integers, exact in float32 within
/// the loader's range), the radiance seen through it (r, g, b), and 1 where it was mostly clipped.
constexpr int kOpeningColumns = 7;
std::string openingsNpy(const RoomOpenings& o) {
  std::string out = npyPreamble("<f4", o.cells.size(), kOpeningColumns);
  std::vector<float> rows(o.cells.size() * kOpeningColumns);
  for (size_t i = 0; i < o.cells.size(); ++i) {
    float* r = &rows[i * kOpeningColumns];
    for (int k = 0; k < 3; ++k) r[k] = static_cast<float>(o.cells[i][k]);
    for (int k = 0; k < 3; ++k) r[3 + k] = i < o.radiance.size() ? o.radiance[i][k] : 0.f;
    r[6] = i < o.clipped.size() && o.clipped[i] ? 1.f : 0.f;
  }
  out.append(reinterpret_cast<const char*>(rows.data()), rows.size() * sizeof(float));
  return out;
}

}  // namespace

void saveRoom(const std::string& dir, const RoomMesh& mesh, const RoomInfo& info) {
  quietOpen3d();
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw capture::InputError(dir, "cannot create: " + ec.message());
  // The appearance first and room.json last: a room cut short by a crash has files that disagree on the
  // vertex count, which loadRoom refuses, rather than a mix that loads.
  capture::writeFileAtomically(fs::path(dir) / "room_appearance.npy", appearanceNpy(mesh));
  o3d::geometry::TriangleMesh m;
  m.vertices_.reserve(mesh.positions.size());
  cv::Vec3f lo(1e30f, 1e30f, 1e30f), hi(-1e30f, -1e30f, -1e30f);
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    const cv::Vec3f& p = mesh.positions[i];
    m.vertices_.emplace_back(p[0], p[1], p[2]);
    m.vertex_normals_.emplace_back(mesh.normals[i][0], mesh.normals[i][1], mesh.normals[i][2]);
    const cv::Vec3f& c = mesh.radiance[i];
    m.vertex_colors_.emplace_back(capture::linearToSrgb(std::clamp(c[0], 0.f, 1.f)),
                                  capture::linearToSrgb(std::clamp(c[1], 0.f, 1.f)),
                                  capture::linearToSrgb(std::clamp(c[2], 0.f, 1.f)));
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], p[k]), hi[k] = std::max(hi[k], p[k]);
  }
  for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3)
    m.triangles_.emplace_back(static_cast<int>(mesh.indices[t]), static_cast<int>(mesh.indices[t + 1]),
                              static_cast<int>(mesh.indices[t + 2]));
  // Written beside and renamed over: a reader sees the old room or the new one, never half of one.
  const fs::path ply = fs::path(dir) / "room.ply", tmp = fs::path(dir) / ".room.partial.ply";
  if (!o3d::io::WriteTriangleMesh(tmp.string(), m, false, false, true, true, false, false))
    throw capture::InputError(ply.string(), "cannot write the room mesh");
  fs::rename(tmp, ply, ec);
  if (ec) throw capture::InputError(ply.string(), "cannot rename: " + ec.message());
  nlohmann::json j = {{"format", "mrgi-room"},
                      {"version", 2},
                      {"appearance", "room_appearance.npy"},
                      {"appearance_bytes", info.appearanceBytes},
                      {"generated_by", "mrgi room"},
                      {"mesh", "room.ply"},
                      {"voxel_m", info.options.voxelM},
                      {"trunc_m", info.options.truncM},
                      {"max_blocks", info.options.maxBlocks},
                      {"frames_integrated", info.framesIntegrated},
                      {"frames_refused", info.framesRefused},
                      {"blocks", info.blocks},
                      {"bytes", info.bytes},
                      {"vertices", mesh.positions.size()},
                      {"triangles", mesh.triangleCount()},
                      {"session", info.session}};
  if (!mesh.positions.empty()) j["bounds_m"] = {{lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]}};
  if (mesh.openings.recorded) {
    // None seen: no file (NumPy's arrays of no rows are more than our reader takes).
    if (!mesh.openings.cells.empty())
      capture::writeFileAtomically(fs::path(dir) / "room_openings.npy", openingsNpy(mesh.openings));
    j["openings"] = {{"cell_m", mesh.openings.cellM},
                     {"cells", mesh.openings.cells.empty() ? nlohmann::json(nullptr) : "room_openings.npy"}};
  }
  capture::writeFileAtomically(fs::path(dir) / "room.json", j.dump(2) + "\n");
}

RoomMesh loadRoom(const std::string& dir, RoomInfo* info) {
  quietOpen3d();
  const fs::path json = fs::path(dir) / "room.json", ply = fs::path(dir) / "room.ply";
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw capture::InputError(dir, "room folder is missing");
  if (!fs::is_regular_file(json, ec))
    throw capture::InputError(json.string(), "missing (not a room folder written by mrgi room)");
  const nlohmann::json j = capture::parseJson(
      capture::readFileBounded(json.string(), capture::kMaxTextFileBytes, "room description"), json.string());
  if (!j.is_object() || !j.contains("format") || !j["format"].is_string() ||
      j["format"].get<std::string>() != "mrgi-room")
    throw capture::InputError(json.string(), "format: not \"mrgi-room\"");
  if (!j.contains("version") || !j["version"].is_number_integer() || j["version"].get<int64_t>() < 1 ||
      j["version"].get<int64_t>() > 2)
    throw capture::InputError(json.string(), "version: only versions 1 and 2 are known");
  const int version = static_cast<int>(j["version"].get<int64_t>());
  RoomInfo ri;
  ri.options.voxelM = capture::jsonNumber(j, "voxel_m", json.string());
  ri.options.truncM = capture::jsonNumber(j, "trunc_m", json.string());
  ri.framesIntegrated = capture::jsonIntOr(j, "frames_integrated", 0, json.string());
  ri.framesRefused = capture::jsonIntOr(j, "frames_refused", 0, json.string());
  ri.session = capture::jsonStringOr(j, "session", std::string(), json.string());
  RoomOpenings openings;
  if (j.contains("openings")) {
    const nlohmann::json& o = j["openings"];
    if (!o.is_object() || !o.contains("cells") || !(o["cells"].is_null() || o["cells"] == "room_openings.npy"))
      throw capture::InputError(json.string(),
                                "\"openings\" must hold \"cell_m\" and \"cells\": \"room_openings.npy\"");
    openings.cellM = capture::jsonNumber(o, "cell_m", json.string());
    capture::checkNumber(openings.cellM, 0.01, 10, json.string(), "openings.cell_m");
    openings.recorded = true;
  }
  if (openings.recorded && !j["openings"]["cells"].is_null()) {
    const fs::path file = fs::path(dir) / "room_openings.npy";
    if (!fs::is_regular_file(file, ec)) throw capture::InputError(file.string(), "room openings are missing");
    const cv::Mat rows = capture::parseNpy(
        capture::readFileBounded(file.string(), capture::kMaxBinaryFileBytes, "room openings array"), file.string());
    if (rows.type() != CV_32FC1 || rows.cols != kOpeningColumns)
      throw capture::InputError(file.string(), "expected float32 (cells, 7)");
    std::vector<std::pair<cv::Vec3i, int>> order;
    for (int i = 0; i < rows.rows; ++i) {
      const float* r = rows.ptr<float>(i);
      for (int k = 0; k < kOpeningColumns; ++k)
        if (!std::isfinite(r[k]) || (k < 3 && (std::abs(r[k]) > (1 << 24) || r[k] != std::floor(r[k]))) ||
            (k >= 3 && r[k] < 0))
          throw capture::InputError(file.string(), "row " + std::to_string(i) + " is out of range");
      order.emplace_back(cv::Vec3i(static_cast<int>(r[0]), static_cast<int>(r[1]), static_cast<int>(r[2])), i);
    }
    std::sort(order.begin(), order.end(), [](const auto& a, const auto& b) { return cellLess(a.first, b.first); });
    for (size_t i = 0; i < order.size(); ++i) {
      if (i > 0 && order[i].first == order[i - 1].first) continue;  // each cell once
      const float* r = rows.ptr<float>(order[i].second);
      openings.cells.push_back(order[i].first);
      openings.radiance.emplace_back(r[3], r[4], r[5]);
      openings.clipped.push_back(r[6] > 0.5f ? 1 : 0);
    }
  }
  ri.options.validate(json.string());
  if (!fs::is_regular_file(ply, ec)) throw capture::InputError(ply.string(), "room mesh is missing");
  capture::checkPlyFile(ply.string());
  o3d::geometry::TriangleMesh m;
  o3d::io::ReadTriangleMeshOptions options;
  if (!o3d::io::ReadTriangleMesh(ply.string(), m, options))
    throw capture::InputError(ply.string(), "cannot read the room mesh (malformed or empty PLY)");
  if (m.vertices_.empty() || m.triangles_.empty()) throw capture::InputError(ply.string(), "room mesh is empty");
  // Every index checked before anything follows one (Open3D's normals would read past the vertices).
  for (size_t t = 0; t < m.triangles_.size(); ++t)
    for (int k = 0; k < 3; ++k) {
      const int i = m.triangles_[t][k];
      if (i < 0 || static_cast<size_t>(i) >= m.vertices_.size())
        throw capture::InputError(ply.string(), "triangle " + std::to_string(t) + " names vertex " + std::to_string(i) +
                                                    " of " + std::to_string(m.vertices_.size()));
    }
  RoomMesh out;
  const bool normals = m.HasVertexNormals() && m.vertex_normals_.size() == m.vertices_.size(),
             colours = m.HasVertexColors() && m.vertex_colors_.size() == m.vertices_.size();
  if (!normals) m.ComputeVertexNormals();
  for (size_t i = 0; i < m.vertices_.size(); ++i) {
    const auto& p = m.vertices_[i];
    const auto& n = m.vertex_normals_[i];
    if (!p.allFinite() || !n.allFinite())
      throw capture::InputError(ply.string(), "vertex " + std::to_string(i) + " is not finite");
    out.positions.emplace_back(static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2]));
    out.normals.emplace_back(static_cast<float>(n[0]), static_cast<float>(n[1]), static_cast<float>(n[2]));
    const Eigen::Vector3d c = colours ? m.vertex_colors_[i] : Eigen::Vector3d(0.5, 0.5, 0.5);
    out.radiance.emplace_back(static_cast<float>(capture::srgbToLinear(std::clamp(c[0], 0.0, 1.0))),
                              static_cast<float>(capture::srgbToLinear(std::clamp(c[1], 0.0, 1.0))),
                              static_cast<float>(capture::srgbToLinear(std::clamp(c[2], 0.0, 1.0))));
  }
  for (const auto& tri : m.triangles_)
    for (int k = 0; k < 3; ++k) out.indices.push_back(static_cast<uint32_t>(tri[k]));
  const size_t n = out.positions.size();
  if (version >= 2) {
    const fs::path npy = fs::path(dir) / "room_appearance.npy";
    if (!fs::is_regular_file(npy, ec)) throw capture::InputError(npy.string(), "room appearance is missing");
    const std::string bytes =
        capture::readFileBounded(npy.string(), capture::kMaxBinaryFileBytes, "room appearance array");
    const cv::Mat rows = capture::parseNpy(bytes, npy.string());
    if (rows.type() != CV_32FC1 || rows.cols != kAppearanceColumns || static_cast<size_t>(rows.rows) != n)
      throw capture::InputError(npy.string(), "expected float32 (" + std::to_string(n) + ", " +
                                                  std::to_string(kAppearanceColumns) + ") for the " +
                                                  std::to_string(n) + " vertices of room.ply");
    for (size_t i = 0; i < n; ++i) {
      const float* r = rows.ptr<float>(static_cast<int>(i));
      for (int k = 0; k < kAppearanceColumns; ++k)
        if (!std::isfinite(r[k]) || r[k] < 0)
          throw capture::InputError(npy.string(), "row " + std::to_string(i) + " holds a negative or non-finite value");
      out.radiance[i] = cv::Vec3f(r[0], r[1], r[2]);
      out.confidence.push_back(r[3]);
      out.saturated.push_back(r[4] > 0.5f ? 1 : 0);
    }
  } else {
    // Version 1: the PLY colour is all there is (8-bit, so clipped where it reads 250 or more).
    const float clip = static_cast<float>(capture::srgbToLinear(250 / 255.f));
    for (size_t i = 0; i < n; ++i) {
      out.confidence.push_back(1.f);
      out.saturated.push_back(std::max({out.radiance[i][0], out.radiance[i][1], out.radiance[i][2]}) >= clip ? 1 : 0);
    }
  }
  out.openings = std::move(openings);
  if (info) *info = ri;
  return out;
}

}  // namespace mrgi::reconstruction
