#include "capture/v4l2_source.h"

#include <fcntl.h>
#include <libv4l2.h>
#include <linux/videodev2.h>
#include <sys/mman.h>
#include <sys/select.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/checks.h"
#include "capture/error.h"
#include "capture/image_io.h"

namespace mrgi::capture {
namespace {

int xioctl(int fd, unsigned long request, void* arg) {
  int r;
  do r = v4l2_ioctl(fd, request, arg);
  while (r == -1 && errno == EINTR);
  return r;
}

}  // namespace

cv::Mat decodeV4l2Buffer(uint32_t fourcc, const uint8_t* data, size_t bytes, int width, int height, size_t bytesPerLine,
                         const std::string& where) {
  if (width <= 0 || height <= 0) throw CaptureError(where, "invalid frame size");
  cv::Mat rgb;
  switch (fourcc) {
    case V4L2_PIX_FMT_YUYV: {
      const size_t stride = bytesPerLine ? bytesPerLine : static_cast<size_t>(width) * 2;
      if (bytes < stride * static_cast<size_t>(height))
        throw CaptureError(
            where, "YUYV buffer holds " + std::to_string(bytes) + " bytes, needs " + std::to_string(stride * height));
      const cv::Mat yuyv(height, width, CV_8UC2, const_cast<uint8_t*>(data), stride);
      cv::cvtColor(yuyv, rgb, cv::COLOR_YUV2RGB_YUYV);
      break;
    }
    case V4L2_PIX_FMT_MJPEG:
    case V4L2_PIX_FMT_JPEG: {
      quietOpenCv();
      const cv::Mat buf(1, static_cast<int>(bytes), CV_8UC1, const_cast<uint8_t*>(data));
      cv::Mat bgr;
      try {
        bgr = cv::imdecode(buf, cv::IMREAD_COLOR);
      } catch (const cv::Exception&) {
      }
      if (bgr.empty()) throw CaptureError(where, "corrupt MJPEG frame");
      if (bgr.cols != width || bgr.rows != height)
        throw CaptureError(where, "MJPEG frame is " + std::to_string(bgr.cols) + "x" + std::to_string(bgr.rows) +
                                      ", the stream is " + std::to_string(width) + "x" + std::to_string(height));
      cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
      break;
    }
    case V4L2_PIX_FMT_RGB24: {
      const size_t stride = bytesPerLine ? bytesPerLine : static_cast<size_t>(width) * 3;
      if (bytes < stride * static_cast<size_t>(height)) throw CaptureError(where, "RGB24 buffer is short");
      rgb = cv::Mat(height, width, CV_8UC3, const_cast<uint8_t*>(data), stride).clone();
      break;
    }
    default: {
      char f[5] = {char(fourcc & 0xff), char((fourcc >> 8) & 0xff), char((fourcc >> 16) & 0xff), char(fourcc >> 24), 0};
      throw CaptureError(where, std::string("unsupported pixel format '") + f + "'");
    }
  }
  return rgb;
}

void writeFisheyeCalibration(const std::string& path, const FisheyeCalibration& c, const std::string& cameraName,
                             const std::string& comment) {
  auto list = [](std::initializer_list<double> v) {
    std::string s = "[";
    char buf[32];
    for (auto it = v.begin(); it != v.end(); ++it) {
      std::snprintf(buf, sizeof buf, "%.6f", *it);
      s += (it == v.begin() ? "" : ", ") + std::string(buf);
    }
    return s + "]";
  };
  const auto& K = c.K;
  std::string y = comment.empty() ? std::string() : comment + "\n";
  y += "image_width: " + std::to_string(c.width) + "\n";
  y += "image_height: " + std::to_string(c.height) + "\n";
  y += "camera_name: " + cameraName + "\n";
  y += "camera_matrix:\n  rows: 3\n  cols: 3\n  data: " +
       list({K(0, 0), K(0, 1), K(0, 2), K(1, 0), K(1, 1), K(1, 2), K(2, 0), K(2, 1), K(2, 2)}) + "\n";
  y += "distortion_model: equidistant\n";
  y += "distortion_coefficients:\n  rows: 1\n  cols: 4\n  data: " + list({c.D[0], c.D[1], c.D[2], c.D[3]}) + "\n";
  y += "rectification_matrix:\n  rows: 3\n  cols: 3\n  data: " + list({1, 0, 0, 0, 1, 0, 0, 0, 1}) + "\n";
  y += "projection_matrix:\n  rows: 3\n  cols: 4\n  data: " +
       list({K(0, 0), 0, K(0, 2), 0, 0, K(1, 1), K(1, 2), 0, 0, 0, 1, 0}) + "\n";
  writeFileAtomically(path, std::vector<uchar>(y.begin(), y.end()));
}

FisheyeCalibration readFisheyeCalibration(const std::string& path) {
  quietOpenCv();
  std::string text = readFileBounded(path, 1 << 20, "calibration YAML");
  if (yamlNestingDepth(text) > kMaxYamlDepth)
    throw CaptureError(path, "calibration YAML nests deeper than " + std::to_string(kMaxYamlDepth) + " levels");
  if (const std::string why = calibrationYamlShapeError(text); !why.empty())
    throw CaptureError(path, "not a camera calibration (ROS or OpenCV YAML): " + why);
  cv::FileStorage fsr;
  try {
    // ROS writes YAML without OpenCV's "%YAML:1.0" directive; add it and parse from memory.
    if (text.rfind("%YAML", 0) != 0) text = "%YAML:1.0\n---\n" + text;
    fsr.open(text, cv::FileStorage::READ | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML);
  } catch (const std::exception&) {
    // cv::Exception, and std::length_error / bad_alloc from OpenCV's parser on malformed text (found by
    // the fisheye_yaml fuzzer): all of them a file that cannot be parsed.
  }
  if (!fsr.isOpened()) throw CaptureError(path, "cannot parse calibration YAML");
  FisheyeCalibration c;
  cv::Mat K, D;
  auto readMat = [&](const char* a, const char* b) {
    cv::Mat m;
    cv::FileNode n = fsr[a];
    if (n.empty()) n = fsr[b];
    if (n.empty()) return m;
    if (n.isMap() && !n["data"].empty() && n["rows"].empty() == false && n["dt"].empty()) {
      // ROS camera_calibration style: {rows, cols, data: [...]}
      std::vector<double> data;
      n["data"] >> data;
      m = cv::Mat(data, true).reshape(1, static_cast<int>(n["rows"]));
    } else {
      n >> m;
    }
    return m;
  };
  try {
    K = readMat("camera_matrix", "K");
    D = readMat("distortion_coefficients", "D");
    c.width = static_cast<int>(fsr["image_width"].empty() ? fsr["width"] : fsr["image_width"]);
    c.height = static_cast<int>(fsr["image_height"].empty() ? fsr["height"] : fsr["image_height"]);
  } catch (const std::exception&) {
    throw CaptureError(path, "calibration keys have the wrong type");
  }
  if (K.total() != 9) throw CaptureError(path, "missing or malformed 'camera_matrix' (3x3)");
  if (D.total() != 4) throw CaptureError(path, "missing or malformed 'distortion_coefficients' (4 values)");
  if (c.width <= 0 || c.height <= 0) throw CaptureError(path, "missing 'image_width' / 'image_height'");
  K.convertTo(K, CV_64F);
  D.convertTo(D, CV_64F);
  for (int i = 0; i < 9; ++i) c.K(i / 3, i % 3) = K.at<double>(i);
  for (int i = 0; i < 4; ++i) c.D[i] = D.at<double>(i);
  // ROS's fisheye calibrator labels its 4-coefficient equidistant output "plumb_bob"; the coefficient count
  // (checked above) is what tells the models apart.
  return c;
}

V4l2Source::V4l2Source(const std::string& devicePath, const OpenOptions& options) : uri_("v4l2://" + devicePath) {
  if (options.fisheyeCalibration.empty()) throw CaptureError(uri_, "a fisheye camera needs --fisheye-calib CALIB.yaml");
  calibration_ = readFisheyeCalibration(options.fisheyeCalibration);
  fd_ = v4l2_open(devicePath.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC, 0);
  if (fd_ < 0) throw CaptureError(uri_, std::string("cannot open camera: ") + std::strerror(errno));
  v4l2_capability cap{};
  if (xioctl(fd_, VIDIOC_QUERYCAP, &cap) < 0 || !(cap.device_caps & V4L2_CAP_VIDEO_CAPTURE) ||
      !(cap.device_caps & V4L2_CAP_STREAMING))
    throw CaptureError(uri_, "not a streaming video capture device");

  // Prefer MJPEG (USB bandwidth), then YUYV, at the calibrated size unless told otherwise.
  const int w = options.width ? options.width : calibration_.width,
            h = options.height ? options.height : calibration_.height;
  for (uint32_t fourcc : {V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_YUYV}) {
    v4l2_format fmt{};
    fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    fmt.fmt.pix.width = static_cast<uint32_t>(w);
    fmt.fmt.pix.height = static_cast<uint32_t>(h);
    fmt.fmt.pix.pixelformat = fourcc;
    fmt.fmt.pix.field = V4L2_FIELD_NONE;
    if (xioctl(fd_, VIDIOC_S_FMT, &fmt) == 0 && fmt.fmt.pix.pixelformat == fourcc) {
      fourcc_ = fourcc;
      width_ = static_cast<int>(fmt.fmt.pix.width);
      height_ = static_cast<int>(fmt.fmt.pix.height);
      bytesPerLine_ = fmt.fmt.pix.bytesperline;
      break;
    }
  }
  if (!fourcc_) throw CaptureError(uri_, "camera offers neither MJPEG nor YUYV");
  if (width_ != calibration_.width || height_ != calibration_.height)
    throw CaptureError(uri_, "camera delivers " + std::to_string(width_) + "x" + std::to_string(height_) +
                                 " but the calibration is for " + std::to_string(calibration_.width) + "x" +
                                 std::to_string(calibration_.height));
  v4l2_requestbuffers req{};
  req.count = 4;
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  if (xioctl(fd_, VIDIOC_REQBUFS, &req) < 0 || req.count < 2) throw CaptureError(uri_, "cannot allocate mmap buffers");
  for (uint32_t i = 0; i < req.count; ++i) {
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = i;
    if (xioctl(fd_, VIDIOC_QUERYBUF, &buf) < 0) throw CaptureError(uri_, "VIDIOC_QUERYBUF failed");
    void* p = v4l2_mmap(nullptr, buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buf.m.offset);
    if (p == MAP_FAILED) throw CaptureError(uri_, "cannot map capture buffer");
    buffers_.emplace_back(p, buf.length);
    if (xioctl(fd_, VIDIOC_QBUF, &buf) < 0) throw CaptureError(uri_, "VIDIOC_QBUF failed");
  }
  v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(fd_, VIDIOC_STREAMON, &type) < 0) throw CaptureError(uri_, "cannot start streaming");
  info_.uri = uri_;
  info_.kind = "v4l2";
  info_.hasFisheye = true;
}

V4l2Source::~V4l2Source() {
  if (fd_ >= 0) {
    v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    xioctl(fd_, VIDIOC_STREAMOFF, &type);
    for (auto& [p, n] : buffers_) v4l2_munmap(p, n);
    v4l2_close(fd_);
  }
}

std::optional<Frame> V4l2Source::next() {
  fd_set fds;
  FD_ZERO(&fds);
  FD_SET(fd_, &fds);
  timeval tv{2, 0};
  const int r = select(fd_ + 1, &fds, nullptr, nullptr, &tv);
  if (r <= 0)
    throw CaptureError(uri_,
                       r == 0 ? "device gone (no frame for 2 s)" : std::string("device gone: ") + std::strerror(errno));
  v4l2_buffer buf{};
  buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  buf.memory = V4L2_MEMORY_MMAP;
  if (xioctl(fd_, VIDIOC_DQBUF, &buf) < 0)
    throw CaptureError(uri_, std::string("device gone: ") + std::strerror(errno));
  Frame f;
  f.index = index_++;
  f.timestamp = static_cast<double>(buf.timestamp.tv_sec) + buf.timestamp.tv_usec * 1e-6;
  FisheyeFrame ff;
  try {
    ff.image = decodeV4l2Buffer(fourcc_, static_cast<const uint8_t*>(buffers_[buf.index].first), buf.bytesused, width_,
                                height_, bytesPerLine_, uri_);
  } catch (...) {
    xioctl(fd_, VIDIOC_QBUF, &buf);
    throw;
  }
  xioctl(fd_, VIDIOC_QBUF, &buf);
  v4l2_control ctrl{};
  ctrl.id = V4L2_CID_EXPOSURE_ABSOLUTE;  // units of 100 us
  ff.exposure = xioctl(fd_, VIDIOC_G_CTRL, &ctrl) == 0 && ctrl.value > 0 ? ctrl.value * 1e-4 : 1.0;
  ff.calibration = calibration_;
  f.fisheye = std::move(ff);
  return f;
}

}  // namespace mrgi::capture
