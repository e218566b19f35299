#include "capture/image_io.h"

#include <fcntl.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

#include <png.h>

#include <csetjmp>
#include <cstdio>

#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/error.h"

namespace mrgi::capture {

bool isImageFile(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".bmp" || ext == ".pgm" || ext == ".ppm" ||
         ext == ".tif" || ext == ".tiff";
}
namespace {

std::vector<unsigned char> readBytes(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw CaptureError(path, "file is missing");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw CaptureError(path, "cannot open for reading");
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// libpng errors and warnings go to our handlers, never to the terminal: an error ends the decode through
/// longjmp with its message kept for our one line.
struct PngErrors {
  char message[256] = "";
  std::jmp_buf jump;
};
[[noreturn]] void pngError(png_structp png, png_const_charp msg) {
  auto* e = static_cast<PngErrors*>(png_get_error_ptr(png));
  std::snprintf(e->message, sizeof e->message, "%s", msg ? msg : "unknown error");
  std::longjmp(e->jump, 1);
}
void pngWarning(png_structp, png_const_charp) {}

struct PngBytes {
  const std::vector<unsigned char>* bytes;
  size_t at = 0;
};
void pngRead(png_structp png, png_bytep out, png_size_t n) {
  auto* r = static_cast<PngBytes*>(png_get_io_ptr(png));
  if (n > r->bytes->size() - r->at) png_error(png, "file is truncated");
  std::memcpy(out, r->bytes->data() + r->at, n);
  r->at += n;
}

/// A PNG decoded by libpng with our own error handlers. colour: 8-bit BGR (as cv::IMREAD_COLOR); else the
/// stored bit depth, grey as one channel and colour as BGR, alpha dropped (as IMREAD_ANYDEPTH|ANYCOLOR).
cv::Mat decodePng(const std::vector<unsigned char>& bytes, bool colour, const std::string& path) {
  PngErrors errors;
  PngBytes reader{&bytes, 0};
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &errors, pngError, pngWarning);
  if (!png) throw CaptureError(path, "cannot decode PNG (out of memory)");
  png_infop info = png_create_info_struct(png);
  auto fail = [&]() {
    png_destroy_read_struct(&png, &info, nullptr);
    throw CaptureError(path, std::string("cannot decode PNG (") + errors.message + ")");
  };
  if (!info || setjmp(errors.jump)) fail();
  png_set_read_fn(png, &reader, pngRead);
  png_read_info(png, info);
  const png_uint_32 width = png_get_image_width(png, info), height = png_get_image_height(png, info);
  if (width == 0 || height == 0 || width > 16384 || height > 16384) {
    std::snprintf(errors.message, sizeof errors.message, "image of %ux%u, at most 16384 a side", width, height);
    fail();
  }
  const int bits = png_get_bit_depth(png, info);
  png_set_expand(png);  // palette -> RGB, grey below 8 bits -> 8, tRNS -> alpha
  png_set_strip_alpha(png);
  if (colour) {
    png_set_strip_16(png);
    png_set_gray_to_rgb(png);
  } else if (bits == 16) {
    png_set_swap(png);  // little-endian host
  }
  png_set_bgr(png);
  png_read_update_info(png, info);
  const int channels = png_get_channels(png, info), depth = png_get_bit_depth(png, info) == 16 ? CV_16U : CV_8U;
  cv::Mat img(static_cast<int>(height), static_cast<int>(width), CV_MAKETYPE(depth, channels));
  std::vector<png_bytep> rows(height);
  for (png_uint_32 y = 0; y < height; ++y) rows[y] = img.ptr(static_cast<int>(y));
  if (setjmp(errors.jump)) fail();
  png_read_image(png, rows.data());
  png_destroy_read_struct(&png, &info, nullptr);
  return img;
}

cv::Mat decode(const std::string& path, int flags) {
  quietOpenCv();
  const std::vector<unsigned char> bytes = readBytes(path);
  if (bytes.empty()) throw CaptureError(path, "file is empty");
  static const unsigned char kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  const bool png = bytes.size() >= 8 && std::memcmp(bytes.data(), kPngSignature, 8) == 0;
  if (png && flags == cv::IMREAD_COLOR) return decodePng(bytes, true, path);
  if (png && flags == (cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR)) return decodePng(bytes, false, path);
  cv::Mat img;
  try {
    img = cv::imdecode(bytes, flags);
  } catch (const cv::Exception&) {
    img.release();
  }
  if (img.empty()) throw CaptureError(path, "cannot decode image (corrupt or truncated)");
  return img;
}

}  // namespace


namespace {
void writeFileDurably(const std::filesystem::path& path, const std::vector<unsigned char>& bytes) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw CaptureError(path.string(), std::string("cannot create: ") + std::strerror(errno));
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int e = errno;
      ::close(fd);
      throw CaptureError(path.string(), std::string("write failed: ") + std::strerror(e));
    }
    done += static_cast<size_t>(n);
  }
  if (::fsync(fd) != 0 || ::close(fd) != 0)
    throw CaptureError(path.string(), std::string("cannot flush to disk: ") + std::strerror(errno));
}

}  // namespace

void writeFileAtomically(const std::filesystem::path& path, const std::string& text) {
  writeFileAtomically(path, std::vector<unsigned char>(text.begin(), text.end()));
}

void writeFileAtomically(const std::filesystem::path& path, const std::vector<unsigned char>& bytes) {
  std::filesystem::path tmp = path;
  tmp += ".tmp";
  writeFileDurably(tmp, bytes);
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw CaptureError(path.string(), "cannot rename temporary file: " + ec.message());
}


void quietOpenCv() {
  static const bool once = [] {
    cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
    return true;
  }();
  (void)once;
}

cv::Mat readColour(const std::string& path) {
  cv::Mat img = decode(path, cv::IMREAD_COLOR);
  if (img.depth() != CV_8U) throw CaptureError(path, "colour image is not 8-bit");
  cv::cvtColor(img, img, cv::COLOR_BGR2RGB);
  return img;
}

cv::Mat readDepth(const std::string& path, double unitsMetres) {
  cv::Mat raw = decode(path, cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR);
  if (raw.channels() != 1) throw CaptureError(path, "depth image has " + std::to_string(raw.channels()) + " channels, expected 1");
  cv::Mat metres;
  if (raw.depth() == CV_16U) {
    raw.convertTo(metres, CV_32F, unitsMetres);
  } else if (raw.depth() == CV_32F) {
    metres = raw;
    for (int y = 0; y < metres.rows; ++y) {
      const float* row = metres.ptr<float>(y);
      for (int x = 0; x < metres.cols; ++x)
        if (!std::isfinite(row[x]) || row[x] < 0.f)
          throw CaptureError(path, "depth holds a non-finite or negative value at pixel (" + std::to_string(x) +
                                       ", " + std::to_string(y) + ")");
    }
  } else {
    throw CaptureError(path, "depth image must be 16-bit integer or 32-bit float");
  }
  return metres;
}

cv::Mat readAny(const std::string& path) {
  cv::Mat img = decode(path, cv::IMREAD_UNCHANGED);
  if (img.channels() == 3) cv::cvtColor(img, img, cv::COLOR_BGR2RGB);
  else if (img.channels() == 4) cv::cvtColor(img, img, cv::COLOR_BGRA2RGB);
  else if (img.channels() == 1) cv::cvtColor(img, img, cv::COLOR_GRAY2RGB);
  return img;
}

cv::Mat depthToUnits(const cv::Mat& depthMetres, double unitsMetres) {
  CV_Assert(depthMetres.type() == CV_32FC1 && unitsMetres > 0);
  cv::Mat out(depthMetres.size(), CV_16UC1);
  for (int y = 0; y < depthMetres.rows; ++y) {
    const float* in = depthMetres.ptr<float>(y);
    uint16_t* o = out.ptr<uint16_t>(y);
    for (int x = 0; x < depthMetres.cols; ++x) {
      const double u = std::isfinite(in[x]) && in[x] > 0 ? std::round(in[x] / unitsMetres) : 0.0;
      o[x] = u > 0 && u <= 65535 ? static_cast<uint16_t>(u) : 0;
    }
  }
  return out;
}

std::vector<unsigned char> encodePng(const cv::Mat& image, const std::string& nameForErrors) {
  // A fresh matrix for the conversion: `bgr = image` would share the caller's pixels, and cvtColor would
  // then swap the caller's channels in place.
  cv::Mat bgr;
  if (image.channels() == 3)
    cv::cvtColor(image, bgr, cv::COLOR_RGB2BGR);
  else
    bgr = image;
  std::vector<unsigned char> bytes;
  if (!cv::imencode(".png", bgr, bytes, {cv::IMWRITE_PNG_COMPRESSION, 3}))
    throw CaptureError(nameForErrors, "cannot encode PNG");
  return bytes;
}

}  // namespace mrgi::capture
