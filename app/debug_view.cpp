#include "app/debug_view.h"

#include <algorithm>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/colour.h"
#include "lighting/debug_views.h"
#include "reconstruction/light_estimation.h"

namespace mrgi::app {

const char* debugViewName(DebugView v) {
  switch (v) {
    case DebugView::Composite: return "composite";
    case DebugView::Delta: return "delta";
    case DebugView::Albedo: return "gbuffer_albedo";
    case DebugView::Normal: return "gbuffer_normal";
    case DebugView::Mask: return "gbuffer_mask";
    case DebugView::RsmFlux: return "rsm_flux";
    case DebugView::RsmNormal: return "rsm_normal";
    case DebugView::Volume: return "dlpv_slices";
    case DebugView::ValIrradiance: return "val_irradiance";
    case DebugView::SparsePoints: return "val_sparse_points";
    case DebugView::Fisheye: return "fisheye_lights";
  }
  return "?";
}

std::vector<DebugView> debugViews(const LightingSetup* setup) {
  std::vector<DebugView> out{DebugView::Composite};
  if (!setup) return out;
  out.insert(out.end(), {DebugView::Delta, DebugView::Albedo, DebugView::Normal, DebugView::Mask, DebugView::RsmFlux,
                         DebugView::RsmNormal});
  if (lighting::usesLpv(setup->scene.technique)) out.push_back(DebugView::Volume);
  if (lighting::usesVal(setup->scene.technique)) out.insert(out.end(), {DebugView::ValIrradiance, DebugView::SparsePoints});
  if (setup->fisheye) out.push_back(DebugView::Fisheye);
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
  std::vector<float> v(lum.begin<float>(), lum.end<float>());
  std::nth_element(v.begin(), v.begin() + v.size() * 99 / 100, v.end());
  const double p99 = std::max(1e-9, static_cast<double>(v[v.size() * 99 / 100]));
  return lighting::linearImage(image, 1.0 / p99);
}

}  // namespace

cv::Mat renderDebugView(DebugView v, FramePipeline& frames, const FrameResult& r, const capture::Intrinsics& k,
                        const cv::Mat& fisheyeImage,
                        nlohmann::json* info) {
  nlohmann::json scratch;
  nlohmann::json& out = info ? *info : scratch;
  if (v == DebugView::Composite) return r.composite;
  const LightingSetup* setup = frames.setup();
  if (v == DebugView::Fisheye) {
    if (!setup || !setup->fisheye || fisheyeImage.empty()) return {};
    cv::Mat img = toneMapped(fisheyeImage);
    // Median-cut lights (marker frame, travel direction) back into the fisheye camera.
    const capture::Pose T_world_fisheye = setup->fisheye->T_world_fisheye.value_or(capture::identityPose());
    const capture::Pose T_marker_world = setup->T_world_marker ? capture::inversePose(*setup->T_world_marker) : capture::identityPose();
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
  lighting::LightingPipeline* pipe = frames.lighting();
  if (!r.lit || !pipe) return {};
  switch (v) {
    case DebugView::Delta: {
      double scale = 0;
      cv::Mat img = lighting::signedImage(pipe->downloadShade(), scale);
      img.setTo(cv::Scalar(40, 40, 90), virtualMask(*pipe));  // the object itself: dark blue
      out["debug_delta_scale"] = scale;
      return img;
    }
    case DebugView::Albedo: return lighting::linearImage(pipe->downloadGBuffer(2));
    case DebugView::Normal: return lighting::normalImage(pipe->downloadGBuffer(1));
    case DebugView::Mask: return virtualMask(*pipe);
    case DebugView::RsmFlux: {
      double scale = 0;
      cv::Mat img = lighting::signedImage(pipe->downloadRsm(true).flux, scale);
      out["debug_rsm_scale"] = scale;
      return img;
    }
    case DebugView::RsmNormal: return lighting::normalImage(pipe->downloadRsm(true).normal);
    case DebugView::Volume: {
      if (!lighting::usesLpv(setup->scene.technique) || !pipe->grid()) return {};
      double scale = 0;
      const auto vol = pipe->downloadVolume(setup->scene.technique == lighting::Technique::LpvDiff ? "rho_full" : "delta");
      cv::Mat img = lighting::volumeSlices(vol, 4, 4, scale);
      out["debug_volume_scale"] = scale;
      return img;
    }
    case DebugView::ValIrradiance: {
      if (!lighting::usesVal(setup->scene.technique)) return {};
      // Bounce irradiance the virtual object receives, on a linear scale.
      cv::Mat rgb, lum;
      cv::cvtColor(pipe->downloadIrradiance(), rgb, cv::COLOR_RGBA2RGB);
      cv::cvtColor(rgb, lum, cv::COLOR_RGB2GRAY);
      const cv::Mat mask = virtualMask(*pipe);
      double lo = 0, hi = 0;
      cv::minMaxLoc(lum, &lo, &hi, nullptr, nullptr, mask);
      rgb.setTo(cv::Scalar::all(0), mask == 0);  // real pixels carry their delta in this target
      out["debug_val_irradiance_max"] = hi;
      return lighting::linearImage(rgb, hi > 0 ? 1.0 / hi : 0.0);
    }
    case DebugView::SparsePoints: {
      if (!lighting::usesVal(setup->scene.technique) || !r.T_marker_camera) return {};
      cv::Mat img = r.composite.clone();
      std::vector<cv::Vec3f> E, S;
      pipe->downloadValSums(E, S);
      double maxE = 1e-12;
      for (const auto& e : E) maxE = std::max(maxE, capture::luminance(cv::Vec3d(e)));
      const capture::Pose T_camera_marker = capture::inversePose(*r.T_marker_camera);
      size_t at = 0;
      for (size_t oi = 0; oi < setup->scene.objects.size(); ++oi) {
        const auto& pts = pipe->sparsePoints(oi);
        const capture::Pose T = T_camera_marker * setup->scene.objects[oi].T_marker_object;
        for (size_t i = 0; i < pts.positions.size(); ++i, ++at) {
          const cv::Vec3d c = capture::transformPoint(T, cv::Vec3d(pts.positions[i]));
          const cv::Vec3d n = capture::rotationOf(T) * cv::Vec3d(pts.normals[i]);
          if (c[2] <= 0 || n.dot(c) > 0) continue;  // behind the camera or on the far side of the object
          const double e = at < E.size() ? capture::luminance(cv::Vec3d(E[at])) / maxE : 0.0;
          const auto g = cv::saturate_cast<uchar>(255.0 * std::sqrt(e));
          cv::circle(img, cv::Point2d(k.fx * c[0] / c[2] + k.cx, k.fy * c[1] / c[2] + k.cy), 2, cv::Scalar(g, g, 255 - g),
                     cv::FILLED, cv::LINE_AA);
        }
      }
      out["debug_sparse_points"] = at;
      return img;
    }
    default: return {};
  }
}

void drawMarkerAxes(cv::Mat& rgb, const capture::Intrinsics& k, const capture::Pose& T_marker_camera, double length) {
  const capture::Pose T = capture::inversePose(T_marker_camera);
  cv::Mat R(3, 3, CV_64F), rvec;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) R.at<double>(i, j) = T(i, j);
  cv::Rodrigues(R, rvec);
  const cv::Vec3d tvec(T(0, 3), T(1, 3), T(2, 3));
  const cv::Matx33d K(k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
  // drawFrameAxes draws x in red for BGR images; the camera image is RGB, so draw on a BGR copy.
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  cv::drawFrameAxes(bgr, K, cv::noArray(), rvec, tvec, static_cast<float>(length), 2);
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
}

}  // namespace mrgi::app
