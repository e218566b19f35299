#pragma once
/// V4L2 fisheye cameras through libv4l2: mmap streaming, YUYV or MJPEG, decoded with OpenCV.
#include <cstdint>
#include <string>
#include <vector>

#include "capture/frame_source.h"

namespace mrgi::capture {

/// Decodes one V4L2 buffer to RGB (CV_8UC3). fourcc: V4L2_PIX_FMT_YUYV | V4L2_PIX_FMT_MJPEG | V4L2_PIX_FMT_RGB24.
/// bytesPerLine 0 means tightly packed. Throws CaptureError(where, ...) on a short or undecodable buffer.
cv::Mat decodeV4l2Buffer(uint32_t fourcc, const uint8_t* data, size_t bytes, int width, int height, size_t bytesPerLine,
                         const std::string& where);

/// Reads an OpenCV fisheye calibration YAML (camera_matrix / distortion_coefficients as written by ROS
/// camera_calibration, or K / D as written by `mrgi calibrate-fisheye`).
FisheyeCalibration readFisheyeCalibration(const std::string& path);
/// Writes a calibration in the ROS camera_calibration YAML form (image_width/height, camera_matrix,
/// distortion_model "equidistant", distortion_coefficients, rectification_matrix, projection_matrix),
/// atomically; readFisheyeCalibration reads it back.
/// `comment`, when given, is written as the file's first line ("# ...").
void writeFisheyeCalibration(const std::string& path, const FisheyeCalibration& c,
                             const std::string& cameraName = "fisheye", const std::string& comment = {});

class V4l2Source final : public FrameSource {
 public:
  /// devicePath like "/dev/video0"; calibrationPath is required (fisheye frames need their model).
  V4l2Source(const std::string& devicePath, const OpenOptions& options);
  ~V4l2Source() override;
  const SourceInfo& info() const override { return info_; }
  /// Throws CaptureError("v4l2:///dev/videoN: device gone") if the camera disappears.
  std::optional<Frame> next() override;

 private:
  std::string uri_;
  int fd_ = -1;
  uint32_t fourcc_ = 0;
  int width_ = 0, height_ = 0;
  size_t bytesPerLine_ = 0;
  std::vector<std::pair<void*, size_t>> buffers_;
  FisheyeCalibration calibration_;
  SourceInfo info_;
  int64_t index_ = 0;
};

}  // namespace mrgi::capture
