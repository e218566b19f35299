#include "runtime/output.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <sstream>

#include "capture/checks.h"
#include "capture/error.h"
#include "capture/image_io.h"
#include "capture/json_io.h"

namespace fs = std::filesystem;

namespace mrgi::runtime {

void writeExr(const std::string& path, const cv::Mat& rgb, bool half) {
  // Outputs hold only finite numbers: a computation that gave nan or inf is an error, never a file of them.
  cv::Point at;
  if (!rgb.empty() && !cv::checkRange(rgb.reshape(1), true, &at))
    throw capture::CaptureError(path, "not written: pixel (" + std::to_string(at.x / rgb.channels()) + ", " +
                                          std::to_string(at.y) + ") came out non-finite");
  capture::writeFileAtomically(path, capture::encodeExr(rgb, half, path));
}

namespace {
uint32_t bigEndian32(const unsigned char* p) {
  return uint32_t(p[0]) << 24 | uint32_t(p[1]) << 16 | uint32_t(p[2]) << 8 | p[3];
}
const unsigned char kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};

/// The text of a PNG's first "Software" tEXt chunk before its image data ("" when none or not a PNG).
std::string pngSoftware(const std::string& bytes) {
  if (bytes.size() < 8 || std::memcmp(bytes.data(), kPngSignature, 8) != 0) return {};
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  for (size_t at = 8; at + 12 <= bytes.size();) {
    const size_t length = bigEndian32(p + at);
    if (length > bytes.size() - at - 12) break;
    const std::string type(bytes, at + 4, 4);
    if (type == "IDAT" || type == "IEND") break;
    if (type == "tEXt") {
      const std::string data(bytes, at + 8, length);
      const size_t nul = data.find('\0');
      if (nul != std::string::npos && data.compare(0, nul, "Software") == 0) return data.substr(nul + 1);
    }
    at += 12 + length;
  }
  return {};
}

/// `png` with a tEXt chunk "Software" = `text` after its header chunk.
std::vector<unsigned char> withPngSoftware(std::vector<unsigned char> png, const std::string& text) {
  const size_t afterHeader = 8 + 12 + 13;  // signature, IHDR (always first, 13 bytes of data)
  std::vector<unsigned char> chunk(8);
  const std::string data = std::string("Software") + '\0' + text;
  const uint32_t length = static_cast<uint32_t>(data.size());
  for (int i = 0; i < 4; ++i) chunk[i] = static_cast<unsigned char>(length >> (24 - 8 * i));
  std::memcpy(chunk.data() + 4, "tEXt", 4);
  chunk.insert(chunk.end(), data.begin(), data.end());
  const uint32_t crc =
      static_cast<uint32_t>(crc32(crc32(0, nullptr, 0), chunk.data() + 4, static_cast<uInt>(chunk.size() - 4)));
  for (int i = 0; i < 4; ++i) chunk.push_back(static_cast<unsigned char>(crc >> (24 - 8 * i)));
  png.insert(png.begin() + static_cast<std::ptrdiff_t>(afterHeader), chunk.begin(), chunk.end());
  return png;
}
}  // namespace

std::string jsonText(const nlohmann::json& j, const std::string& input, int indent) {
  capture::requireFiniteJson(j, input, "the computation");
  return j.dump(indent);
}

std::vector<std::string> inPipelineOrder(const std::vector<std::string>& recorded) {
  // Before the technique's stages, then after them; a name not listed sits with the technique's.
  static const std::vector<std::string> before = {
      "read",        "register",         "depth_filter", "normals",     "marker",    "odometry",
      "relocalise",  "track_model",      "world",        "room_fusion", "room_mesh", "room_albedo",
      "room_bounce", "room_hidden",      "view_mesh",    "mesh",        "albedo",    "lights",
      "prepare",     "technique_inputs", "gbuffer",      "rsm"};
  static const std::vector<std::string> after = {"shade", "render", "composite", "readback", "debug", "dump", "write"};
  const auto rank = [&](const std::string& name) -> size_t {
    if (const auto it = std::find(before.begin(), before.end(), name); it != before.end())
      return static_cast<size_t>(it - before.begin());
    if (const auto it = std::find(after.begin(), after.end(), name); it != after.end())
      return before.size() + 1 + static_cast<size_t>(it - after.begin());
    return before.size();
  };
  std::vector<std::string> out = recorded;
  std::stable_sort(out.begin(), out.end(), [&](const auto& a, const auto& b) { return rank(a) < rank(b); });
  return out;
}

void warnIfRoomCoverageLow(const std::string& file, double coverage, const std::string& around) {
  if (!(coverage < 0.5)) return;
  std::fprintf(stderr,
               "warning: %s: the room covers %.0f %% of the directions around %s: lights from it miss the rest (scan "
               "around, the ceiling included)\n",
               file.c_str(), 100 * coverage, around.c_str());
}

std::string bundledPath(const std::string& relative) {
  std::error_code ec;
  if (fs::exists(relative, ec)) return relative;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (ec) return relative;
  for (fs::path dir = exe.parent_path(); !dir.empty(); dir = dir.parent_path()) {
    if (fs::exists(dir / relative, ec)) return (dir / relative).string();
    if (dir == dir.root_path()) break;
  }
  return relative;
}

std::string describeFolder(const std::string& folder) {
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) return {};
  std::map<std::string, std::vector<std::string>> groups;  // the name with its digit runs as N -> the names
  for (const auto& e : fs::directory_iterator(folder, ec)) {
    std::string name = e.path().filename().string(), pattern;
    if (name == kOutputClaimFile) continue;  // the folder's claim, not an output
    for (const char c : name) pattern += std::isdigit(static_cast<unsigned char>(c)) ? 'N' : c;
    if (e.is_directory(ec)) name += '/', pattern += '/';
    groups[pattern].push_back(name);
  }
  std::string out;
  for (const auto& [pattern, names] : groups) {
    if (!out.empty()) out += ", ";
    out += names.size() > 1 ? pattern + " x " + std::to_string(names.size()) : names.front();
  }
  return out;
}

void writePng(const std::string& path, const cv::Mat& rgb, const std::string& generator) {
  std::vector<unsigned char> png = capture::encodePng(rgb, path);
  if (!generator.empty()) png = withPngSoftware(std::move(png), generator);
  capture::writeFileAtomically(path, png);
}

namespace {
/// Whether bytes are a JSON object whose "generated_by" is generator.
bool jsonGeneratedBy(const std::string& bytes, const std::string& path, const std::string& generator) {
  try {
    const nlohmann::json j = capture::parseJson(bytes, path);
    return j.is_object() && j.contains("generated_by") && j["generated_by"].is_string() &&
           j["generated_by"].get<std::string>() == generator;
  } catch (const capture::InputError&) {
    return false;
  }
}

/// Whether the regular file at path says it was written by generator: a PNG's Software text, a JSON
/// document's generated_by, a "# generated by" first line (or one beginning with firstLinePrefix), an HTML generator
/// meta tag.
bool writtenBy(const std::string& path, const std::string& generator, const std::string& firstLinePrefix) {
  std::error_code ec;
  if (!fs::is_regular_file(fs::symlink_status(path, ec)) || fs::file_size(path, ec) > (1u << 26)) return false;
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  if (pngSoftware(bytes) == generator) return true;
  if (!bytes.empty() && bytes.front() == '{' && jsonGeneratedBy(bytes, path, generator)) return true;
  const std::string line = bytes.substr(0, bytes.find('\n'));
  return line == "# generated by " + generator || (!firstLinePrefix.empty() && line.rfind(firstLinePrefix, 0) == 0) ||
         bytes.substr(0, 4096).find("<meta name=\"generator\" content=\"" + generator + "\">") != std::string::npos;
}
}  // namespace

void checkReplaceable(const std::string& path, const std::string& flag, const std::string& generator,
                      const std::string& firstLinePrefix) {
  if (path.empty()) return;
  std::error_code ec;
  const fs::file_status st = fs::symlink_status(path, ec);
  if (!fs::exists(st)) return;
  if (!writtenBy(path, generator, firstLinePrefix))
    throw capture::CaptureError(path, "exists and was not written by " + generator + " (" + flag +
                                          "); refusing to overwrite it (remove it or name another file)");
}

void createParentDirectory(const std::string& path) {
  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty()) fs::create_directories(parent);
}

OutputClaim& OutputClaim::operator=(OutputClaim&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = o.fd_;
    o.fd_ = -1;
  }
  return *this;
}

OutputClaim::~OutputClaim() {
  if (fd_ >= 0) ::close(fd_);  // the lock goes with the descriptor; the file stays, the folder's mark
}

namespace {
/// Opens and locks `dir`/.mrgi-claim without waiting, and returns the descriptor and what the claim said;
/// throws naming `dir` when another process holds it.
std::pair<int, std::string> lockClaim(const fs::path& dir) {
  const fs::path path = dir / kOutputClaimFile;
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
  if (fd < 0) throw capture::CaptureError(dir.string(), "cannot claim the output folder (" + path.string() + ")");
  char buf[512];
  const ssize_t n = ::pread(fd, buf, sizeof buf - 1, 0);
  const std::string said = n > 0 ? std::string(buf, static_cast<size_t>(n)) : std::string();
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    std::string holder;
    try {
      const auto j = nlohmann::json::parse(said);
      if (j.contains("pid") && j["pid"].is_number_integer())
        holder = " (process " + std::to_string(j["pid"].get<long long>()) + ")";
    } catch (const std::exception&) {  // half written: no process to name
    }
    ::close(fd);
    throw capture::CaptureError(dir.string(), "is being written by another run of mrgi" + holder +
                                                  "; wait for it to end or name another folder");
  }
  return {fd, said};
}

/// Writes which command (and process) holds the claim.
OutputClaim stampClaim(int fd, const fs::path& dir, const std::string& generator) {
  OutputClaim claim(fd);
  const std::string text = nlohmann::json{{"generated_by", generator}, {"pid", ::getpid()}}.dump() + "\n";
  if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, text.data(), text.size(), 0) != static_cast<ssize_t>(text.size()))
    throw capture::CaptureError(dir.string(),
                                "cannot claim the output folder (" + (dir / kOutputClaimFile).string() + ")");
  return claim;
}
}  // namespace

OutputClaim prepareOutputDirectory(const std::string& out, const std::string& marker, const std::string& generator) {
  std::error_code ec;
  if (fs::exists(out, ec)) {
    if (!fs::is_directory(out, ec)) throw capture::CaptureError(out, "exists and is not a directory");
    const fs::path claimPath = fs::path(out) / kOutputClaimFile;
    std::optional<std::pair<int, std::string>> claim;
    // A folder some run of mrgi claimed: a live one holds the lock (refused here); a finished or killed one left
    // the claim saying which command made the folder.
    if (fs::is_regular_file(fs::symlink_status(claimPath, ec))) claim = lockClaim(out);
    OutputClaim held(claim ? claim->first : -1);  // released on any error below
    bool empty = true;
    for (auto it = fs::directory_iterator(out, ec); !ec && it != fs::directory_iterator(); it.increment(ec))
      if (it->path().filename() != kOutputClaimFile) empty = false;
    if (!empty) {
      // Our own earlier output is recognised by what its marker (or, for a run killed before it wrote one, its
      // claim) says, not by its name alone.
      bool ours = claim && jsonGeneratedBy(claim->second, claimPath.string(), generator);
      const fs::path m = fs::path(out) / marker;
      if (!ours && fs::is_regular_file(m, ec) && fs::file_size(m, ec) < (1u << 26)) {
        try {
          ours = jsonGeneratedBy(capture::readFileBounded(m.string(), 1u << 26, "marker file"), m.string(), generator);
        } catch (const capture::InputError&) {  // unreadable: not ours
        }
      }
      if (!ours)
        throw capture::CaptureError(
            out, "is not empty and holds no earlier output of " + generator + "; refusing to overwrite");
      // The earlier run's own files go (a shorter run would otherwise leave its frames beside a summary that
      // does not list them); anything else in the folder stays.
      std::vector<fs::path> own;
      for (auto it = fs::recursive_directory_iterator(out, ec); !ec && it != fs::recursive_directory_iterator();
           it.increment(ec))
        if (it->is_regular_file(ec) && it->path() != m && it->path() != claimPath &&
            writtenBy(it->path().string(), generator, ""))
          own.push_back(it->path());
      for (const fs::path& f : own) fs::remove(f, ec);  // the marker stays until the new run replaces it
    }
    if (claim) return stampClaim(held.release(), out, generator);
  }
  fs::create_directories(out, ec);
  if (ec) throw capture::CaptureError(out, "cannot create output directory: " + ec.message());
  return stampClaim(lockClaim(out).first, out, generator);
}

void checkInsideOutput(const std::string& name, const std::string& flag) {
  const fs::path p = fs::path(name).lexically_normal();
  if (p.is_absolute() || p.empty() || *p.begin() == "..")
    throw std::invalid_argument(flag + " " + name +
                                ": must be a file name inside --out (nothing is written outside it)");
}

ProgressBar::ProgressBar(std::string label)
    : label_(std::move(label)), tty_(isatty(fileno(stderr))), start_(std::chrono::steady_clock::now()) {}

ProgressBar::~ProgressBar() {
  if (tty_ && shown_ >= 0) std::fprintf(stderr, "\n");
}

std::string progressText(const std::string& label, double fraction, double elapsedS, double leftS, bool tty) {
  fraction = std::isfinite(fraction) ? std::clamp(fraction, 0.0, 1.0) : 0.0;
  const int percent = static_cast<int>(fraction * 100.0);
  char time[64] = "";
  if (fraction < 1.0 && std::isfinite(leftS) && leftS >= 0)
    std::snprintf(time, sizeof time, "%.0f s, about %.0f s left", elapsedS, leftS);
  else
    std::snprintf(time, sizeof time, "%.0f s", elapsedS);
  char out[256];
  if (tty) {
    char bar[41];
    for (int i = 0; i < 40; ++i) bar[i] = i < percent * 40 / 100 ? '#' : '.';
    bar[40] = 0;
    std::snprintf(out, sizeof out, "%s [%s] %3d%%  %s", label.c_str(), bar, percent, time);
  } else {
    std::snprintf(out, sizeof out, "%s: %d %% (%s)", label.c_str(), percent, time);
  }
  return out;
}

void ProgressBar::operator()(double fraction) {
  const int percent = static_cast<int>((std::isfinite(fraction) ? std::clamp(fraction, 0.0, 1.0) : 0.0) * 100.0);
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  // What is left, at the rate since the first report (work before it, a first pass, is not this rate).
  if (!first_) first_ = std::pair{elapsed, std::isfinite(fraction) ? fraction : 0.0};
  const double done = fraction - first_->second, spent = elapsed - first_->first;
  const double left = done > 0 && spent > 0 ? spent * (1.0 - fraction) / done : -1.0;
  if (tty_) {
    if (percent == shown_) return;
    shown_ = percent;
    std::fprintf(stderr, "\r%s\033[K", progressText(label_, fraction, elapsed, left, true).c_str());
  } else {
    // A line per 10 % crossed, once the command has run long enough to need one.
    if (percent / 10 <= shown_ / 10 || percent < 10 || elapsed < 2.0) return;
    shown_ = percent;
    std::fprintf(stderr, "%s\n", progressText(label_, fraction, elapsed, left, false).c_str());
  }
  std::fflush(stderr);
}

namespace {
std::atomic<bool> gInterrupted{false};
struct sigaction gOldInt, gOldTerm;

void onInterrupt(int) {
  if (gInterrupted.exchange(true)) std::_Exit(130);  // the second Ctrl-C
}
}  // namespace

InterruptGuard::InterruptGuard() {
  gInterrupted = false;
  struct sigaction sa {};
  sa.sa_handler = onInterrupt;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, &gOldInt);
  sigaction(SIGTERM, &sa, &gOldTerm);
}

InterruptGuard::~InterruptGuard() {
  sigaction(SIGINT, &gOldInt, nullptr);
  sigaction(SIGTERM, &gOldTerm, nullptr);
}

bool InterruptGuard::interrupted() { return gInterrupted.load(); }

Mp4Writer::Mp4Writer(std::string path, int width, int height, double fps)
    : path_(std::move(path)), partial_(path_ + ".partial.mp4") {
  if (!(fps > 0 && fps <= 1000) || width <= 0 || height <= 0)
    throw capture::CaptureError(path_, "cannot write a video of " + std::to_string(width) + "x" +
                                           std::to_string(height) + " at " + capture::formatNumber(fps) +
                                           " frames per second");
  writer_ =
      cv::makePtr<cv::VideoWriter>(partial_, cv::VideoWriter::fourcc('m', 'p', '4', 'v'), fps, cv::Size(width, height));
  if (!writer_->isOpened())
    throw capture::CaptureError(
        path_,
        "cannot open an MP4 writer (no FFmpeg MPEG-4 encoder in OpenCV's video output, or the folder is not writable)");
}

Mp4Writer::~Mp4Writer() {
  if (writer_) {
    writer_->release();
    std::error_code ec;
    fs::remove(partial_, ec);
  }
}

void Mp4Writer::write(const cv::Mat& rgb) {
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  writer_->write(bgr);
  ++frames_;
}

int Mp4Writer::close() {
  writer_->release();
  writer_.reset();
  std::error_code ec;
  fs::rename(partial_, path_, ec);
  if (ec) throw capture::CaptureError(path_, "cannot move the finished video into place: " + ec.message());
  return frames_;
}

std::function<void(const std::string& what, double fraction)> precomputeProgress() {
  auto bars = std::make_shared<std::map<std::string, std::unique_ptr<ProgressBar>>>();
  return [bars](const std::string& what, double fraction) {
    auto& bar = (*bars)[what];
    if (!bar) bar = std::make_unique<ProgressBar>(what);
    (*bar)(fraction);
    if (fraction >= 1.0) bar.reset();  // done: the next precompute of this kind draws a new bar
  };
}

}  // namespace mrgi::runtime
