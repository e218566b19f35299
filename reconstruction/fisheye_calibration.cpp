#include "reconstruction/fisheye_calibration.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "capture/image_io.h"

namespace mrgi::reconstruction {

FisheyeCalibrationResult calibrateFisheye(const std::vector<std::string>& paths, cv::Size inner, double square) {
  FisheyeCalibrationResult out;
  std::vector<std::vector<cv::Point3d>> objects;
  std::vector<std::vector<cv::Point2d>> images;
  std::vector<cv::Point3d> board;
  for (int r = 0; r < inner.height; ++r)
    for (int c = 0; c < inner.width; ++c) board.emplace_back(c * square, r * square, 0);
  cv::Size size;
  for (const auto& path : paths) {
    // Decoded by our readers (a damaged file is an error naming it; libpng never prints).
    cv::Mat grey;
    cv::cvtColor(capture::readColour(path), grey, cv::COLOR_RGB2GRAY);
    if (size.area() == 0) size = grey.size();
    if (grey.size() != size) {
      out.rejected.push_back(path + ": size differs from the first image");
      continue;
    }
    std::vector<cv::Point2f> corners;
    if (!cv::findChessboardCorners(
            grey, inner, corners,
            cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_FAST_CHECK)) {
      out.rejected.push_back(path + ": board not found");
      continue;
    }
    cv::cornerSubPix(grey, corners, {5, 5}, {-1, -1},
                     cv::TermCriteria(cv::TermCriteria::EPS | cv::TermCriteria::COUNT, 50, 1e-3));
    objects.push_back(board);
    images.emplace_back(corners.begin(), corners.end());
    out.used.push_back(path);
  }
  const int flags =
      cv::fisheye::CALIB_RECOMPUTE_EXTRINSIC | cv::fisheye::CALIB_CHECK_COND | cv::fisheye::CALIB_FIX_SKEW;
  const cv::TermCriteria term(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-9);
  while (true) {
    if (objects.size() < 3)
      throw std::runtime_error("fewer than 3 usable checkerboard views (" + std::to_string(objects.size()) + ")");
    cv::Matx33d K;
    cv::Vec4d D;
    std::vector<cv::Mat> rvecs, tvecs;
    try {
      out.rms = cv::fisheye::calibrate(objects, images, size, K, D, rvecs, tvecs, flags, term);
      out.calibration.width = size.width;
      out.calibration.height = size.height;
      out.calibration.K = K;
      out.calibration.D = D;
      return out;
    } catch (const cv::Exception& e) {
      // CALIB_CHECK_COND names the ill-conditioned view: "CALIB_CHECK_COND - Ill-conditioned matrix for input array N".
      const std::string msg = e.what();
      const size_t at = msg.find("input array ");
      if (at == std::string::npos) throw;
      const size_t i = std::stoul(msg.substr(at + 12));
      if (i >= objects.size()) throw;
      out.rejected.push_back(out.used[i] + ": ill-conditioned view");
      objects.erase(objects.begin() + i), images.erase(images.begin() + i), out.used.erase(out.used.begin() + i);
    }
  }
}

}  // namespace mrgi::reconstruction
