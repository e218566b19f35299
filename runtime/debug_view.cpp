#include "runtime/debug_view.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/colour.h"
#include "lighting/debug_views.h"
#include "reconstruction/light_estimation.h"

namespace mrgi::runtime {

std::vector<DebugView> debugViews(FramePipeline& frames) {
  std::vector<DebugView> out{Views::kComposite};
  const LightingSetup* setup = frames.setup();
  if (!setup) return out;
  out.insert(out.end(),
             {Views::kDelta, Views::kAlbedo, Views::kNormal, Views::kMask, Views::kRsmFlux, Views::kRsmNormal});
  if (const lighting::LightingPipeline* pipe = frames.lighting())
    for (const auto& t : pipe->techniques())
      for (const std::string& v : t->debugViews()) out.push_back(v);
  if (setup->fisheye) out.push_back(Views::kFisheye);
  // A room being fused has its views before its first surface (they show nothing until then).
  if (frames.roomLights() || setup->scene.lightSource == lighting::LightSource::Room) out.push_back(Views::kRoomLights);
  if (frames.room() || frames.liveRoom()) out.insert(out.end(), {Views::kRoomRadiance, Views::kRoomAlbedo});
  return out;
}

cv::Mat roomSeenFrom(const reconstruction::MeshRays& rays, const reconstruction::RoomMesh& room,
                     const std::vector<cv::Vec3f>& values, const capture::Intrinsics& k,
                     const capture::Pose& T_world_camera, cv::Mat* hitMask) {
  CV_Assert(values.size() == room.positions.size());
  cv::Mat out(k.height, k.width, CV_32FC3, cv::Scalar::all(0)), mask(k.height, k.width, CV_8U, cv::Scalar(0));
  const cv::Vec3d o = capture::translationOf(T_world_camera);
  const cv::Matx33d R = capture::rotationOf(T_world_camera);
  cv::parallel_for_(cv::Range(0, k.height), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y)
      for (int x = 0; x < k.width; ++x) {
        const cv::Vec3d d = cv::normalize(R * cv::Vec3d((x + 0.0 - k.cx) / k.fx, (y + 0.0 - k.cy) / k.fy, 1.0));
        const reconstruction::MeshRays::Hit h = rays.intersect(o, d);
        if (!h.hit) continue;
        const uint32_t* t = &room.indices[3 * static_cast<size_t>(h.triangle)];
        const float u = static_cast<float>(h.u), v = static_cast<float>(h.v);
        out.at<cv::Vec3f>(y, x) = (1 - u - v) * values[t[0]] + u * values[t[1]] + v * values[t[2]];
        mask.at<uchar>(y, x) = 255;
      }
  });
  if (hitMask) *hitMask = mask;
  return out;
}

cv::Point latLongPixel(const cv::Vec3d& d, cv::Size size) {
  const double theta = std::acos(std::clamp(d[2], -1.0, 1.0)), phi = std::atan2(d[1], d[0]);
  return {static_cast<int>(std::fmod(phi + 2 * CV_PI, 2 * CV_PI) / (2 * CV_PI) * size.width),
          static_cast<int>(theta / CV_PI * size.height)};
}

cv::Mat roomLightsImage(const reconstruction::RoomLights& l) {
  cv::Mat view = l.environment.clone();
  std::vector<double> lum;
  for (int i = 0; i < static_cast<int>(view.total()); ++i)
    lum.push_back(capture::luminance(cv::Vec3d(view.at<cv::Vec3f>(i))));
  const double p99 = lighting::percentile99(lum);
  if (p99 > 0) view *= 0.8 / p99;
  cv::Mat out = capture::encodeSrgb(view);
  for (const auto& light : l.lights) {
    cv::circle(out, latLongPixel(light.direction, out.size()), 6,
               light.saturatedFraction > 0.5 ? cv::Scalar(255, 128, 0) : cv::Scalar(0, 200, 255), 2, cv::LINE_AA);
  }
  return out;
}

namespace {

cv::Mat virtualMask(lighting::LightingPipeline& pipe) {
  cv::Mat albedo = pipe.downloadGBuffer(2), mask;
  cv::extractChannel(albedo, mask, 3);
  mask.convertTo(mask, CV_8U, 255);
  return mask;
}

/// Linear HDR (or 8-bit sRGB) fisheye image -> RGB8, exposed so the 99th percentile maps to white.
cv::Mat toneMapped(const cv::Mat& image) {
  if (image.depth() == CV_8U) return image.clone();
  cv::Mat lum;
  cv::cvtColor(image, lum, cv::COLOR_RGB2GRAY);
  std::vector<double> v(lum.begin<float>(), lum.end<float>());
  return lighting::linearImage(image, 1.0 / lighting::percentile99(v));
}

}  // namespace

cv::Mat renderDebugView(const DebugView& v, FramePipeline& frames, const FrameResult& r, const capture::Intrinsics& k,
                        const cv::Mat& fisheyeImage, nlohmann::json* info) {
  nlohmann::json scratch;
  nlohmann::json& out = info ? *info : scratch;
  if (v == Views::kComposite) return r.composite;
  const LightingSetup* setup = frames.setup();
  if (v == Views::kFisheye) {
    if (!setup || !setup->fisheye || fisheyeImage.empty()) return {};
    cv::Mat img = toneMapped(fisheyeImage);
    // Median-cut lights (marker frame, travel direction) back into the fisheye camera.
    const capture::Pose T_world_fisheye = setup->fisheye->T_world_fisheye.value_or(capture::identityPose());
    const capture::Pose T_marker_world =
        setup->T_world_marker ? capture::inversePose(*setup->T_world_marker) : capture::identityPose();
    const cv::Matx33d R_fisheye_marker = capture::rotationOf(T_marker_world * T_world_fisheye).t();
    std::vector<cv::Vec3d> dirs;
    std::vector<double> power;
    for (const auto& l : setup->lights) {
      if (l.type != lighting::LightType::Directional) continue;
      dirs.push_back(-(R_fisheye_marker * l.direction));
      power.push_back(capture::luminance(l.irradiance));
    }
    const double maxPower = power.empty() ? 1.0 : *std::max_element(power.begin(), power.end());
    for (size_t i = 0; i < dirs.size(); ++i) {
      if (dirs[i][2] <= 1e-6) continue;  // behind the lens
      std::vector<cv::Point3d> obj{cv::Point3d(dirs[i][0], dirs[i][1], dirs[i][2])};
      std::vector<cv::Point2d> px;
      cv::fisheye::projectPoints(obj, px, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), setup->fisheye->K, setup->fisheye->D);
      const double scale = static_cast<double>(img.cols) / std::max(setup->fisheye->width, 1);
      const int radius = 3 + static_cast<int>(12.0 * std::sqrt(power[i] / std::max(maxPower, 1e-12)));
      cv::circle(img, px[0] * scale, radius, cv::Scalar(255, 40, 40), 2, cv::LINE_AA);
    }
    out["debug_fisheye_lights"] = dirs.size();
    return img;
  }
  if (v == Views::kRoomLights) return frames.roomLights() ? roomLightsImage(*frames.roomLights()) : cv::Mat();
  if (v == Views::kRoomRadiance || v == Views::kRoomAlbedo) {
    // What the room holds where this camera looks; unscanned directions dark blue.
    const reconstruction::RoomMesh* room = frames.room();
    if (!room || !r.T_marker_camera) return {};
    const bool radiance = v == Views::kRoomRadiance;
    if (!radiance && frames.roomAlbedo().size() != room->positions.size()) return {};
    cv::Mat hit;
    cv::Mat linear = roomSeenFrom(frames.roomRays(), *room, radiance ? room->radiance : frames.roomAlbedo(), k,
                                  *r.T_marker_camera, &hit);
    if (radiance) linear *= r.exposure;
    cv::Mat img = capture::encodeSrgb(linear);
    img.setTo(cv::Scalar(30, 30, 70), ~hit);
    out[radiance ? "debug_room_radiance_coverage" : "debug_room_albedo_coverage"] =
        cv::countNonZero(hit) / static_cast<double>(hit.total());
    return img;
  }
  lighting::LightingPipeline* pipe = frames.lighting();
  if (!r.lit || !pipe) return {};
  if (v == Views::kDelta) {
    double scale = 0;
    cv::Mat img = lighting::signedImage(pipe->downloadShade(), scale);
    img.setTo(cv::Scalar(40, 40, 90), virtualMask(*pipe));  // the object itself: dark blue
    out["debug_delta_scale"] = scale;
    return img;
  }
  if (v == Views::kAlbedo) return lighting::linearImage(pipe->downloadGBuffer(2));
  if (v == Views::kNormal) return lighting::normalImage(pipe->downloadGBuffer(1));
  if (v == Views::kMask) return virtualMask(*pipe);
  if (v == Views::kRsmFlux) {
    double scale = 0;
    cv::Mat img = lighting::signedImage(pipe->downloadRsm(true).flux, scale);
    out["debug_rsm_scale"] = scale;
    return img;
  }
  if (v == Views::kRsmNormal) return lighting::normalImage(pipe->downloadRsm(true).normal);
  // A technique's own view.
  lighting::DebugContext context;
  context.composite = r.composite;
  context.intrinsics = k;
  context.T_world_camera = r.T_marker_camera;
  for (const auto& t : pipe->techniques()) {
    const auto names = t->debugViews();
    if (std::find(names.begin(), names.end(), v) != names.end()) return t->debugImage(v, context, out);
  }
  return {};
}

std::array<cv::Point2f, 4> markerAxesPixels(const capture::Intrinsics& k, const capture::Pose& T_marker_camera,
                                            double length) {
  const capture::Pose T = capture::inversePose(T_marker_camera);
  std::array<cv::Point2f, 4> out;
  const cv::Vec3d ends[4] = {{0, 0, 0}, {length, 0, 0}, {0, length, 0}, {0, 0, length}};
  for (int i = 0; i < 4; ++i) {
    const cv::Vec3d p = capture::transformPoint(T, ends[i]);
    const double z = std::max(p[2], 1e-6);
    out[static_cast<size_t>(i)] =
        cv::Point2f(static_cast<float>(k.fx * p[0] / z + k.cx), static_cast<float>(k.fy * p[1] / z + k.cy));
  }
  return out;
}

void drawMarkerAxes(cv::Mat& rgb, const capture::Intrinsics& k, const capture::Pose& T_marker_camera, double length) {
  // The live window draws the same pixels over its GPU image (markerAxesPixels); here onto the RGB image.
  const std::array<cv::Point2f, 4> p = markerAxesPixels(k, T_marker_camera, length);
  const cv::Scalar colours[3] = {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}};  // x red, y green, z blue (RGB)
  for (int i = 0; i < 3; ++i) cv::line(rgb, p[0], p[static_cast<size_t>(i) + 1], colours[i], 2);
}

}  // namespace mrgi::runtime
