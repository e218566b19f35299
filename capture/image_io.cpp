#include "capture/image_io.h"

#include <Imath/half.h>
#include <ImfChannelList.h>
#include <ImfCheckFile.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <fcntl.h>
#include <jpeglib.h>
#include <png.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <csetjmp>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <mutex>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/checks.h"
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
  if (!std::filesystem::exists(path, ec)) throw CaptureError(path, "file is missing");
  const std::string bytes = readFileBounded(path, kMaxBinaryFileBytes, "image");
  return {bytes.begin(), bytes.end()};
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

/// OpenEXR reads from and writes to memory through these, so no temporary file is ever made (OpenCV's EXR
/// codec goes through one in /tmp) and nothing is printed.
class ExrMemoryIn final : public Imf::IStream {
 public:
  ExrMemoryIn(const std::vector<unsigned char>& bytes, const std::string& path)
      : Imf::IStream(path.c_str()), bytes_(bytes) {}
  bool read(char c[], int n) override {
    if (n < 0 || static_cast<uint64_t>(n) > bytes_.size() - std::min<uint64_t>(at_, bytes_.size()))
      throw std::runtime_error("file is truncated");
    std::memcpy(c, bytes_.data() + at_, static_cast<size_t>(n));
    at_ += static_cast<uint64_t>(n);
    return at_ < bytes_.size();
  }
  uint64_t tellg() override { return at_; }
  void seekg(uint64_t pos) override { at_ = pos; }

 private:
  const std::vector<unsigned char>& bytes_;
  uint64_t at_ = 0;
};

class ExrMemoryOut final : public Imf::OStream {
 public:
  explicit ExrMemoryOut(const std::string& path) : Imf::OStream(path.c_str()) {}
  void write(const char c[], int n) override {
    if (at_ + static_cast<uint64_t>(n) > bytes.size()) bytes.resize(at_ + static_cast<uint64_t>(n));
    std::memcpy(bytes.data() + at_, c, static_cast<size_t>(n));
    at_ += static_cast<uint64_t>(n);
  }
  uint64_t tellp() override { return at_; }
  void seekp(uint64_t pos) override { at_ = pos; }
  std::vector<unsigned char> bytes;

 private:
  uint64_t at_ = 0;
};

bool isExr(const std::vector<unsigned char>& bytes) {
  return bytes.size() >= 4 && bytes[0] == 0x76 && bytes[1] == 0x2f && bytes[2] == 0x31 && bytes[3] == 0x01;
}

/// An EXR decoded by OpenEXR from memory as 32-bit float, BGR (or one channel for a luminance-only file),
/// as cv::IMREAD_UNCHANGED gives. The file is first checked by OpenEXR's own validator, which bounds memory
/// and time on damaged files (its stricter core check is off: it refuses sound files written by Blender).
/// Walks the EXR header(s) before OpenEXR does: every attribute must fit in the file. OpenEXR allocates an
/// attribute of the size the file declares before reading it, so a damaged size meant allocating up to
/// 2 GB for a file of a few bytes (found by the image fuzzer as a time-out).
void checkExrHeader(const std::vector<unsigned char>& bytes, const std::string& path) {
  auto bad = [&](const std::string& why) { throw CaptureError(path, "cannot decode EXR (" + why + ")"); };
  if (bytes.size() < 8) bad("file is truncated");
  const bool multipart = (bytes[5] & 0x10) != 0;  // version field, flags byte: bit 12 of the 32-bit field
  size_t at = 8;
  auto readString = [&]() {
    std::string out;
    while (true) {
      if (at >= bytes.size()) bad("header is truncated");
      const char c = static_cast<char>(bytes[at++]);
      if (c == '\0') return out;
      if (out.size() >= 255) bad("header holds a name longer than 255 bytes");
      out += c;
    }
  };
  for (int headers = 0, attributes = 0;; ++headers) {
    if (headers > 1000) bad("more than 1000 parts");
    while (true) {
      const std::string name = readString();
      if (name.empty()) break;  // end of this header
      if (++attributes > 100000) bad("more than 100000 header attributes");
      const std::string type = readString();
      if (at + 4 > bytes.size()) bad("header is truncated");
      auto int32At = [&](size_t i) {
        return static_cast<int32_t>(uint32_t(bytes[i]) | uint32_t(bytes[i + 1]) << 8 | uint32_t(bytes[i + 2]) << 16 |
                                    uint32_t(bytes[i + 3]) << 24);
      };
      const uint32_t size = static_cast<uint32_t>(int32At(at));
      at += 4;
      if (name == "dataWindow" && type == "box2i" && size == 16 && at + 16 <= bytes.size()) {
        // The image size, checked before OpenEXR allocates line buffers for it (a 5-million-pixel-wide line
        // in a 500-byte file was a time-out under the image fuzzer): at most 16384 a side, and no more
        // pixels than any codec packs into the file (deflate tops out near 1000:1 on bytes).
        const int64_t w = int64_t(int32At(at + 8)) - int32At(at) + 1,
                      h = int64_t(int32At(at + 12)) - int32At(at + 4) + 1;
        if (w <= 0 || h <= 0 || w > 16384 || h > 16384)
          throw CaptureError(path,
                             "EXR image of " + std::to_string(w) + "x" + std::to_string(h) + ", at most 16384 a side");
        if (static_cast<double>(w) * static_cast<double>(h) > 4096.0 * static_cast<double>(bytes.size()) + 1048576.0)
          throw CaptureError(path, "EXR image of " + std::to_string(w) + "x" + std::to_string(h) + " in a file of " +
                                       std::to_string(bytes.size()) + " bytes: damaged");
      }
      if (size > bytes.size() - at) {
        std::string shown;
        for (char c : name.substr(0, 40)) shown += c >= 0x20 && c < 0x7f ? c : '?';
        bad("header attribute '" + shown + "' declares " + std::to_string(size) + " bytes, past the end of the file");
      }
      at += size;
    }
    if (!multipart) return;
    if (at >= bytes.size()) bad("header is truncated");
    if (bytes[at] == 0) return;  // an empty header ends the list of parts
  }
}

cv::Mat decodeExr(const std::vector<unsigned char>& bytes, const std::string& path) {
  checkExrHeader(bytes, path);
  try {
    if (Imf::checkOpenEXRFile(reinterpret_cast<const char*>(bytes.data()), bytes.size(), true, true, false))
      throw CaptureError(path, "cannot decode EXR (corrupt or truncated)");
    ExrMemoryIn in(bytes, path);
    Imf::InputFile file(in, 1);
    const Imath::Box2i window = file.header().dataWindow();
    const int64_t width = int64_t(window.max.x) - window.min.x + 1, height = int64_t(window.max.y) - window.min.y + 1;
    if (width <= 0 || height <= 0 || width > 16384 || height > 16384)
      throw CaptureError(
          path, "EXR image of " + std::to_string(width) + "x" + std::to_string(height) + ", at most 16384 a side");
    const Imf::ChannelList& channels = file.header().channels();
    const bool rgb = channels.findChannel("R") && channels.findChannel("G") && channels.findChannel("B");
    const bool grey = !rgb && channels.findChannel("Y");
    if (!rgb && !grey) throw CaptureError(path, "EXR holds neither R, G, B nor Y channels");
    cv::Mat img(static_cast<int>(height), static_cast<int>(width), rgb ? CV_32FC3 : CV_32FC1);
    const size_t xStride = img.elemSize(), yStride = img.step;
    Imf::FrameBuffer frame;
    auto* base = reinterpret_cast<char*>(img.data);
    if (rgb) {
      frame.insert("B", Imf::Slice::Make(Imf::FLOAT, base, window, xStride, yStride));
      frame.insert("G", Imf::Slice::Make(Imf::FLOAT, base + sizeof(float), window, xStride, yStride));
      frame.insert("R", Imf::Slice::Make(Imf::FLOAT, base + 2 * sizeof(float), window, xStride, yStride));
    } else {
      frame.insert("Y", Imf::Slice::Make(Imf::FLOAT, base, window, xStride, yStride));
    }
    file.setFrameBuffer(frame);
    file.readPixels(window.min.y, window.max.y);
    return img;
  } catch (const CaptureError&) {
    throw;
  } catch (const std::exception& e) {
    std::string what = e.what();
    if (const size_t nl = what.find('\n'); nl != std::string::npos) what.resize(nl);
    throw CaptureError(path, "cannot decode EXR (" + what + ")");
  }
}

/// libjpeg's errors and warnings go to our handlers: an error ends the decode through longjmp; a warning
/// ("corrupt JPEG data: premature end of data segment", which libjpeg would print and then return a
/// partly grey image for) makes the file count as corrupt too.
struct JpegErrors {
  jpeg_error_mgr mgr;
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX] = "";
  int warnings = 0;
};
[[noreturn]] void jpegError(j_common_ptr info) {
  auto* e = reinterpret_cast<JpegErrors*>(info->err);
  (*info->err->format_message)(info, e->message);
  std::longjmp(e->jump, 1);
}
void jpegMessage(j_common_ptr info, int level) {
  auto* e = reinterpret_cast<JpegErrors*>(info->err);
  if (level < 0 && e->warnings++ == 0) (*info->err->format_message)(info, e->message);
}
void jpegSilent(j_common_ptr) {}
/// A progressive JPEG can hold thousands of tiny scans that take minutes to decode; more than this many is
/// refused.
constexpr int kMaxJpegScans = 256;
void jpegProgress(j_common_ptr info) {
  auto* d = reinterpret_cast<j_decompress_ptr>(info);
  if (d->input_scan_number > kMaxJpegScans) {
    auto* e = reinterpret_cast<JpegErrors*>(info->err);
    std::snprintf(e->message, sizeof e->message, "more than %d scans", kMaxJpegScans);
    std::longjmp(e->jump, 1);
  }
}

/// A JPEG decoded by libjpeg with our handlers: 8-bit BGR, or one grey channel where the file is grey and
/// `colour` is false (as OpenCV's IMREAD_COLOR / IMREAD_UNCHANGED give).
cv::Mat decodeJpeg(const std::vector<unsigned char>& bytes, bool colour, const std::string& path) {
  jpeg_decompress_struct info{};
  JpegErrors errors;
  info.err = jpeg_std_error(&errors.mgr);
  errors.mgr.error_exit = jpegError;
  errors.mgr.emit_message = jpegMessage;
  errors.mgr.output_message = jpegSilent;
  jpeg_progress_mgr progress{};
  progress.progress_monitor = jpegProgress;
  cv::Mat img;
  if (setjmp(errors.jump)) {
    jpeg_destroy_decompress(&info);
    throw CaptureError(path, std::string("cannot decode JPEG (") + errors.message + ")");
  }
  jpeg_create_decompress(&info);
  info.progress = &progress;
  jpeg_mem_src(&info, bytes.data(), static_cast<unsigned long>(bytes.size()));
  jpeg_read_header(&info, TRUE);
  if (info.image_width == 0 || info.image_height == 0 || info.image_width > 16384 || info.image_height > 16384) {
    std::snprintf(errors.message, sizeof errors.message, "image of %ux%u, at most 16384 a side", info.image_width,
                  info.image_height);
    std::longjmp(errors.jump, 1);
  }
  const bool grey = !colour && info.num_components == 1;
  info.out_color_space = grey ? JCS_GRAYSCALE : JCS_EXT_BGR;
  jpeg_start_decompress(&info);
  img.create(static_cast<int>(info.output_height), static_cast<int>(info.output_width), grey ? CV_8UC1 : CV_8UC3);
  while (info.output_scanline < info.output_height) {
    JSAMPROW row = img.ptr(static_cast<int>(info.output_scanline));
    jpeg_read_scanlines(&info, &row, 1);
  }
  jpeg_finish_decompress(&info);
  jpeg_destroy_decompress(&info);
  if (errors.warnings > 0) throw CaptureError(path, std::string("cannot decode JPEG (") + errors.message + ")");
  return img;
}

/// Radiance RGBE (.hdr), the format light probes are shared in, decoded here from memory: OpenCV's decoder
/// goes through a temporary file and a C parser we cannot bound. Reads what Greg Ward's reference reader
/// (and OpenCV's, which is built on it) reads: a "#?" header up to its blank line (FORMAT must be
/// 32-bit_rle_rgbe when given; EXPOSURE is ignored, as they ignore it), the standard "-Y H +X W"
/// orientation, then scanlines either adaptive run-length encoded or flat; each pixel (r, g, b, e) is
/// (r, g, b) * 2^(e - 136), 0 where e is 0. Returns 32-bit float BGR, as cv::imdecode gives.
bool isRadiance(const std::vector<unsigned char>& bytes) {
  return bytes.size() >= 2 && bytes[0] == '#' && bytes[1] == '?';
}
cv::Mat decodeRadiance(const std::vector<unsigned char>& bytes, const std::string& path) {
  auto bad = [&](const std::string& why) -> void {
    throw CaptureError(path, "cannot decode Radiance HDR (" + why + ")");
  };
  size_t at = 0;
  auto line = [&]() {
    const size_t end = std::find(bytes.begin() + static_cast<std::ptrdiff_t>(at), bytes.end(), '\n') - bytes.begin();
    if (end >= bytes.size()) bad("the header does not end");
    std::string l(bytes.begin() + static_cast<std::ptrdiff_t>(at), bytes.begin() + static_cast<std::ptrdiff_t>(end));
    at = end + 1;
    if (!l.empty() && l.back() == '\r') l.pop_back();
    return l;
  };
  line();  // "#?RADIANCE" or another program's name
  for (int n = 0;; ++n) {
    if (n > 1000) bad("a header of more than 1000 lines");
    const std::string l = line();
    if (l.empty()) break;
    if (l.rfind("FORMAT=", 0) == 0 && l != "FORMAT=32-bit_rle_rgbe")
      bad("only 32-bit_rle_rgbe is supported, not " + excerpt(l.substr(7), 30));
  }
  const std::string resolution = line();
  int h = 0, w = 0;
  char tail = 0;
  if (std::sscanf(resolution.c_str(), "-Y %d +X %d%c", &h, &w, &tail) != 2)
    bad("the resolution line must read '-Y height +X width', not '" + excerpt(resolution, 40) + "'");
  if (w <= 0 || h <= 0 || w > 16384 || h > 16384)
    bad("image of " + std::to_string(w) + "x" + std::to_string(h) + ", at most 16384 a side");
  // Each scanline takes at least 4 bytes per 127 pixels and channel when run-length encoded: a file too
  // short for its size is refused before memory is taken for it.
  const size_t minLine = std::min<size_t>(4 * static_cast<size_t>(w), 4 + 8 * ((static_cast<size_t>(w) + 126) / 127));
  if (bytes.size() - at < minLine * static_cast<size_t>(h))
    bad("truncated: too short for " + std::to_string(w) + "x" + std::to_string(h));
  cv::Mat out(h, w, CV_32FC3);
  std::vector<unsigned char> rgbe(4 * static_cast<size_t>(w));
  bool flat = w < 8 || w > 0x7fff;
  for (int y = 0; y < h; ++y) {
    if (!flat) {
      if (at + 4 > bytes.size()) bad("truncated at scanline " + std::to_string(y));
      const unsigned char* b = bytes.data() + at;
      if (b[0] == 2 && b[1] == 2 && !(b[2] & 0x80)) {
        if (((b[2] << 8) | b[3]) != w) bad("scanline " + std::to_string(y) + " has the wrong width");
        at += 4;
        for (int c = 0; c < 4; ++c)
          for (int x = 0; x < w;) {
            if (at >= bytes.size()) bad("truncated at scanline " + std::to_string(y));
            int count = bytes[at++];
            const bool run = count > 128;
            if (run) count -= 128;
            if (count == 0 || count > w - x) bad("a run of scanline " + std::to_string(y) + " is out of bounds");
            if (run) {
              if (at >= bytes.size()) bad("truncated at scanline " + std::to_string(y));
              const unsigned char v = bytes[at++];
              for (int k = 0; k < count; ++k) rgbe[4 * static_cast<size_t>(x++) + c] = v;
            } else {
              if (at + static_cast<size_t>(count) > bytes.size()) bad("truncated at scanline " + std::to_string(y));
              for (int k = 0; k < count; ++k) rgbe[4 * static_cast<size_t>(x++) + c] = bytes[at++];
            }
          }
      } else {
        flat = true;  // not run-length encoded: this scanline and the rest are flat, as the reference reader has it
      }
    }
    if (flat) {
      if (at + rgbe.size() > bytes.size()) bad("truncated at scanline " + std::to_string(y));
      std::memcpy(rgbe.data(), bytes.data() + at, rgbe.size());
      at += rgbe.size();
    }
    float* row = out.ptr<float>(y);
    for (int x = 0; x < w; ++x) {
      const unsigned char* p = &rgbe[4 * static_cast<size_t>(x)];
      const float f = p[3] == 0 ? 0.f : std::ldexp(1.f, p[3] - 136);
      row[3 * x + 0] = p[2] * f;  // BGR
      row[3 * x + 1] = p[1] * f;
      row[3 * x + 2] = p[0] * f;
    }
  }
  return out;
}

/// OpenCV's decoders print to std::cerr when a header throws; while they run, std::cerr goes nowhere.
class SilenceCerr {
 public:
  SilenceCerr() : lock_(mutex()), saved_(std::cerr.rdbuf(nullptr)) {}
  ~SilenceCerr() { std::cerr.rdbuf(saved_); }

 private:
  static std::mutex& mutex() {
    static std::mutex m;
    return m;
  }
  std::lock_guard<std::mutex> lock_;
  std::streambuf* saved_;
};

cv::Mat decode(const std::string& path, int flags) {
  quietOpenCv();
  const std::vector<unsigned char> bytes = readBytes(path);
  if (bytes.empty()) throw CaptureError(path, "file is empty");
  static const unsigned char kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  const bool png = bytes.size() >= 8 && std::memcmp(bytes.data(), kPngSignature, 8) == 0;
  if (png && flags == cv::IMREAD_COLOR) return decodePng(bytes, true, path);
  if (png) return decodePng(bytes, false, path);  // depth (ANYDEPTH|ANYCOLOR) and fisheye (UNCHANGED, alpha dropped)
  if (isExr(bytes)) return decodeExr(bytes, path);
  if (isRadiance(bytes)) {
    if (flags == cv::IMREAD_COLOR)
      throw CaptureError(path, "is a Radiance HDR image; an 8-bit colour image is expected here");
    return decodeRadiance(bytes, path);
  }
  if (bytes.size() >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF)
    return decodeJpeg(bytes, flags == cv::IMREAD_COLOR, path);
  // Only formats we name reach OpenCV (BMP, PNM, TIFF): Debian's OpenCV also carries GDAL and GDCM
  // (DICOM) decoders, which print to the terminal and abort on damaged input (found by the image fuzzer).
  const bool bmp = bytes.size() >= 2 && bytes[0] == 'B' && bytes[1] == 'M';
  const bool pnm = bytes.size() >= 2 && bytes[0] == 'P' && bytes[1] >= '1' && bytes[1] <= '6';
  const bool tiff = bytes.size() >= 4 && ((bytes[0] == 'I' && bytes[1] == 'I' && bytes[2] == 42 && bytes[3] == 0) ||
                                          (bytes[0] == 'M' && bytes[1] == 'M' && bytes[2] == 0 && bytes[3] == 42));
  if (!bmp && !pnm && !tiff)
    throw CaptureError(path,
                       "cannot decode image: not a supported format (PNG, JPEG, EXR, Radiance HDR, BMP, PNM, TIFF)");
  cv::Mat img;
  try {
    const SilenceCerr quiet;
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
    // FFmpeg (OpenCV's video writer) prints its own errors ("encoder timebase is not set") unless OpenCV
    // is told a log level before it loads FFmpeg: quiet (AV_LOG_QUIET), unless the user set one.
    ::setenv("OPENCV_FFMPEG_LOGLEVEL", "-8", 0);
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
  if (raw.channels() != 1)
    throw CaptureError(path, "depth image has " + std::to_string(raw.channels()) + " channels, expected 1");
  cv::Mat metres;
  if (raw.depth() == CV_16U) {
    raw.convertTo(metres, CV_32F, unitsMetres);
  } else if (raw.depth() == CV_32F) {
    metres = raw;
    for (int y = 0; y < metres.rows; ++y) {
      const float* row = metres.ptr<float>(y);
      for (int x = 0; x < metres.cols; ++x)
        if (!std::isfinite(row[x]) || row[x] < 0.f)
          throw CaptureError(path, "depth holds a non-finite or negative value at pixel (" + std::to_string(x) + ", " +
                                       std::to_string(y) + ")");
    }
  } else {
    throw CaptureError(path, "depth image must be 16-bit integer or 32-bit float");
  }
  return metres;
}

cv::Mat readAny(const std::string& path) {
  cv::Mat img = decode(path, cv::IMREAD_UNCHANGED);
  if (img.depth() == CV_32F || img.depth() == CV_64F) {
    // NaN or inf in a float image would reach every sum made of it: refused here, naming the pixel.
    cv::Point at;
    if (!cv::checkRange(img.reshape(1), true, &at))
      throw CaptureError(path, "holds a non-finite value at pixel (" + std::to_string(at.x / img.channels()) + ", " +
                                   std::to_string(at.y) + ")");
  }
  if (img.channels() == 3)
    cv::cvtColor(img, img, cv::COLOR_BGR2RGB);
  else if (img.channels() == 4)
    cv::cvtColor(img, img, cv::COLOR_BGRA2RGB);
  else if (img.channels() == 1)
    cv::cvtColor(img, img, cv::COLOR_GRAY2RGB);
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

std::vector<unsigned char> encodeExr(const cv::Mat& rgb, bool half, const std::string& nameForErrors) {
  if (rgb.empty() || rgb.depth() != CV_32F || (rgb.channels() != 3 && rgb.channels() != 1))
    throw CaptureError(nameForErrors, "cannot encode EXR (expects a 32-bit float RGB or grey image)");
  const cv::Mat img = rgb.isContinuous() ? rgb : rgb.clone();
  try {
    Imf::Header header(img.cols, img.rows);
    header.compression() = Imf::ZIP_COMPRESSION;
    const Imf::PixelType stored = half ? Imf::HALF : Imf::FLOAT;
    const char* names[3] = {"R", "G", "B"};
    // OpenEXR writes only what the frame buffer holds in the stored type: half pixels are converted here.
    const int n = img.channels();
    std::vector<Imath::half> halves;
    if (half) {
      halves.resize(img.total() * static_cast<size_t>(n));
      const auto* f = img.ptr<float>();
      for (size_t i = 0; i < halves.size(); ++i) halves[i] = Imath::half(f[i]);
    }
    char* base =
        half ? reinterpret_cast<char*>(halves.data()) : reinterpret_cast<char*>(const_cast<unsigned char*>(img.data));
    const size_t xStride = (half ? sizeof(Imath::half) : sizeof(float)) * static_cast<size_t>(n);
    const size_t yStride = xStride * static_cast<size_t>(img.cols);
    Imf::FrameBuffer frame;
    for (int c = 0; c < n; ++c) {
      const char* name = n == 3 ? names[c] : "Y";
      header.channels().insert(name, Imf::Channel(stored));
      frame.insert(
          name, Imf::Slice(stored, base + static_cast<size_t>(c) * xStride / static_cast<size_t>(n), xStride, yStride));
    }
    ExrMemoryOut out(nameForErrors);
    Imf::OutputFile file(out, header, 1);
    file.setFrameBuffer(frame);
    file.writePixels(img.rows);
    return std::move(out.bytes);
  } catch (const std::exception& e) {
    throw CaptureError(nameForErrors, std::string("cannot encode EXR (") + e.what() + ")");
  }
}

namespace {
/// An RGB image in OpenCV's channel order, a grey one as it is. A fresh matrix for the conversion: `bgr =
/// image` would share the caller's pixels, and cvtColor would then swap the caller's channels in place.
cv::Mat toBgr(const cv::Mat& image) {
  cv::Mat bgr;
  if (image.channels() == 3)
    cv::cvtColor(image, bgr, cv::COLOR_RGB2BGR);
  else
    bgr = image;
  return bgr;
}

void pngWrite(png_structp png, png_bytep data, png_size_t n) {
  auto* out = static_cast<std::vector<unsigned char>*>(png_get_io_ptr(png));
  out->insert(out->end(), data, data + n);
}
void pngFlush(png_structp) {}
}  // namespace

std::vector<unsigned char> encodePng(const cv::Mat& image, const std::string& nameForErrors) {
  const int channels = image.channels();
  if ((image.depth() != CV_8U && image.depth() != CV_16U) || (channels != 1 && channels != 3 && channels != 4) ||
      image.empty())
    throw CaptureError(nameForErrors, "cannot encode PNG (an 8- or 16-bit image of 1, 3 or 4 channels is needed)");
  // libpng straight from the caller's rows (RGB is PNG's own order: no conversion, no copy), each row filtered by
  // its difference from the row above and deflated run-length (Z_RLE) at level 1: on camera frames twice as fast as
  // OpenCV's encoder with the same deflate and every row filter tried, for files 13 % larger (BM_EncodePng). The
  // writer thread shares the CPU with the frame loop.
  std::vector<unsigned char> bytes;
  bytes.reserve(image.total() * image.elemSize() / 2 + 1024);
  PngErrors errors;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &errors, pngError, pngWarning);
  if (!png) throw CaptureError(nameForErrors, "cannot encode PNG (out of memory)");
  png_infop info = png_create_info_struct(png);
  if (!info || setjmp(errors.jump)) {
    png_destroy_write_struct(&png, &info);
    throw CaptureError(nameForErrors, std::string("cannot encode PNG (") + errors.message + ")");
  }
  png_set_write_fn(png, &bytes, pngWrite, pngFlush);
  const int type = channels == 1 ? PNG_COLOR_TYPE_GRAY : channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_RGB_ALPHA;
  png_set_IHDR(png, info, static_cast<png_uint_32>(image.cols), static_cast<png_uint_32>(image.rows),
               image.depth() == CV_16U ? 16 : 8, type, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_UP);
  png_set_compression_level(png, 1);
  png_set_compression_strategy(png, Z_RLE);
  png_write_info(png, info);
  if (image.depth() == CV_16U) png_set_swap(png);  // PNG is big-endian, the host little-endian
  for (int y = 0; y < image.rows; ++y) png_write_row(png, const_cast<png_bytep>(image.ptr<png_byte>(y)));
  png_write_end(png, info);
  png_destroy_write_struct(&png, &info);
  return bytes;
}

std::vector<unsigned char> encodeJpeg(const cv::Mat& image, int quality, const std::string& nameForErrors) {
  const cv::Mat bgr = toBgr(image);
  std::vector<unsigned char> bytes;
  if (image.depth() != CV_8U ||
      !cv::imencode(".jpg", bgr, bytes, {cv::IMWRITE_JPEG_QUALITY, std::clamp(quality, 1, 100)}))
    throw CaptureError(nameForErrors, "cannot encode JPEG");
  return bytes;
}

}  // namespace mrgi::capture
