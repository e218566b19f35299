#include "reconstruction/pose_graph.h"

#include <open3d/core/Tensor.h>
#include <open3d/pipelines/registration/GlobalOptimization.h>
#include <open3d/pipelines/registration/PoseGraph.h>
#include <open3d/t/geometry/PointCloud.h>
#include <open3d/t/pipelines/registration/Registration.h>
#include <open3d/utility/Logging.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <deque>

#include "reconstruction/marker.h"
#include "reconstruction/open3d_pose.h"

namespace mrgi::reconstruction {

namespace o3c = open3d::core;
namespace o3r = open3d::pipelines::registration;

namespace {

/// The finite vertices of a vertex map (CV_32FC3, NaN = none) as an Open3D point cloud.
open3d::t::geometry::PointCloud cloudOf(const cv::Mat& vertices) {
  std::vector<float> xyz;
  xyz.reserve(vertices.total() * 3);
  for (int y = 0; y < vertices.rows; ++y) {
    const auto* v = vertices.ptr<cv::Vec3f>(y);
    for (int x = 0; x < vertices.cols; ++x)
      if (std::isfinite(v[x][2])) xyz.insert(xyz.end(), {v[x][0], v[x][1], v[x][2]});
  }
  const int64_t n = static_cast<int64_t>(xyz.size() / 3);
  o3c::Tensor t({n, 3}, o3c::Float32);
  if (n > 0) std::memcpy(t.GetDataPtr(), xyz.data(), xyz.size() * sizeof(float));
  return open3d::t::geometry::PointCloud(t);
}

}  // namespace

struct TrajectoryOptimiser::Impl {
  struct Kept {
    size_t index;
    OdometryFrame frame;
    capture::Pose T_world_camera;
    open3d::t::geometry::PointCloud cloud;
  };
  struct Edge {
    size_t source, target;  ///< frame indices; target == kWorld: the world node
    capture::Pose T_target_source;
    Eigen::Matrix<double, 6, 6> information;
    bool loop;  ///< a loop closure (uncertain, as marker sightings are)
  };
  static constexpr size_t kWorld = static_cast<size_t>(-1);

  std::vector<TrajectoryFrame> frames;
  std::deque<Kept> window;
  std::vector<Kept> loops;
  std::vector<Edge> edges;
  size_t posed = 0;
  int refused = 0;
};

TrajectoryOptimiser::TrajectoryOptimiser(const TrajectoryOptions& options)
    : o_(options), impl_(std::make_unique<Impl>()) {}
TrajectoryOptimiser::~TrajectoryOptimiser() = default;

void TrajectoryOptimiser::add(const OdometryFrame& frame, const TrajectoryFrame& poses) {
  Impl& s = *impl_;
  const size_t index = s.frames.size();
  s.frames.push_back(poses);
  if (!poses.T_world_camera) return;
  const capture::Pose& T = *poses.T_world_camera;
  if (poses.markerT_world_camera) {
    Eigen::Matrix<double, 6, 6> info = Eigen::Matrix<double, 6, 6>::Zero();
    const double sr = o_.markerSigmaDeg * M_PI / 180.0;
    for (int i = 0; i < 3; ++i)
      info(i, i) = 1.0 / (sr * sr), info(i + 3, i + 3) = 1.0 / (o_.markerSigmaM * o_.markerSigmaM);
    s.edges.push_back({index, Impl::kWorld, *poses.markerT_world_camera, info, true});
  }
  const int level = std::min(o_.informationLevel, frame.levels() - 1);
  Impl::Kept kept{index, frame, T, cloudOf(frame.vertices(level))};
  // An edge from an alignment with an earlier frame, when the quality gate takes it.
  const auto align = [&](const Impl::Kept& target, bool loop) {
    const capture::Pose init = capture::inversePose(target.T_world_camera) * T;
    const OdometryResult r = estimateOdometry(frame, target.frame, init, o_.odometry);
    if (!r.solved || r.fitness < o_.minFitness || r.inlierRmse > o_.maxRmseM || kept.cloud.IsEmpty() ||
        target.cloud.IsEmpty()) {
      ++s.refused;
      return;
    }
    const o3c::Tensor info = open3d::t::pipelines::registration::GetInformationMatrix(
        kept.cloud, target.cloud, o_.informationDistanceM, poseTensor(r.T_target_source));
    const o3c::Tensor c = info.To(o3c::Float64).Contiguous();
    Eigen::Matrix<double, 6, 6> m;
    const double* p = c.GetDataPtr<double>();
    for (int i = 0; i < 36; ++i) m(i / 6, i % 6) = p[i];
    // Open3D's matrix counts correspondences (its translation block is their number times the identity):
    // scaled so that the edge's translation spread is odometrySigmaM, its shape (which motions the view's
    // geometry holds and which it lets slide) kept.
    if (!(m(3, 3) > 0) || !m.allFinite()) {
      ++s.refused;
      return;
    }
    m *= 1.0 / (m(3, 3) * o_.odometrySigmaM * o_.odometrySigmaM);
    s.edges.push_back({index, target.index, r.T_target_source, m, loop});
  };
  for (auto it = s.window.rbegin(); it != s.window.rend(); ++it) align(*it, false);
  // Loop closures: kept frames older than the window whose pose lies near, nearest first.
  std::vector<std::pair<double, const Impl::Kept*>> near;
  const size_t oldest = s.window.empty() ? index : s.window.front().index;
  for (const auto& k : s.loops) {
    if (k.index >= oldest) continue;
    const double d = translationError(k.T_world_camera, T), a = rotationErrorDeg(k.T_world_camera, T);
    if (d <= o_.loopDistanceM && a <= o_.loopAngleDeg) near.emplace_back(d + a * M_PI / 180.0, &k);
  }
  std::sort(near.begin(), near.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  for (size_t i = 0; i < near.size() && static_cast<int>(i) < o_.maxLoopsPerFrame; ++i) align(*near[i].second, true);

  if (o_.loopEvery > 0 && s.posed % static_cast<size_t>(o_.loopEvery) == 0) s.loops.push_back(kept);
  s.window.push_back(std::move(kept));
  while (static_cast<int>(s.window.size()) > o_.window) s.window.pop_front();
  ++s.posed;
}

TrajectoryResult TrajectoryOptimiser::optimise() const {
  const Impl& s = *impl_;
  TrajectoryResult out;
  out.T_world_camera.resize(s.frames.size());
  out.refusedAlignments = s.refused;
  bool world = false;
  for (const auto& e : s.edges) {
    world |= e.target == Impl::kWorld;
    (e.target == Impl::kWorld ? out.markerEdges : e.loop ? out.loopEdges : out.odometryEdges)++;
  }
  o3r::PoseGraph graph;
  std::vector<int> node(s.frames.size(), -1);
  if (world) graph.nodes_.emplace_back(Eigen::Matrix4d::Identity());
  for (size_t i = 0; i < s.frames.size(); ++i)
    if (s.frames[i].T_world_camera) {
      node[i] = static_cast<int>(graph.nodes_.size());
      graph.nodes_.emplace_back(toEigen(*s.frames[i].T_world_camera));
    }
  if (graph.nodes_.empty()) return out;
  for (const auto& e : s.edges)
    graph.edges_.emplace_back(node[e.source], e.target == Impl::kWorld ? 0 : node[e.target], toEigen(e.T_target_source),
                              e.information, e.loop || e.target == Impl::kWorld, 1.0);
  const size_t before = graph.edges_.size();
  if (!graph.edges_.empty()) {
    open3d::utility::SetVerbosityLevel(open3d::utility::VerbosityLevel::Error);
    // The line process weighs an uncertain edge (a loop closure) by (mu / (mu + e))^2, e its squared residual
    // in its information's units and mu = d^2 times the edges' mean translation information, and prunes it
    // below 0.25: with information 1 / sigma^2, a loop closure more than about d off the rest is pruned.
    const o3r::GlobalOptimizationOption option(0.01, 0.25, 1.0, 0);
    o3r::GlobalOptimization(graph, o3r::GlobalOptimizationLevenbergMarquardt(),
                            o3r::GlobalOptimizationConvergenceCriteria(), option);
  }
  out.prunedEdges = static_cast<int>(before - graph.edges_.size());
  double sum = 0;
  int n = 0;
  for (size_t i = 0; i < s.frames.size(); ++i) {
    if (node[i] < 0) continue;
    capture::Pose T = fromEigen(graph.nodes_[static_cast<size_t>(node[i])].pose_);
    if (world) T = capture::inversePose(fromEigen(graph.nodes_[0].pose_)) * T;  // the world node held at identity
    const double shift = translationError(T, *s.frames[i].T_world_camera);
    sum += shift, ++n;
    out.maxShiftM = std::max(out.maxShiftM, shift);
    out.T_world_camera[i] = T;
  }
  out.meanShiftM = n ? sum / n : 0.0;
  return out;
}

}  // namespace mrgi::reconstruction
