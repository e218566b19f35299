// V4L2 buffer decoding with synthetic YUYV and MJPEG buffers; fisheye calibration files.
#include <gtest/gtest.h>
#include <linux/videodev2.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/checks.h"
#include "capture/error.h"
#include "capture/frame_source.h"
#include "capture/v4l2_source.h"

using namespace mrgi::capture;

namespace {
/// BT.601 limited-range YUV of an RGB colour, as a camera's encoder produces it.
cv::Vec3d yuvOf(cv::Vec3d rgb) {
  const double y = 16 + (65.481 * rgb[0] + 128.553 * rgb[1] + 24.966 * rgb[2]) / 255.0;
  const double u = 128 + (-37.797 * rgb[0] - 74.203 * rgb[1] + 112.0 * rgb[2]) / 255.0;
  const double v = 128 + (112.0 * rgb[0] - 93.786 * rgb[1] - 18.214 * rgb[2]) / 255.0;
  return {y, u, v};
}
}  // namespace

TEST(V4l2, YuyvDecodesKnownColours) {
  const int w = 8, h = 2;
  const cv::Vec3d colours[4] = {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}, {128, 128, 128}};
  std::vector<uint8_t> buf(w * h * 2);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; x += 2) {
      const cv::Vec3d yuv = yuvOf(colours[x / 2]);
      uint8_t* p = &buf[(y * w + x) * 2];
      p[0] = p[2] = static_cast<uint8_t>(std::lround(yuv[0]));
      p[1] = static_cast<uint8_t>(std::lround(yuv[1]));
      p[3] = static_cast<uint8_t>(std::lround(yuv[2]));
    }
  const cv::Mat rgb = decodeV4l2Buffer(V4L2_PIX_FMT_YUYV, buf.data(), buf.size(), w, h, 0, "test");
  ASSERT_EQ(rgb.type(), CV_8UC3);
  for (int x = 0; x < w; ++x) {
    const cv::Vec3b got = rgb.at<cv::Vec3b>(1, x);
    for (int c = 0; c < 3; ++c)
      // OpenCV decodes YUYV with full-range coefficients; saturated primaries land within 40 levels.
      EXPECT_NEAR(got[c], colours[x / 2][c], 40) << "pixel " << x << " channel " << c;
  }
  // Grey stays grey and channel order is RGB (red pixel: R largest).
  const cv::Vec3b red = rgb.at<cv::Vec3b>(0, 0);
  EXPECT_GT(red[0], 200);
  EXPECT_LT(red[2], 60);
  const cv::Vec3b grey = rgb.at<cv::Vec3b>(0, 6);
  EXPECT_LE(std::abs(grey[0] - grey[2]), 2);
}

TEST(V4l2, YuyvWithRowPaddingAndShortBuffer) {
  const int w = 4, h = 2, stride = 16;
  std::vector<uint8_t> buf(stride * h, 128);
  const cv::Mat rgb = decodeV4l2Buffer(V4L2_PIX_FMT_YUYV, buf.data(), buf.size(), w, h, stride, "test");
  EXPECT_EQ(rgb.cols, w);
  try {
    decodeV4l2Buffer(V4L2_PIX_FMT_YUYV, buf.data(), 10, w, h, stride, "v4l2:///dev/video9");
    FAIL();
  } catch (const CaptureError& e) {
    EXPECT_NE(std::string(e.what()).find("v4l2:///dev/video9: YUYV buffer holds 10 bytes"), std::string::npos);
  }
}

TEST(V4l2, MjpegDecodesToRgbAndRejectsCorruptFrames) {
  cv::Mat bgr(48, 64, CV_8UC3, cv::Scalar(20, 40, 200));  // BGR: red-ish
  std::vector<uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", bgr, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95}));
  const cv::Mat rgb = decodeV4l2Buffer(V4L2_PIX_FMT_MJPEG, jpeg.data(), jpeg.size(), 64, 48, 0, "test");
  const cv::Vec3b p = rgb.at<cv::Vec3b>(24, 32);
  EXPECT_NEAR(p[0], 200, 3);  // JPEG at quality 95 on a flat colour: within 3 levels
  EXPECT_NEAR(p[1], 40, 3);
  EXPECT_NEAR(p[2], 20, 3);
  std::vector<uint8_t> garbage(500, 0x55);
  EXPECT_THROW(decodeV4l2Buffer(V4L2_PIX_FMT_MJPEG, garbage.data(), garbage.size(), 64, 48, 0, "t"), CaptureError);
  EXPECT_THROW(decodeV4l2Buffer(V4L2_PIX_FMT_MJPEG, jpeg.data(), jpeg.size(), 32, 48, 0, "t"), CaptureError);
  EXPECT_THROW(decodeV4l2Buffer(v4l2_fourcc('N', 'V', '1', '2'), jpeg.data(), jpeg.size(), 64, 48, 0, "t"),
               CaptureError);
}

TEST(V4l2, ReadsTheRosFisheyeCalibration) {
  const FisheyeCalibration c = readFisheyeCalibration(std::string(MRGI_SHARED_DATA) + "/fisheye-ros-calib/ost.yaml");
  EXPECT_EQ(c.width, 800);
  EXPECT_EQ(c.height, 503);
  EXPECT_DOUBLE_EQ(c.K(0, 0), 290.050152);
  EXPECT_DOUBLE_EQ(c.K(1, 2), 273.885669);
  EXPECT_DOUBLE_EQ(c.D[0], -0.030464);
  EXPECT_DOUBLE_EQ(c.D[3], 0.001030);
}

TEST(V4l2, MissingDeviceIsAOneLineError) {
  OpenOptions o;
  o.fisheyeCalibration = std::string(MRGI_SHARED_DATA) + "/fisheye-ros-calib/ost.yaml";
  try {
    open("v4l2:///dev/video-mrgi-none", o);
    FAIL();
  } catch (const CaptureError& e) {
    EXPECT_NE(std::string(e.what()).find("v4l2:///dev/video-mrgi-none: cannot open camera"), std::string::npos)
        << e.what();
  }
}

TEST(FisheyeCalibration, MalformedYamlFoundByTheFuzzerIsAOneLineError) {
  // OpenCV's YAML parser throws std::length_error on this input (not cv::Exception): it escaped as a
  // message naming no file.
  const std::string path = std::string(MRGI_SOURCE_DIR) + "/tests/data/fuzz/fisheye_yaml_length_error.yaml";
  try {
    readFisheyeCalibration(path);
    ADD_FAILURE() << "accepted";
  } catch (const CaptureError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(path + ": ", 0), 0u) << e.what();
  }
}

TEST(FisheyeCalibration, OnlyCalibrationShapedYamlReachesOpenCvsParser) {
  // Found by the fisheye_yaml fuzzer: 22 bytes of block sequences and a flow mapping kept OpenCV's YAML
  // parser busy for over a minute. Text that is not "key: value" lines and lists of numbers never reaches it.
  const std::string path = std::string(MRGI_SOURCE_DIR) + "/tests/data/fuzz/fisheye_yaml_parser_hang.yaml";
  try {
    readFisheyeCalibration(path);
    ADD_FAILURE() << "accepted";
  } catch (const CaptureError& e) {
    EXPECT_EQ(std::string(e.what()),
              path + ": not a camera calibration (ROS or OpenCV YAML): line 2: not a 'key: value' line");
  }
  EXPECT_EQ(
      calibrationYamlShapeError("%YAML:1.0\n---\na: 1\nm: !!opencv-matrix\n  rows: 1\n  data: [ 1., -2e-3,\n    3 ]\n"),
      "");
  EXPECT_EQ(calibrationYamlShapeError("a: {b: 1}\n"), "line 1: '{' (only plain values and lists of numbers)");
  EXPECT_EQ(calibrationYamlShapeError("a:\n  - 1\n"), "line 2: not a 'key: value' line");
  EXPECT_EQ(calibrationYamlShapeError("a: [1, [2]]\n"), "line 1: a list inside a list");
  EXPECT_EQ(calibrationYamlShapeError("a: [1, x]\n"), "line 1: a list holds something other than numbers");
  EXPECT_EQ(calibrationYamlShapeError("a: [1, 2\n"), "a list is not closed");
  EXPECT_EQ(calibrationYamlShapeError("a: &x 1\n"), "line 1: '&' (only plain values and lists of numbers)");
}
