#include "capture/session.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "capture/checks.h"
#include "capture/error.h"
#include "capture/image_io.h"
#include "capture/json_io.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace mrgi::capture {
namespace {

constexpr const char* kManifest = "manifest.json";
constexpr const char* kIndex = "frames.jsonl";

// JSON field access that names the key in every error: capture/json_io.h.
const json& need(const json& j, const std::string& key, const std::string& file, const std::string& path) {
  return jsonKey(j, key, file, path);
}
double number(const json& j, const std::string& key, const std::string& file, const std::string& path) {
  return jsonNumber(j, key, file, path);
}
int integer(const json& j, const std::string& key, const std::string& file, const std::string& path) {
  return jsonInt(j, key, file, path);
}

std::vector<double> numbers(const json& v, size_t n, const std::string& file, const std::string& key) {
  if (!v.is_array() || v.size() != n)
    throw CaptureError(file, "key '" + key + "' must be an array of " + std::to_string(n) + " numbers");
  std::vector<double> out;
  for (const json& x : v) {
    if (!x.is_number() || !std::isfinite(x.get<double>()))
      throw CaptureError(file, "key '" + key + "' must hold finite numbers");
    out.push_back(x.get<double>());
  }
  return out;
}

json intrinsicsToJson(const Intrinsics& k) {
  return {{"width", k.width}, {"height", k.height}, {"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy}};
}

Intrinsics intrinsicsFromJson(const json& j, const std::string& file, const std::string& path) {
  Intrinsics k;
  k.width = integer(j, "width", file, path);
  k.height = integer(j, "height", file, path);
  k.fx = number(j, "fx", file, path);
  k.fy = number(j, "fy", file, path);
  k.cx = number(j, "cx", file, path);
  k.cy = number(j, "cy", file, path);
  // `path` is the key's prefix ("colour."): the object is named without its dot.
  if (!k.valid())
    throw CaptureError(file, "key '" + path.substr(0, path.size() - (!path.empty() && path.back() == '.')) +
                                 "' holds a non-positive size or focal length");
  // Larger than any sensor: its frames could not be allocated, let alone lit.
  if (k.width > kMaxImageSide || k.height > kMaxImageSide)
    throw CaptureError(file, "key '" + path + "' holds an image of " + std::to_string(k.width) + "x" +
                                 std::to_string(k.height) + " (at most " + std::to_string(kMaxImageSide) + " a side)");
  return k;
}

void syncDirectory(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

std::string frameName(const char* kind, int64_t index, const char* ext) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%s/%06lld.%s", kind, static_cast<long long>(index), ext);
  return buf;
}

}  // namespace

json poseToJson(const Pose& p) {
  json a = json::array();
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) a.push_back(p(r, c));
  return a;
}

Pose poseFromJson(const json& j, const std::string& file, const std::string& key) {
  const auto v = numbers(j, 16, file, key);
  Pose p;
  for (int i = 0; i < 16; ++i) p(i / 4, i % 4) = v[i];
  checkRigid(p, file, "key '" + key + "'");
  return p;
}

// --- manifest ---------------------------------------------------------------------------------------------

json SessionManifest::toJson() const {
  json j;
  j["format"] = "mrgi-session";
  j["version"] = version;
  j["colour"] = intrinsicsToJson(colour);
  j["depth"] = intrinsicsToJson(depth);
  j["depth"]["units_m"] = depthUnitsMetres;
  j["depth"]["registered"] = depthRegistered;
  j["depth"]["T_colour_depth"] = poseToJson(T_colour_depth);
  if (fisheye) {
    json f = {{"width", fisheye->width}, {"height", fisheye->height}, {"model", fisheye->model}};
    f["K"] = json::array();
    for (int i = 0; i < 9; ++i) f["K"].push_back(fisheye->K(i / 3, i % 3));
    f["D"] = {fisheye->D[0], fisheye->D[1], fisheye->D[2], fisheye->D[3]};
    if (fisheye->T_world_fisheye) f["T_world_fisheye"] = poseToJson(*fisheye->T_world_fisheye);
    j["fisheye"] = f;
  }
  if (marker) j["marker"] = {{"family", marker->family}, {"size_m", marker->sizeMetres}, {"id", marker->id}};
  if (!groundTruth.is_null()) j["ground_truth"] = groundTruth;
  return j;
}

namespace {
/// A key's value when present and of the right type, else the fallback; the wrong type names the key.
template <typename T>
T optionalKey(const json& j, const char* key, T fallback, const std::string& file, const std::string& prefix) {
  if (!j.contains(key)) return fallback;
  try {
    return j[key].get<T>();
  } catch (const json::exception&) {
    throw CaptureError(file, "key '" + prefix + key + "' has the wrong type");
  }
}
}  // namespace

SessionManifest SessionManifest::fromJson(const json& j, const std::string& file) {
  try {
    return fromJsonChecked(j, file);
  } catch (const json::exception& e) {
    // Every key is checked on the way; a type mismatch that slipped past still names the file.
    std::string what = e.what();
    if (const size_t at = what.find("] "); at != std::string::npos) what = what.substr(at + 2);
    throw CaptureError(file, "malformed manifest: " + what);
  }
}

SessionManifest SessionManifest::fromJsonChecked(const json& j, const std::string& file) {
  if (!j.is_object()) throw CaptureError(file, "manifest is not a JSON object");
  if (optionalKey<std::string>(j, "format", "", file, "") != "mrgi-session")
    throw CaptureError(file, "key 'format' must be \"mrgi-session\"");
  SessionManifest m;
  m.version = integer(j, "version", file, "");
  if (m.version != kSessionVersion)
    throw CaptureError(file, "unknown session version " + std::to_string(m.version) + " (this build reads version " +
                                 std::to_string(kSessionVersion) + ")");
  m.colour = intrinsicsFromJson(need(j, "colour", file, ""), file, "colour.");
  const json& d = need(j, "depth", file, "");
  m.depth = intrinsicsFromJson(d, file, "depth.");
  m.depthUnitsMetres = number(d, "units_m", file, "depth.");
  checkNumber(m.depthUnitsMetres, kMinDepthUnitsM, kMaxDepthUnitsM, file, "key 'depth.units_m'");
  m.depthRegistered = optionalKey<bool>(d, "registered", true, file, "depth.");
  if (d.contains("T_colour_depth")) m.T_colour_depth = poseFromJson(d["T_colour_depth"], file, "depth.T_colour_depth");
  if (m.depthRegistered && (m.depth.width != m.colour.width || m.depth.height != m.colour.height))
    throw CaptureError(file, "registered depth must match the colour resolution (depth " +
                                 std::to_string(m.depth.width) + "x" + std::to_string(m.depth.height) + ", colour " +
                                 std::to_string(m.colour.width) + "x" + std::to_string(m.colour.height) + ")");
  if (j.contains("fisheye")) {
    const json& f = j["fisheye"];
    FisheyeCalibration c;
    c.width = integer(f, "width", file, "fisheye.");
    c.height = integer(f, "height", file, "fisheye.");
    c.model = optionalKey<std::string>(f, "model", "equidistant", file, "fisheye.");
    if (c.model != "equidistant") throw CaptureError(file, "key 'fisheye.model' must be \"equidistant\"");
    const auto K = numbers(need(f, "K", file, "fisheye."), 9, file, "fisheye.K");
    for (int i = 0; i < 9; ++i) c.K(i / 3, i % 3) = K[i];
    // A camera matrix: positive focal lengths, a principal point inside the image, [0 0 1] below.
    if (!(K[0] > 0 && K[4] > 0) || K[3] != 0 || K[6] != 0 || K[7] != 0 || K[8] != 1 ||
        !(K[2] >= 0 && K[2] <= c.width) || !(K[5] >= 0 && K[5] <= c.height))
      throw CaptureError(file, "key 'fisheye.K' is not a camera matrix (fx, fy > 0, the principal point inside the " +
                                   std::to_string(c.width) + "x" + std::to_string(c.height) +
                                   " image, last row 0 0 1)");
    const auto D = numbers(need(f, "D", file, "fisheye."), 4, file, "fisheye.D");
    c.D = {D[0], D[1], D[2], D[3]};
    if (f.contains("T_world_fisheye"))
      c.T_world_fisheye = poseFromJson(f["T_world_fisheye"], file, "fisheye.T_world_fisheye");
    m.fisheye = c;
  }
  if (j.contains("marker")) {
    const json& mk = j["marker"];
    MarkerSpec s;
    if (!mk.contains("family") || !mk["family"].is_string())
      throw CaptureError(file, "key 'marker.family' must be a string");
    s.family = mk["family"].get<std::string>();
    s.sizeMetres = number(mk, "size_m", file, "marker.");
    s.id = integer(mk, "id", file, "marker.");
    checkNumber(s.sizeMetres, kMinTagSizeM, kMaxTagSizeM, file, "key 'marker.size_m'");
    const std::string tag = s.id >= 0 ? tagProblem(s.family, s.id) : tagProblem(s.family);  // a negative id: any tag
    if (!tag.empty()) throw CaptureError(file, "key 'marker': " + tag);
    m.marker = s;
  }
  if (j.contains("ground_truth")) {
    m.groundTruth = j["ground_truth"];
    m.truth = GroundTruth::fromJson(m.groundTruth, file);
  }
  return m;
}

// --- writer -------------------------------------------------------------------------------------------------

SessionWriter::SessionWriter(std::string directory, SessionManifest manifest)
    : dir_(std::move(directory)), manifest_(std::move(manifest)) {
  std::error_code ec;
  if (fs::exists(dir_, ec) && !(fs::is_directory(dir_, ec) && fs::is_empty(dir_, ec))) {
    // A recording already there (one that was interrupted, even by kill -9, keeps every complete frame) is said
    // as such: it plays as it is; recording again means another folder, or removing this one.
    const fs::path index = fs::path(dir_) / kIndex;
    if (fs::is_regular_file(fs::path(dir_) / kManifest, ec) && fs::is_regular_file(index, ec)) {
      std::ifstream in(index);
      size_t frames = 0;
      for (std::string line; std::getline(in, line);) frames += !line.empty() && line.back() == '}';
      throw CaptureError(dir_, "already holds a recording of " + std::to_string(frames) +
                                   " frames (an interrupted one keeps every complete frame and replays as it is); "
                                   "record into another folder, or remove this one to record it again");
    }
    throw CaptureError(dir_, "already exists and is not an empty directory; refusing to overwrite");
  }
  for (const char* sub : {"", "colour", "depth", "fisheye"}) {
    if (std::string(sub) == "fisheye" && !manifest_.fisheye) continue;
    fs::create_directories(fs::path(dir_) / sub, ec);
    if (ec) throw CaptureError(dir_, "cannot create directory: " + ec.message());
  }
  writeFileAtomically(fs::path(dir_) / kManifest, manifest_.toJson().dump(2) + "\n");
  const fs::path index = fs::path(dir_) / kIndex;
  indexFd_ = ::open(index.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (indexFd_ < 0) throw CaptureError(index.string(), std::string("cannot create: ") + std::strerror(errno));
  syncDirectory(dir_);
}

SessionWriter::~SessionWriter() {
  if (indexFd_ >= 0) ::close(indexFd_);
}

void SessionWriter::append(const Frame& frame) {
  const fs::path dir(dir_);
  if (written_ > 0 && !(frame.timestamp > lastTimestamp_))
    throw CaptureError(dir_, "frame timestamps must increase (" + std::to_string(frame.timestamp) + " after " +
                                 std::to_string(lastTimestamp_) + ")");
  const int64_t i = written_;
  json line = {{"index", i}, {"t", frame.timestamp}};
  if (frame.rgbd) {
    const RgbdFrame& f = *frame.rgbd;
    if (f.colour.type() != CV_8UC3 || f.colour.cols != manifest_.colour.width ||
        f.colour.rows != manifest_.colour.height)
      throw CaptureError(dir_, "colour frame does not match the manifest's size/type");
    if (f.depth.type() != CV_32FC1 || f.depth.cols != manifest_.depth.width || f.depth.rows != manifest_.depth.height)
      throw CaptureError(dir_, "depth frame does not match the manifest's size/type");
    const std::string colourName = frameName("colour", i, jpegQuality_ > 0 ? "jpg" : "png"),
                      depthName = frameName("depth", i, "png");
    writeFileAtomically(dir / colourName, jpegQuality_ > 0 ? encodeJpeg(f.colour, jpegQuality_, colourName)
                                                           : encodePng(f.colour, colourName));
    writeFileAtomically(dir / depthName, encodePng(depthToUnits(f.depth, manifest_.depthUnitsMetres), depthName));
    line["colour"] = colourName;
    line["depth"] = depthName;
    if (!(f.exposure > 0) || !std::isfinite(f.exposure))
      throw CaptureError(dir_, "colour exposure must be positive and finite");
    if (f.exposure != 1.0) line["colour_exposure"] = f.exposure;
  }
  if (frame.fisheye) {
    if (!manifest_.fisheye) throw CaptureError(dir_, "fisheye frame given but the manifest has no fisheye calibration");
    const FisheyeFrame& f = *frame.fisheye;
    const std::string name = frameName("fisheye", i, f.image.depth() == CV_8U ? "png" : "exr");
    std::vector<unsigned char> bytes;
    if (f.image.depth() == CV_8U) {
      bytes = encodePng(f.image, name);
    } else {
      bytes = encodeExr(f.image, true, name);
    }
    writeFileAtomically(dir / name, bytes);
    line["fisheye"] = name;
    line["exposure"] = f.exposure;
  }
  if (frame.groundTruthT_world_camera) line["T_world_camera"] = poseToJson(*frame.groundTruthT_world_camera);
  if (frame.groundTruthLights) line["lights"] = lightsToJson(*frame.groundTruthLights);
  for (const char* sub : {"colour", "depth", "fisheye"})
    if (line.contains(sub)) syncDirectory(dir / sub);
  const std::string text = line.dump() + "\n";
  // One write() of the whole line: a crash leaves a prefix without '\n', which readers ignore.
  size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(indexFd_, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) throw CaptureError((dir / kIndex).string(), std::string("write failed: ") + std::strerror(errno));
    done += static_cast<size_t>(n);
  }
  if (::fsync(indexFd_) != 0)
    throw CaptureError((dir / kIndex).string(), std::string("fsync failed: ") + std::strerror(errno));
  lastTimestamp_ = frame.timestamp;
  ++written_;
}

// --- reader -------------------------------------------------------------------------------------------------

SessionSource::SessionSource(const std::string& directory) : dir_(directory) {
  quietOpenCv();
  const fs::path dir(directory);
  const std::string manifestPath = (dir / kManifest).string();
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw CaptureError(directory, "session directory does not exist");
  if (!fs::exists(manifestPath, ec)) throw CaptureError(manifestPath, "missing: not an mrgi session");
  // A folder, a pipe or a device in its place is said as what it is (readFileBounded).
  json mj;
  mj = parseJson(readFileBounded(manifestPath, kMaxTextFileBytes, "session manifest"), manifestPath);
  manifest_ = SessionManifest::fromJson(mj, manifestPath);

  const std::string indexPath = (dir / kIndex).string();
  if (!fs::is_regular_file(indexPath, ec)) throw CaptureError(indexPath, "missing: the session has no frame index");
  const std::string text = readFileBounded(indexPath, kMaxBinaryFileBytes, "frame index");
  size_t start = 0;
  int lineNo = 0;
  while (start < text.size()) {
    const size_t nl = text.find('\n', start);
    if (nl == std::string::npos) {  // a write cut short: not a complete frame
      trailingBytes_ = static_cast<int64_t>(text.size() - start);
      break;
    }
    ++lineNo;
    const std::string line = text.substr(start, nl - start);
    start = nl + 1;
    const std::string where = indexPath + ":" + std::to_string(lineNo);
    json j;
    try {
      j = parseJson(line, where);
    } catch (const InputError&) {
      throw CaptureError(where, "malformed frame line");
    }
    Entry e;
    e.index = integer(j, "index", where, "");
    e.t = number(j, "t", where, "");
    if (e.index != static_cast<int64_t>(entries_.size()))
      throw CaptureError(where, "frame index " + std::to_string(e.index) + " out of sequence (expected " +
                                    std::to_string(entries_.size()) + ")");
    if (!entries_.empty() && !(e.t > entries_.back().t))
      throw CaptureError(where, "timestamp " + formatNumber(e.t) + " does not increase (previous " +
                                    formatNumber(entries_.back().t) + ")");
    auto relPath = [&](const char* key) -> std::string {
      if (!j.contains(key)) return {};
      if (!j[key].is_string()) throw CaptureError(where, std::string("key '") + key + "' must be a string");
      const std::string p = j[key].get<std::string>();
      if (p.empty() || p[0] == '/' || p.find("..") != std::string::npos)
        throw CaptureError(where, std::string("key '") + key + "' must be a path inside the session");
      return p;
    };
    e.colour = relPath("colour");
    e.depth = relPath("depth");
    e.fisheye = relPath("fisheye");
    if (e.colour.empty() != e.depth.empty())
      throw CaptureError(where, "a frame needs both 'colour' and 'depth' or neither");
    if (e.colour.empty() && e.fisheye.empty()) throw CaptureError(where, "frame has no images");
    if (!e.fisheye.empty() && !manifest_.fisheye)
      throw CaptureError(where, "frame has a fisheye image but the manifest has no fisheye calibration");
    if (j.contains("exposure")) {
      e.exposure = number(j, "exposure", where, "");
      checkNumber(e.exposure, kMinExposure, kMaxExposure, where, "exposure");
    }
    if (j.contains("colour_exposure")) {
      e.colourExposure = number(j, "colour_exposure", where, "");
      checkNumber(e.colourExposure, kMinExposure, kMaxExposure, where, "colour_exposure");
    }
    if (j.contains("T_world_camera")) e.pose = poseFromJson(j["T_world_camera"], where, "T_world_camera");
    if (j.contains("lights")) e.lights = lightsFromJson(j["lights"], where, "lights");
    entries_.push_back(std::move(e));
  }
  if (entries_.empty()) throw CaptureError(indexPath, "the session holds no complete frame");

  info_.uri = directory;
  info_.kind = "session";
  info_.frameCount = frameCount();
  info_.colourIntrinsics = manifest_.colour;
  info_.depthIntrinsics = manifest_.depth;
  info_.hasRgbd = !entries_.front().colour.empty();
  info_.hasFisheye = manifest_.fisheye.has_value();
  info_.hasGroundTruth = !manifest_.groundTruth.is_null() || entries_.front().pose.has_value();
  std::vector<double> ts;
  for (const Entry& e : entries_) ts.push_back(e.t);
  info_.fps = medianRate(ts);
}

Frame SessionSource::read(int64_t i) const {
  const Entry& e = entries_.at(static_cast<size_t>(i));
  const fs::path dir(dir_);
  Frame f;
  f.index = e.index;
  f.timestamp = e.t;
  f.groundTruthT_world_camera = e.pose;
  f.groundTruthLights = e.lights;
  if (!e.colour.empty()) {
    RgbdFrame r;
    const std::string colourPath = (dir / e.colour).string(), depthPath = (dir / e.depth).string();
    r.colour = readColour(colourPath);
    r.depth = readDepth(depthPath, manifest_.depthUnitsMetres);
    if (r.colour.cols != manifest_.colour.width || r.colour.rows != manifest_.colour.height)
      throw CaptureError(colourPath, "image is " + std::to_string(r.colour.cols) + "x" + std::to_string(r.colour.rows) +
                                         ", the manifest says " + std::to_string(manifest_.colour.width) + "x" +
                                         std::to_string(manifest_.colour.height));
    if (r.depth.cols != manifest_.depth.width || r.depth.rows != manifest_.depth.height)
      throw CaptureError(depthPath, "image is " + std::to_string(r.depth.cols) + "x" + std::to_string(r.depth.rows) +
                                        ", the manifest says " + std::to_string(manifest_.depth.width) + "x" +
                                        std::to_string(manifest_.depth.height));
    r.colourIntrinsics = manifest_.colour;
    r.depthIntrinsics = manifest_.depth;
    r.depthRegistered = manifest_.depthRegistered;
    r.T_colour_depth = manifest_.T_colour_depth;
    r.exposure = e.colourExposure;
    f.rgbd = std::move(r);
  }
  if (!e.fisheye.empty()) {
    FisheyeFrame ff;
    const std::string path = (dir / e.fisheye).string();
    ff.image = readAny(path);
    if (ff.image.depth() == CV_32F) {
      // An HDR environment image: radiance, finite and non-negative, and not all dark (the median cut would
      // place its lights nowhere, and the object would render black).
      double lo = 0, hi = 0;
      const cv::Mat flat = ff.image.reshape(1);
      if (cv::checkRange(flat, true, nullptr, -1e30, 1e30))
        cv::minMaxLoc(flat, &lo, &hi);
      else
        lo = hi = std::numeric_limits<double>::quiet_NaN();
      if (!std::isfinite(lo) || !std::isfinite(hi)) throw CaptureError(path, "fisheye image holds non-finite values");
      if (lo < 0) throw CaptureError(path, "fisheye image holds negative radiance (" + std::to_string(lo) + ")");
      if (!(hi > 0)) throw CaptureError(path, "fisheye image is black everywhere: no light to estimate");
    }
    ff.exposure = e.exposure;
    ff.calibration = *manifest_.fisheye;
    if (ff.image.cols != ff.calibration.width || ff.image.rows != ff.calibration.height)
      throw CaptureError(path, "fisheye image size does not match the calibration in the manifest");
    f.fisheye = std::move(ff);
  }
  return f;
}

std::optional<Frame> SessionSource::next() {
  if (cursor_ >= frameCount()) return std::nullopt;
  return read(cursor_++);
}

}  // namespace mrgi::capture
