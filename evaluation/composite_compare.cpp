#include "evaluation/composite_compare.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/checks.h"
#include "capture/colour.h"
#include "capture/error.h"
#include "capture/image_io.h"
#include "capture/json_io.h"

namespace fs = std::filesystem;

namespace mrgi::evaluation {
namespace {

/// An 8-bit sRGB image (RGB) in linear light, CV_32FC3.
cv::Mat linearOf(const std::string& path) {
  const cv::Mat rgb = capture::readColour(path);
  float lut[256];
  for (int i = 0; i < 256; ++i) lut[i] = static_cast<float>(capture::srgbToLinear(i / 255.f));
  cv::Mat out(rgb.size(), CV_32FC3);
  for (int y = 0; y < rgb.rows; ++y)
    for (int x = 0; x < rgb.cols; ++x) {
      const cv::Vec3b v = rgb.at<cv::Vec3b>(y, x);
      out.at<cv::Vec3f>(y, x) = {lut[v[0]], lut[v[1]], lut[v[2]]};
    }
  return out;
}

double lum(const cv::Vec3f& c) { return capture::luminance(cv::Vec3d(c)); }

std::string frameName(const char* pattern, int i) {
  char name[64];
  std::snprintf(name, sizeof name, pattern, i);
  return name;
}

/// The luminance-weighted centroid of the brightest fifth of `image`'s pixels under `mask`.
cv::Point2d brightestSide(const cv::Mat& image, const std::vector<cv::Point>& pixels) {
  std::vector<double> l;
  for (const cv::Point& p : pixels) l.push_back(lum(image.at<cv::Vec3f>(p)));
  std::vector<double> sorted = l;
  const size_t q = sorted.size() * 4 / 5;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(q), sorted.end());
  const double cut = sorted[q];
  cv::Point2d sum(0, 0);
  double w = 0;
  for (size_t i = 0; i < pixels.size(); ++i)
    if (l[i] >= cut) sum += cv::Point2d(pixels[i]) * l[i], w += l[i];
  return w > 0 ? sum / w : cv::Point2d(0, 0);
}

}  // namespace

std::vector<ComposedFrame> compareComposites(const std::string& session, const std::string& replay) {
  const fs::path summaryPath = fs::path(replay) / "summary.json";
  const nlohmann::json summary =
      capture::parseJson(capture::readFileBounded(summaryPath.string(), capture::kMaxTextFileBytes, "replay summary"),
                         summaryPath.string());
  if (!summary.is_object() || !summary.contains("per_frame") || !summary["per_frame"].is_array())
    throw capture::CaptureError(summaryPath.string(), "no \"per_frame\" list (not a replay's summary)");
  std::vector<ComposedFrame> out;
  for (const nlohmann::json& f : summary["per_frame"]) {
    if (!f.is_object() || !f.contains("index") || !f.contains("frame") || !f["index"].is_number_integer() ||
        !f["frame"].is_number_integer())
      throw capture::CaptureError(summaryPath.string(), "a per_frame entry without its index and frame");
    const int index = f["index"].get<int>(), frame = f["frame"].get<int>();
    const fs::path refDir = fs::path(session) / "reference";
    const std::string refPath = (refDir / frameName("%06d.png", frame)).string();
    if (!fs::is_regular_file(refPath)) continue;  // frames without a reference (a look-around) are not judged
    const cv::Mat background = linearOf((fs::path(session) / "colour" / frameName("%06d.png", frame)).string());
    const cv::Mat reference = linearOf(refPath);
    const std::string oursPath = (fs::path(replay) / frameName("frame_%04d.png", index)).string();
    const cv::Mat ours = linearOf(oursPath);
    const cv::Mat mask = capture::readAny((refDir / frameName("mask_%06d.png", frame)).string());
    if (ours.size() != reference.size() || background.size() != reference.size() || mask.size() != reference.size())
      throw capture::CaptureError(oursPath, "is " + std::to_string(ours.cols) + " x " + std::to_string(ours.rows) +
                                                ", the reference " + std::to_string(reference.cols) + " x " +
                                                std::to_string(reference.rows));
    cv::Mat objects;
    if (mask.channels() == 3)
      cv::cvtColor(mask, objects, cv::COLOR_RGB2GRAY);
    else
      objects = mask;
    objects = objects > 127;
    cv::Mat grown;
    cv::dilate(objects, grown, cv::getStructuringElement(cv::MORPH_ELLIPSE, {5, 5}));
    ComposedFrame c;
    c.frame = frame;
    std::vector<cv::Point> pixels;
    double sumOurs = 0, sumRef = 0, l1 = 0, refChannels = 0, darkOurs = 0, darkRef = 0;
    for (int y = 0; y < reference.rows; ++y)
      for (int x = 0; x < reference.cols; ++x) {
        const cv::Vec3f r = reference.at<cv::Vec3f>(y, x), o = ours.at<cv::Vec3f>(y, x);
        if (objects.at<uchar>(y, x)) {
          pixels.emplace_back(x, y);
          sumOurs += lum(o), sumRef += lum(r);
          for (int k = 0; k < 3; ++k) l1 += std::abs(o[k] - r[k]), refChannels += r[k];
        } else if (!grown.at<uchar>(y, x)) {
          const double b = lum(background.at<cv::Vec3f>(y, x));
          darkOurs += std::max(0.0, b - lum(o));
          darkRef += std::max(0.0, b - lum(r));
        }
      }
    c.objectPixels = static_cast<int>(pixels.size());
    if (pixels.empty() || !(sumRef > 0)) continue;
    c.brightness = sumOurs / sumRef;
    c.relativeL1 = l1 / refChannels;
    const double radius = std::sqrt(static_cast<double>(pixels.size()) / CV_PI);
    c.brightestSide = cv::norm(brightestSide(ours, pixels) - brightestSide(reference, pixels)) / radius;
    c.referenceShadow = darkRef;
    c.shadowEnergy = darkRef > 0 ? darkOurs / darkRef : 0.0;
    out.push_back(c);
  }
  return out;
}

}  // namespace mrgi::evaluation
