#include "runtime/room_preview.h"

#include <algorithm>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "capture/colour.h"
#include "lighting/debug_views.h"
#include "reconstruction/distant_lights.h"
#include "reconstruction/mesh_rays.h"
#include "reconstruction/room_lights.h"
#include "runtime/debug_view.h"

namespace mrgi::runtime {

namespace {

void label(cv::Mat& img, const std::string& text, cv::Point at, double scale = 0.45) {
  cv::putText(img, text, at, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
  cv::putText(img, text, at, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
}

/// The values seen from a camera as RGB8: scaled so that the 99th percentile of what was hit reads 0.8
/// (`scale` 0: found here), dark blue where nothing was.
cv::Mat view(const reconstruction::MeshRays& rays, const reconstruction::RoomMesh& room,
             const std::vector<cv::Vec3f>& values, const capture::Intrinsics& k, const capture::Pose& T, double scale) {
  cv::Mat hit;
  cv::Mat linear = roomSeenFrom(rays, room, values, k, T, &hit);
  if (scale <= 0) {
    std::vector<double> lum;
    for (int y = 0; y < linear.rows; ++y)
      for (int x = 0; x < linear.cols; ++x)
        if (hit.at<uchar>(y, x)) lum.push_back(capture::luminance(cv::Vec3d(linear.at<cv::Vec3f>(y, x))));
    const double p = lum.empty() ? 0.0 : lighting::percentile99(lum);
    scale = p > 0 ? 0.8 / p : 1.0;
  }
  cv::Mat img = capture::encodeSrgb(linear * scale);
  img.setTo(cv::Scalar(30, 30, 70), ~hit);
  return img;
}

}  // namespace

cv::Mat roomPreview(const reconstruction::RoomMesh& room, const std::optional<capture::Pose>& T_world_camera,
                    const capture::Intrinsics& k, const RoomPreviewOptions& o, double* coverage) {
  const int W = std::max(64, o.width), H = W * 3 / 4;
  const reconstruction::MeshRays rays(room.positions, room.indices);
  reconstruction::RoomLightOptions lo;
  lo.split.medianCut.count = o.lightCount;
  lo.findDistant = true;
  const reconstruction::RoomLights lights = reconstruction::estimateRoomLights(room, o.at, lo, &rays);
  if (coverage) *coverage = lights.coverage;

  // The albedo under the room's own lights and the light it sends itself (as the frame pipeline takes it).
  const reconstruction::RoomAlbedo albedo = reconstruction::albedoUnderRoomLights(room, lights, o.at, rays);

  // Cameras: the recording's first (scaled to the view's size), and one 1.5 m from the object's place at 55
  // degrees above it, on the first camera's side, brought inside the room where its ceiling or a wall is nearer.
  cv::Vec3d side(1, 0, 0);
  if (T_world_camera) {
    const cv::Vec3d c = capture::translationOf(*T_world_camera) - o.at;
    if (std::hypot(c[0], c[1]) > 1e-3) side = cv::normalize(cv::Vec3d(c[0], c[1], 0));
  }
  const double elevation = 55 * CV_PI / 180;
  const cv::Vec3d up = side * std::cos(elevation) + cv::Vec3d(0, 0, std::sin(elevation));
  double distance = 1.5;
  if (const auto h = rays.intersect(o.at, up, distance); h.hit) distance = 0.9 * h.t;
  const cv::Vec3d eye = o.at + up * std::max(distance, 0.3);
  std::vector<std::pair<std::string, std::pair<capture::Intrinsics, capture::Pose>>> cameras;
  if (T_world_camera && k.valid()) {
    const double s = static_cast<double>(W) / k.width;
    cameras.push_back({"first frame's camera", {{W, H, k.fx * s, k.fy * s, k.cx * s, k.cy * s}, *T_world_camera}});
  }
  const double f = 0.5 * W / std::tan(35 * CV_PI / 180);  // 70 degrees across
  cameras.push_back(
      {"from above", {{W, H, f, f, (W - 1) / 2.0, (H - 1) / 2.0}, capture::lookAtPose(eye, o.at, {0, 0, 1})}});

  std::vector<cv::Mat> rows;
  for (const auto& [name, cam] : cameras) {
    cv::Mat r = view(rays, room, room.radiance, cam.first, cam.second, 0);
    cv::Mat a = view(rays, room, albedo.albedo, cam.first, cam.second, 1.0);
    label(r, "radiance, " + name, {6, 18});
    label(a, "albedo, " + name, {6, 18});
    cv::Mat row;
    cv::hconcat(r, a, row);
    rows.push_back(row);
  }
  // A light found from the room's shadow edges: the surfaces it lights (the sunlit patches that justify it) in
  // yellow over the room's radiance dimmed, from the same cameras.
  if (lights.distant) {
    const cv::Vec3d w = lights.distant->towards;
    const reconstruction::DistantLightRays reach(room.positions, rays, &room.openings);
    std::vector<double> lum;
    for (const auto& r : room.radiance) lum.push_back(capture::luminance(cv::Vec3d(r)));
    const float top = static_cast<float>(lum.empty() ? 1.0 : std::max(lighting::percentile99(lum), 1e-6));
    std::vector<cv::Vec3f> patches(room.positions.size());
    for (size_t i = 0; i < patches.size(); ++i) {
      const bool lit = reach.lightOn(cv::Vec3d(room.positions[i]), cv::Vec3d(room.normals[i]), w) > 0;
      patches[i] = lit ? cv::Vec3f(1.0f, 0.85f, 0.2f) * top : room.radiance[i] * 0.35f;
    }
    std::vector<cv::Mat> views;
    for (const auto& [name, cam] : cameras) {
      cv::Mat v = view(rays, room, patches, cam.first, cam.second, 0.8 / top);
      label(v, "lit by light " + std::to_string(lights.lights.size()) + ", " + name, {6, 18});
      views.push_back(v);
    }
    if (views.size() == 1) views.push_back(cv::Mat(views[0].size(), views[0].type(), cv::Scalar(20, 20, 20)));
    cv::Mat row;
    cv::hconcat(views, row);
    rows.push_back(row);
  }
  // The environment at the object: the map at the views' width, then one line per light.
  cv::Mat env = roomLightsImage(lights);
  cv::resize(env, env, cv::Size(2 * W, W), 0, 0, cv::INTER_NEAREST);
  const double sx = static_cast<double>(env.cols) / lights.environment.cols;
  char line[200];
  for (size_t i = 0; i < lights.lights.size(); ++i) {
    const cv::Point p = latLongPixel(lights.lights[i].direction, env.size());
    cv::circle(env, p, static_cast<int>(6 * sx), cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
    label(env, std::to_string(i + 1), {p.x + static_cast<int>(7 * sx), p.y - 4});
  }
  std::snprintf(line, sizeof line, "the room at (%.2f, %.2f, %.2f): covers %.0f %% of the directions", o.at[0], o.at[1],
                o.at[2], 100 * lights.coverage);
  label(env, line, {6, 18});
  cv::Mat legend(22 * static_cast<int>(lights.lights.size() + 1), env.cols, CV_8UC3, cv::Scalar(20, 20, 20));
  for (size_t i = 0; i < lights.lights.size(); ++i) {
    const auto& l = lights.lights[i];
    if (l.distant && lights.distant)
      std::snprintf(line, sizeof line,
                    "%zu: distant towards (%.2f, %.2f, %.2f), irradiance %.3g%s: unseen, from %d shadow edges", i + 1,
                    l.direction[0], l.direction[1], l.direction[2], capture::luminance(l.irradiance),
                    lights.distant->atLeast() ? " at least" : "", lights.distant->edges);
    else if (l.point)
      std::snprintf(line, sizeof line, "%zu: point at (%.2f, %.2f, %.2f), irradiance %.3g%s", i + 1, l.position[0],
                    l.position[1], l.position[2], capture::luminance(l.irradiance),
                    l.saturatedFraction > 0.5 ? " (clipped: its gain estimated)" : "");
    else
      std::snprintf(line, sizeof line, "%zu: directional towards (%.2f, %.2f, %.2f), irradiance %.3g", i + 1,
                    l.direction[0], l.direction[1], l.direction[2], capture::luminance(l.irradiance));
    label(legend, line, {6, 16 + 22 * static_cast<int>(i)});
  }
  std::snprintf(line, sizeof line, "and an SH remainder of mean radiance %.3g",
                capture::luminance(lights.ambientRadiance));
  label(legend, line, {6, 16 + 22 * static_cast<int>(lights.lights.size())});
  rows.push_back(env);
  rows.push_back(legend);
  cv::Mat out;
  cv::vconcat(rows, out);
  return out;
}

}  // namespace mrgi::runtime
