#include "capture/npz.h"

#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <regex>

#include "capture/checks.h"
#include "capture/error.h"

namespace mrgi::capture {
namespace {

uint64_t le(const std::string& b, size_t at, int bytes, const std::string& where) {
  if (at + bytes > b.size()) throw CaptureError(where, "truncated zip structure");
  uint64_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(b[at + i]);
  return v;
}

}  // namespace

cv::Mat parseNpy(const std::string& b, const std::string& where) {
  if (b.size() < 10 || b.compare(0, 6, "\x93NUMPY") != 0) throw CaptureError(where, "not a .npy array (bad magic)");
  const int major = static_cast<unsigned char>(b[6]);
  const size_t lenBytes = major == 1 ? 2 : 4;
  const size_t headerLen = le(b, 8, static_cast<int>(lenBytes), where);
  const size_t dataAt = 8 + lenBytes + headerLen;
  if (dataAt > b.size()) throw CaptureError(where, "truncated .npy header");
  const std::string header = b.substr(8 + lenBytes, headerLen);
  std::smatch m;
  if (!std::regex_search(header, m, std::regex(R"('descr'\s*:\s*'([<>|=])([uif])(\d+)')")))
    throw CaptureError(where, "unsupported .npy dtype in its header");
  if (m[1] == ">") throw CaptureError(where, "big-endian .npy arrays are not supported");
  const char kind = m[2].str()[0];
  const int size = m[3].length() <= 2 ? std::stoi(m[3]) : 0;  // 1, 2, 4 or 8; anything longer is refused below
  if (std::regex_search(header, std::regex(R"('fortran_order'\s*:\s*True)")))
    throw CaptureError(where, "Fortran-ordered .npy arrays are not supported");
  if (!std::regex_search(header, m, std::regex(R"('shape'\s*:\s*\(([^)]*)\))")))
    throw CaptureError(where, ".npy header has no shape");
  std::vector<int> shape;
  const std::string dims = m[1];
  const std::regex number(R"(\d+)");
  for (std::sregex_iterator it(dims.begin(), dims.end(), number), end; it != end; ++it) {
    // Each dimension 1..2^24 (found by the npy fuzzer: std::stoi threw out_of_range past int, and a zero
    // dimension reached memcpy with no buffer).
    const std::string digits = it->str();
    const long long d = digits.size() <= 9 ? std::stoll(digits) : -1;
    if (d < 1 || d > (1 << 24))
      throw CaptureError(where, ".npy dimension " + digits.substr(0, 12) + " out of range [1, 16777216]");
    shape.push_back(static_cast<int>(d));
  }
  if (shape.empty() || shape.size() > 3) throw CaptureError(where, ".npy arrays of 1-3 dimensions only");
  int depth = -1;
  if (kind == 'u' && size == 1)
    depth = CV_8U;
  else if (kind == 'u' && size == 2)
    depth = CV_16U;
  else if (kind == 'i' && size == 2)
    depth = CV_16S;
  else if (kind == 'i' && size == 4)
    depth = CV_32S;
  else if (kind == 'f' && size == 4)
    depth = CV_32F;
  else if (kind == 'f' && size == 8)
    depth = CV_64F;
  else
    throw CaptureError(where, std::string("unsupported .npy dtype ") + kind + std::to_string(size));
  const int rows = shape.size() >= 2 ? shape[0] : 1, cols = shape.size() >= 2 ? shape[1] : shape[0];
  const int channels = shape.size() == 3 ? shape[2] : 1;
  if (channels < 1 || channels > CV_CN_MAX) throw CaptureError(where, "unsupported .npy channel count");
  // The data must be there before anything is allocated for it.
  const unsigned long long bytes =
      static_cast<unsigned long long>(rows) * cols * channels * static_cast<unsigned long long>(size);
  if (b.size() - dataAt < bytes) throw CaptureError(where, "truncated .npy data");
  cv::Mat out(rows, cols, CV_MAKETYPE(depth, channels));
  std::memcpy(out.data, b.data() + dataAt, bytes);
  return out;
}

cv::Mat readNpzArray(const std::string& path, const std::string& name) {
  const std::string b = readFileBounded(path, kMaxBinaryFileBytes, ".npz archive");
  // End of central directory: the last "PK\5\6" record.
  const size_t eocd = b.rfind(std::string("PK\x05\x06", 4));
  if (eocd == std::string::npos) throw CaptureError(path, "not a zip/npz archive (no end of central directory)");
  const uint64_t entries = le(b, eocd + 10, 2, path);
  uint64_t at = le(b, eocd + 16, 4, path);
  for (uint64_t e = 0; e < entries; ++e) {
    if (le(b, at, 4, path) != 0x02014b50) throw CaptureError(path, "corrupt zip central directory");
    const uint64_t method = le(b, at + 10, 2, path);
    uint64_t size = le(b, at + 20, 4, path);
    const uint64_t nameLen = le(b, at + 28, 2, path), extraLen = le(b, at + 30, 2, path),
                   commentLen = le(b, at + 32, 2, path);
    uint64_t local = le(b, at + 42, 4, path);
    const std::string entry = b.substr(at + 46, nameLen);
    // Zip64: 0xFFFFFFFF fields live in extra block 0x0001 (uncompressed, compressed, offset).
    for (uint64_t x = at + 46 + nameLen; x + 4 <= at + 46 + nameLen + extraLen;) {
      const uint64_t id = le(b, x, 2, path), len = le(b, x + 2, 2, path);
      if (id == 1) {
        uint64_t f = x + 4;
        if (le(b, at + 24, 4, path) == 0xFFFFFFFFu) f += 8;
        if (size == 0xFFFFFFFFu) size = le(b, f, 8, path), f += 8;
        if (local == 0xFFFFFFFFu) local = le(b, f, 8, path);
      }
      x += 4 + len;
    }
    if (entry == name) {
      if (method != 0)
        throw CaptureError(path,
                           "entry " + name + " is compressed (only numpy.savez, not savez_compressed, is supported)");
      if (le(b, local, 4, path) != 0x04034b50) throw CaptureError(path, "corrupt zip local header for " + name);
      const uint64_t dataAt = local + 30 + le(b, local + 26, 2, path) + le(b, local + 28, 2, path);
      if (dataAt + size > b.size()) throw CaptureError(path, "truncated entry " + name);
      return parseNpy(b.substr(dataAt, size), path + ":" + name);
    }
    at += 46 + nameLen + extraLen + commentLen;
  }
  throw CaptureError(path, "no entry " + name + " in the archive");
}

}  // namespace mrgi::capture
