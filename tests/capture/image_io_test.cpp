// Image codecs that name the file in every error and print nothing themselves: EXR through OpenEXR from
// memory (no temporary files), PNG through libpng with our handlers.
#include "capture/image_io.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <tuple>

#include "capture/error.h"

namespace fs = std::filesystem;
using namespace mrgi::capture;

namespace {

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("mrgi_image_io_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir / name;
}

void writeBytes(const fs::path& p, const std::vector<unsigned char>& bytes) {
  std::ofstream(p, std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

cv::Mat ramp(int w, int h) {
  cv::Mat img(h, w, CV_32FC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) img.at<cv::Vec3f>(y, x) = {0.01f * x, 1000.f * y, 0.5f + 1e-3f * (x + y)};
  return img;
}

/// OpenCV puts the temporary files of codecs that cannot decode from memory in OPENCV_TEMP_PATH: a private
/// folder here, so that other processes' files do not count.
int opencvTempFiles() {
  static const fs::path dir = [] {
    const fs::path d = scratch("opencv_temp");
    fs::create_directories(d);
    ::setenv("OPENCV_TEMP_PATH", d.c_str(), 1);
    return d;
  }();
  return static_cast<int>(std::distance(fs::directory_iterator(dir), fs::directory_iterator()));
}

/// Runs fn with std::cerr captured; returns what was printed.
template <typename Fn>
std::string cerrOf(Fn&& fn) {
  std::stringstream captured;
  std::streambuf* saved = std::cerr.rdbuf(captured.rdbuf());
  try {
    fn();
  } catch (...) {
    std::cerr.rdbuf(saved);
    throw;
  }
  std::cerr.rdbuf(saved);
  return captured.str();
}

}  // namespace

TEST(ImageIo, ExrRoundTripsFullFloatExactlyAndHalfWithinItsPrecision) {
  const cv::Mat img = ramp(37, 23);
  const fs::path full = scratch("full.exr"), half = scratch("half.exr");
  writeBytes(full, encodeExr(img, false, full.string()));
  writeBytes(half, encodeExr(img, true, half.string()));
  const cv::Mat a = readAny(full.string()), b = readAny(half.string());
  ASSERT_EQ(a.type(), CV_32FC3);
  ASSERT_EQ(a.size(), img.size());
  EXPECT_EQ(cv::norm(a, img, cv::NORM_INF), 0.0);  // channel order kept: R stays R
  ASSERT_EQ(b.size(), img.size());
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x)
      for (int c = 0; c < 3; ++c) {
        const float v = img.at<cv::Vec3f>(y, x)[c];
        EXPECT_NEAR(b.at<cv::Vec3f>(y, x)[c], v, 1e-3 * std::abs(v) + 1e-7) << x << "," << y << "," << c;
      }
}

TEST(ImageIo, GreyExrIsReadAsThreeEqualChannels) {
  cv::Mat grey(5, 7, CV_32FC1, cv::Scalar(2.5f));
  const fs::path p = scratch("grey.exr");
  writeBytes(p, encodeExr(grey, false, p.string()));
  const cv::Mat back = readAny(p.string());
  ASSERT_EQ(back.type(), CV_32FC3);
  EXPECT_EQ(cv::norm(back, cv::Mat(5, 7, CV_32FC3, cv::Scalar::all(2.5f)), cv::NORM_INF), 0.0);
}

TEST(ImageIo, DamagedExrIsOneErrorNamingTheFileWithNothingPrintedAndNoTemporaryFile) {
  const fs::path p = scratch("bad.exr");
  const std::vector<unsigned char> good = encodeExr(ramp(64, 48), true, p.string());
  std::vector<std::vector<unsigned char>> damaged;
  damaged.emplace_back(good.begin(), good.begin() + static_cast<long>(good.size() / 2));  // truncated
  damaged.emplace_back(good.begin(), good.begin() + 12);                                  // header cut short
  for (size_t at : {size_t(8), size_t(40), good.size() / 3, good.size() - 20}) {          // bit flips
    std::vector<unsigned char> b = good;
    b[at] ^= 0xA5;
    damaged.push_back(b);
  }
  std::vector<unsigned char> huge = good;  // dataWindow max beyond 16384: find "dataWindow" and patch xMax
  const std::string key = "dataWindow";
  auto it = std::search(huge.begin(), huge.end(), key.begin(), key.end());
  ASSERT_NE(it, huge.end());
  const size_t xMaxAt =
      static_cast<size_t>(it - huge.begin()) + key.size() + 1 + 6 + 4 + 8;  // name\0 "box2i"\0 size xMin yMin
  huge[xMaxAt + 1] = 0x7f;                                                  // xMax = 0x7f00 + 63
  damaged.push_back(huge);
  const int tempsBefore = opencvTempFiles();
  int refused = 0;
  for (const auto& bytes : damaged) {
    writeBytes(p, bytes);
    const std::string printed = cerrOf([&] {
      try {
        (void)readAny(p.string());
      } catch (const InputError& e) {
        ++refused;
        EXPECT_EQ(std::string(e.what()).rfind(p.string() + ": ", 0), 0u) << e.what();
        EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
      }
    });
    EXPECT_EQ(printed, "");
  }
  // A bit flip inside compressed pixel data may decode to other values; everything else must be refused.
  EXPECT_GE(refused, static_cast<int>(damaged.size()) - 1);
  EXPECT_EQ(opencvTempFiles(), tempsBefore);
  fs::remove_all(p.parent_path());
}

TEST(ImageIo, JpegDecodesAsOpenCvDoesAndDamagedJpegIsRefused) {
  // A smooth colour image and its grey version, encoded by OpenCV (libjpeg-turbo) at quality 90.
  cv::Mat bgr(60, 80, CV_8UC3);
  for (int y = 0; y < bgr.rows; ++y)
    for (int x = 0; x < bgr.cols; ++x) bgr.at<cv::Vec3b>(y, x) = cv::Vec3b(uchar(3 * x), uchar(4 * y), uchar(x + y));
  cv::Mat grey;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  for (const cv::Mat& img : {bgr, grey}) {
    std::vector<unsigned char> bytes;
    ASSERT_TRUE(cv::imencode(".jpg", img, bytes, {cv::IMWRITE_JPEG_QUALITY, 90}));
    const fs::path p = scratch("frame.jpg");
    writeBytes(p, bytes);
    // Parity with OpenCV's decoder (the same libjpeg underneath): identical pixels, RGB order for colour.
    cv::Mat expected = cv::imdecode(bytes, cv::IMREAD_COLOR);
    cv::cvtColor(expected, expected, cv::COLOR_BGR2RGB);
    const cv::Mat colour = readColour(p.string());
    ASSERT_EQ(colour.type(), CV_8UC3);
    EXPECT_EQ(cv::norm(colour, expected, cv::NORM_INF), 0.0);
    // Cut short: libjpeg warns ("premature end of data segment") and fills grey; that is refused, quietly.
    writeBytes(p, std::vector<unsigned char>(bytes.begin(), bytes.begin() + static_cast<long>(bytes.size() * 2 / 3)));
    const std::string printed = cerrOf([&] {
      try {
        (void)readColour(p.string());
        ADD_FAILURE() << "a truncated JPEG decoded";
      } catch (const InputError& e) {
        EXPECT_EQ(std::string(e.what()).rfind(p.string() + ": cannot decode JPEG", 0), 0u) << e.what();
      }
    });
    EXPECT_EQ(printed, "");
  }
}

TEST(ImageIo, FormatsOutsideTheSupportedOnesNeverReachOpenCv) {
  // Found by the image fuzzer: bytes that OpenCV hands to its DICOM decoder (GDCM), whose assertion
  // aborts the process. Only PNG, JPEG, EXR, BMP, PNM and TIFF are decoded at all.
  const std::string dicom = std::string(MRGI_SOURCE_DIR) + "/tests/data/fuzz/image_dicom_gdcm_abort.bin";
  for (bool depth : {false, true}) {
    try {
      if (depth)
        (void)readDepth(dicom, 0.001);
      else
        (void)readColour(dicom);
      ADD_FAILURE() << "decoded";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(dicom + ": cannot decode image: not a supported format"), std::string::npos)
          << e.what();
    }
  }
}

TEST(ImageIo, ExrHeaderAttributesLongerThanTheFileAreRefusedBeforeAllocation) {
  // Found by the image fuzzer (as a time-out): an attribute declaring 1.6 GB in a 1.3 KB file, which
  // OpenEXR allocates before finding the file too short.
  const std::string file = std::string(MRGI_SOURCE_DIR) + "/tests/data/fuzz/image_exr_huge_attribute.exr";
  try {
    (void)readAny(file);
    ADD_FAILURE() << "decoded";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("declares 1664937503 bytes, past the end of the file"), std::string::npos)
        << e.what();
  }
  // Found by the image fuzzer (a time-out under ASan): a data window 5 million pixels wide; and a sound
  // file's window raised to 10000 x 10000, more pixels than any codec packs into its 1 KB. Both refused
  // from the header, before OpenEXR allocates line buffers.
  try {
    (void)readAny(std::string(MRGI_SOURCE_DIR) + "/tests/data/fuzz/image_exr_huge_data_window.exr");
    ADD_FAILURE() << "decoded";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("EXR image of 5046273x5, at most 16384 a side"), std::string::npos)
        << e.what();
  }
  {
    const fs::path q = scratch("window.exr");
    std::vector<unsigned char> big = encodeExr(ramp(8, 8), true, q.string());
    const std::string key = "dataWindow";
    const size_t box = static_cast<size_t>(std::search(big.begin(), big.end(), key.begin(), key.end()) - big.begin()) +
                       key.size() + 1 + 6 + 4;
    for (size_t k : {box + 8, box + 12}) {  // xMax, yMax = 9999
      big[k] = 0x0f, big[k + 1] = 0x27, big[k + 2] = 0, big[k + 3] = 0;
    }
    writeBytes(q, big);
    try {
      (void)readAny(q.string());
      ADD_FAILURE() << "decoded";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("EXR image of 10000x10000 in a file of"), std::string::npos) << e.what();
    }
  }
  // The same check on a sound file, every attribute size raised past the end one at a time: always refused.
  const fs::path p = scratch("attr.exr");
  const std::vector<unsigned char> good = encodeExr(ramp(8, 8), true, p.string());
  int attributes = 0;
  for (size_t at = 8; at + 4 < good.size() && good[at] != 0;) {  // name\0 type\0 size value
    while (good[at]) ++at;
    ++at;
    while (good[at]) ++at;
    ++at;
    std::vector<unsigned char> bad = good;
    bad[at + 3] = 0x7f;
    writeBytes(p, bad);
    EXPECT_THROW((void)readAny(p.string()), InputError);
    const uint32_t size = uint32_t(good[at]) | uint32_t(good[at + 1]) << 8;
    at += 4 + size;
    ++attributes;
  }
  EXPECT_GE(attributes, 6);  // channels, compression, dataWindow, displayWindow, lineOrder, ...
}

TEST(ImageIo, RadianceHdrProbesDecodeAsOpenCvDoes) {
  // The light probes in ../shared/data/hdr-probes are Radiance RGBE, run-length encoded. Our decoder (from
  // memory, bounded) against OpenCV's reference-derived one: identical floats, RGB order.
  for (const char* name : {"grace", "pisa", "uffizi"}) {
    const std::string path = std::string(MRGI_SHARED_DATA) + "/hdr-probes/" + name + ".hdr";
    cv::Mat expected = cv::imread(path, cv::IMREAD_UNCHANGED);
    ASSERT_EQ(expected.type(), CV_32FC3) << name;
    cv::cvtColor(expected, expected, cv::COLOR_BGR2RGB);
    const cv::Mat ours = readAny(path);
    ASSERT_EQ(ours.type(), CV_32FC3) << name;
    ASSERT_EQ(ours.size(), expected.size()) << name;
    EXPECT_EQ(cv::norm(ours, expected, cv::NORM_INF), 0.0) << name;
    double hi = 0;
    cv::minMaxLoc(ours.reshape(1), nullptr, &hi);
    EXPECT_GT(hi, 1.0) << name << ": a probe's sky is brighter than 1";
  }
}

TEST(ImageIo, FlatRadianceHdrDecodesAndDamagedOnesAreOneErrorNamingTheFile) {
  // A 4x2 flat (not run-length encoded) file written by hand: pixel (r, g, b, e) = (r, g, b) * 2^(e - 136).
  std::string text = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 4\n";
  std::vector<unsigned char> bytes(text.begin(), text.end());
  for (int i = 0; i < 8; ++i)
    for (unsigned char b : {static_cast<unsigned char>(16 * i), static_cast<unsigned char>(128),
                            static_cast<unsigned char>(255), static_cast<unsigned char>(i == 3 ? 0 : 129 + i)})
      bytes.push_back(b);
  const fs::path p = scratch("flat.hdr");
  writeBytes(p, bytes);
  const cv::Mat img = readAny(p.string());
  ASSERT_EQ(img.type(), CV_32FC3);
  ASSERT_EQ(img.size(), cv::Size(4, 2));
  EXPECT_FLOAT_EQ(img.at<cv::Vec3f>(0, 1)[0], 16.f * std::ldexp(1.f, 130 - 136));
  EXPECT_FLOAT_EQ(img.at<cv::Vec3f>(0, 1)[2], 255.f * std::ldexp(1.f, 130 - 136));
  EXPECT_EQ(img.at<cv::Vec3f>(0, 3), cv::Vec3f(0, 0, 0));  // exponent 0: black
  EXPECT_FLOAT_EQ(img.at<cv::Vec3f>(1, 3)[1], 128.f * std::ldexp(1.f, 136 - 136));
  // Damaged: cut short, a run past the scanline, an absurd size, another pixel format, a missing resolution.
  const std::string probe = std::string(MRGI_SHARED_DATA) + "/hdr-probes/grace.hdr";
  std::ifstream in(probe, std::ios::binary);
  const std::vector<unsigned char> good((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<unsigned char> cut(good.begin(), good.begin() + static_cast<long>(good.size() / 2));
  std::vector<unsigned char> run = good;
  const size_t body = std::string(good.begin(), good.end()).find("+X 256\n") + 7;
  ASSERT_EQ(run[body], 2);  // run-length encoded
  run[body + 4] = 128;      // the first run of the first scanline: a run of nothing
  const std::string huge = "#?RADIANCE\n\n-Y 100000 +X 100000\n",
                    xyze = "#?RADIANCE\nFORMAT=32-bit_rle_xyze\n\n-Y 1 +X 1\n0000",
                    nores = "#?RADIANCE\n\n+Y 2 -X 2\n00000000";
  int cases = 0;
  for (const auto& [name, data, message] :
       std::vector<std::tuple<std::string, std::vector<unsigned char>, std::string>>{
           {"cut.hdr", cut, "truncated"},
           {"run.hdr", run, "out of bounds"},
           {"huge.hdr", {huge.begin(), huge.end()}, "at most 16384 a side"},
           {"xyze.hdr", {xyze.begin(), xyze.end()}, "only 32-bit_rle_rgbe"},
           {"orientation.hdr", {nores.begin(), nores.end()}, "'-Y height +X width'"}}) {
    const fs::path f = scratch(name);
    writeBytes(f, data);
    try {
      (void)readAny(f.string());
      ADD_FAILURE() << name << " decoded";
    } catch (const InputError& e) {
      const std::string m = e.what();
      EXPECT_EQ(m.rfind(f.string() + ": cannot decode Radiance HDR (", 0), 0u) << m;
      EXPECT_NE(m.find(message), std::string::npos) << m;
      ++cases;
    }
  }
  EXPECT_EQ(cases, 5);
}

TEST(ImageIo, FloatImagesWithNanOrInfAreRefusedNamingThePixel) {
  const fs::path p = scratch("nonfinite.exr");
  for (const auto& [x, y, c, value] : {std::tuple{5, 2, 1, std::numeric_limits<float>::quiet_NaN()},
                                       std::tuple{7, 3, 2, std::numeric_limits<float>::infinity()}}) {
    cv::Mat img = ramp(8, 4);
    img.at<cv::Vec3f>(y, x)[c] = value;
    writeBytes(p, encodeExr(img, false, p.string()));
    try {
      (void)readAny(p.string());
      ADD_FAILURE() << "decoded";
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()), p.string() + ": holds a non-finite value at pixel (" + std::to_string(x) + ", " +
                                           std::to_string(y) + ")");
    }
  }
}

TEST(ImageIo, EncodedPngsDecodeToThePixelsGivenByLibpngAndOpenCv) {
  cv::RNG rng(3);
  cv::Mat grey(37, 53, CV_8UC1), rgb(37, 53, CV_8UC3), rgba(37, 53, CV_8UC4), depth(37, 53, CV_16UC1);
  for (cv::Mat* m : {&grey, &rgb, &rgba, &depth}) rng.fill(*m, cv::RNG::UNIFORM, 0, m->depth() == CV_16U ? 65536 : 256);
  const cv::Mat window = rgb(cv::Rect(5, 3, 20, 11));  // rows that are not contiguous
  const auto decoded = [](const cv::Mat& m) {
    return cv::imdecode(encodePng(m, "x.png"), cv::IMREAD_UNCHANGED);  // OpenCV: BGR(A) order
  };
  EXPECT_EQ(cv::norm(decoded(grey), grey, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(decoded(depth), depth, cv::NORM_INF), 0.0);  // 16-bit, byte order included
  cv::Mat bgr, bgra;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  cv::cvtColor(rgba, bgra, cv::COLOR_RGBA2BGRA);
  EXPECT_EQ(cv::norm(decoded(rgb), bgr, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(decoded(rgba), bgra, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(decoded(window), bgr(cv::Rect(5, 3, 20, 11)), cv::NORM_INF), 0.0);
  // Our own reader, through a file: RGB in memory as written.
  const fs::path p = scratch("encoded.png");
  writeBytes(p, encodePng(rgb, p.string()));
  EXPECT_EQ(cv::norm(readColour(p.string()), rgb, cv::NORM_INF), 0.0);
  writeBytes(p, encodePng(depth, p.string()));
  EXPECT_EQ(cv::norm(
                readDepth(p.string(), 1.0),
                [&] {
                  cv::Mat metres;
                  depth.convertTo(metres, CV_32F);
                  return metres;
                }(),
                cv::NORM_INF),
            0.0);
  // What PNG cannot hold is one error naming the file.
  for (const cv::Mat& bad :
       {cv::Mat(4, 4, CV_32FC3, cv::Scalar::all(0.5)), cv::Mat(4, 4, CV_8UC2, cv::Scalar(1, 2)), cv::Mat()})
    try {
      encodePng(bad, "bad.png");
      ADD_FAILURE() << "encoded a " << bad.type();
    } catch (const CaptureError& e) {
      EXPECT_NE(std::string(e.what()).find("bad.png"), std::string::npos) << e.what();
    }
}
