// The command contract, checked from outside: run the mrgi binary and inspect exit codes, stdout, stderr
// and the files it writes.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <regex>
#include <set>
#include <sstream>
#include <tuple>

#include "capture/v4l2_source.h"
#include "lighting/scene_file.h"
#include "made_sessions.h"
#include "reconstruction/marker.h"
#include "reconstruction/room_model.h"
#include "runtime/threads.h"

namespace fs = std::filesystem;

namespace {

struct Result {
  int exitCode = -1;
  bool signalled = false;
  std::string out, err;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// `environment`: what env(1) changes before mrgi starts ("-u NAME", "NAME=value"); empty: the test's own.
Result runMrgiWith(const std::string& environment, const std::string& args) {
  static int n = 0;
  const fs::path tmp =
      fs::temp_directory_path() / ("mrgi_cli_" + std::to_string(::getpid()) + "_" + std::to_string(n++));
  const std::string cmd = (environment.empty() ? std::string() : "env " + environment + " ") + MRGI_BINARY + " " +
                          args + " >" + tmp.string() + ".out 2>" + tmp.string() + ".err";
  const int status = std::system(cmd.c_str());
  Result r;
  r.signalled = WIFSIGNALED(status);
  r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = slurp(tmp.string() + ".out");
  r.err = slurp(tmp.string() + ".err");
  fs::remove(tmp.string() + ".out");
  fs::remove(tmp.string() + ".err");
  return r;
}

Result runMrgi(const std::string& args) { return runMrgiWith("", args); }

int lines(const std::string& s) { return static_cast<int>(std::count(s.begin(), s.end(), '\n')); }

/// The lines of a command's stderr other than its progress ("room: 40 % (2 s, about 3 s left)"), which a run
/// prints on a pipe once it has taken 2 s: a slower machine or build (sanitizers) adds them.
int messageLines(const std::string& s) {
  int n = 0;
  size_t start = 0;
  while (start < s.size()) {
    const size_t end = s.find('\n', start);
    const std::string line = s.substr(start, end == std::string::npos ? std::string::npos : end - start);
    const size_t colon = line.find(": "), percent = line.find(" % (");
    const bool progress = colon != std::string::npos && percent != std::string::npos && percent > colon &&
                          line.find_first_not_of("0123456789", colon + 2) == percent;
    if (end != std::string::npos && !progress) ++n;
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return n;
}

/// One small synthetic session shared by the tests of this file (and their processes: tests read it, never write it).
const fs::path& session() {
  static const fs::path dir = [] {
    const fs::path d = mrgi::test::madeSession(
        "cli_session", "--frames 3 --width 160 --height 120 --fisheye-every 2 --render raycast");
    EXPECT_FALSE(d.empty()) << "mrgi synth failed";
    return d;
  }();
  return dir;
}

void expectOneLineError(const Result& r, const std::string& needle) {
  EXPECT_FALSE(r.signalled);
  EXPECT_GE(r.exitCode, 1);
  EXPECT_LE(r.exitCode, 127);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
}

}  // namespace

TEST(Cli, HelpListsSubcommands) {
  const Result r = runMrgi("--help");
  EXPECT_EQ(r.exitCode, 0);
  for (const char* sub : {"info", "replay", "synth"}) EXPECT_NE(r.out.find(sub), std::string::npos) << sub;
}

TEST(Cli, InfoPrintsOneJsonObject) {
  const Result r = runMrgi("info " + session().string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  ASSERT_EQ(lines(r.out), 1);
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["frame_count"], 3);
  EXPECT_EQ(j["colour_resolution"], nlohmann::json({160, 120}));
  EXPECT_EQ(j["depth_resolution"], nlohmann::json({160, 120}));
  EXPECT_DOUBLE_EQ(j["colour_intrinsics"]["fx"].get<double>(), 525.0 / 4);
  EXPECT_EQ(j["has_fisheye"], true);
  EXPECT_EQ(j["has_ground_truth"], true);
}

TEST(Cli, SynthSessionCarriesGroundTruthAndFisheye) {
  const auto m = nlohmann::json::parse(slurp(session() / "manifest.json"));
  EXPECT_EQ(m["marker"]["family"], "tag36h11");
  EXPECT_EQ(m["ground_truth"]["lights"].size(), 1u);
  EXPECT_EQ(m["fisheye"]["width"], 800);
  const std::string index = slurp(session() / "frames.jsonl");
  EXPECT_EQ(lines(index), 3);
  EXPECT_NE(index.find("T_world_camera"), std::string::npos);
  EXPECT_TRUE(fs::exists(session() / "fisheye/000000.exr"));
  EXPECT_TRUE(fs::exists(session() / "fisheye/000002.exr"));
  const cv::Mat depth = cv::imread((session() / "depth/000000.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(depth.type(), CV_16UC1);
  const double validFraction = cv::countNonZero(depth) / static_cast<double>(depth.total());
  EXPECT_GT(validFraction, 0.8);  // a tabletop view is mostly in range...
  EXPECT_LT(validFraction, 1.0);  // ...but holes and edge dropouts exist
}

// mrgi starts itself again with the settings its runtime libraries read on load (runtime/threads.h), unless the
// environment sets them, and a replay's summary says which it ran with.
TEST(Cli, ReplayRunsWithTheProcessSettingsAndRecordsThem) {
  const fs::path out = fs::temp_directory_path() / ("mrgi_cli_process_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const std::string args = "replay " + session().string() + " --out " + out.string() + " --frames 1";
  Result r = runMrgiWith("-u GLIBC_TUNABLES -u OMP_WAIT_POLICY -u OMP_NUM_THREADS", args);
  ASSERT_EQ(r.exitCode, 0) << r.err;
  auto s = nlohmann::json::parse(slurp(out / "summary.json"));
  EXPECT_EQ(s["process"]["GLIBC_TUNABLES"], mrgi::runtime::kGlibcTunables);
  EXPECT_EQ(s["process"]["OMP_WAIT_POLICY"], "PASSIVE");
  EXPECT_TRUE(s["process"]["OMP_NUM_THREADS"].is_null());
  // The user's own settings stand.
  r = runMrgiWith("-u OMP_WAIT_POLICY GLIBC_TUNABLES=glibc.malloc.arena_max=2 OMP_NUM_THREADS=1", args);
  ASSERT_EQ(r.exitCode, 0) << r.err;
  s = nlohmann::json::parse(slurp(out / "summary.json"));
  EXPECT_EQ(s["process"]["GLIBC_TUNABLES"], "glibc.malloc.arena_max=2");
  EXPECT_TRUE(s["process"]["OMP_WAIT_POLICY"].is_null());
  EXPECT_EQ(s["process"]["OMP_NUM_THREADS"], "1");
  fs::remove_all(out);
}

TEST(Cli, ReplayWritesFramesAndSummary) {
  const fs::path out = fs::temp_directory_path() / ("mrgi_cli_replay_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const Result r = runMrgi("replay " + session().string() + " --out " + out.string() + " --frames 2");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_TRUE(fs::exists(out / "frame_0000.png"));
  EXPECT_TRUE(fs::exists(out / "frame_0001.png"));
  EXPECT_FALSE(fs::exists(out / "frame_0002.png"));
  const auto s = nlohmann::json::parse(slurp(out / "summary.json"));
  EXPECT_EQ(s["frames"], 2);
  EXPECT_TRUE(s["stages_ms"].contains("composite"));
  EXPECT_EQ(s["gl"]["backend"], "osmesa");
  // With no virtual object the composite equals the camera image.
  const cv::Mat composite = cv::imread((out / "frame_0001.png").string());
  const cv::Mat colour = cv::imread((session() / "colour/000001.png").string());
  EXPECT_LE(cv::norm(composite, colour, cv::NORM_INF), 1.0);
  // Running again into the same folder (earlier output) works, and leaves none of the earlier run's frames
  // beside the new summary; a file the user put there stays. A folder of user files is refused.
  std::ofstream(out / "notes.txt") << "mine";
  EXPECT_EQ(runMrgi("replay " + session().string() + " --out " + out.string() + " --frames 1").exitCode, 0);
  EXPECT_TRUE(fs::exists(out / "frame_0000.png"));
  EXPECT_FALSE(fs::exists(out / "frame_0001.png")) << "a stale frame of the earlier run";
  EXPECT_EQ(nlohmann::json::parse(slurp(out / "summary.json"))["frames"], 1);
  EXPECT_EQ(slurp(out / "notes.txt"), "mine");
  const fs::path mine = out.string() + "_user";
  fs::create_directories(mine);
  std::ofstream(mine / "thesis.tex") << "precious";
  expectOneLineError(runMrgi("replay " + session().string() + " --out " + mine.string()), "refusing to overwrite");
  EXPECT_EQ(slurp(mine / "thesis.tex"), "precious");
  // A file of the user's that merely bears our marker's name does not make the folder ours.
  std::ofstream(mine / "summary.json") << "{\"my\": \"notes\"}";
  std::ofstream(mine / "replay.mp4") << "my video";
  expectOneLineError(runMrgi("replay " + session().string() + " --out " + mine.string()), "refusing to overwrite");
  EXPECT_EQ(slurp(mine / "summary.json"), "{\"my\": \"notes\"}");
  EXPECT_EQ(slurp(mine / "replay.mp4"), "my video");
  EXPECT_FALSE(fs::exists(mine / "frame_0000.png"));
  // The video goes inside --out only: an absolute path or one climbing out is refused, nothing written.
  std::ofstream(out.string() + "_video.mp4") << "my other video";
  for (const std::string& mp4 : {out.string() + "_video.mp4", "../" + out.filename().string() + "_video.mp4"}) {
    expectOneLineError(runMrgi("replay " + session().string() + " --frames 1 --out " + out.string() + " --mp4 " + mp4),
                       "--mp4");
    EXPECT_EQ(slurp(out.string() + "_video.mp4"), "my other video");
  }
  fs::remove(out.string() + "_video.mp4");
  fs::remove_all(out);
  fs::remove_all(mine);
}

TEST(Cli, LightsFromARadianceProbe) {
  // The Debevec probes are shared as equirectangular Radiance .hdr files: without --calib, lights reads one
  // as a lat-long map (z up at the top row). Its total power is the probe's radiance summed over the sphere,
  // each pixel weighted by its solid angle, computed here from OpenCV's own decoding of the file.
  const std::string probe = std::string(MRGI_SHARED_DATA) + "/hdr-probes/grace.hdr";
  const Result r = runMrgi("lights " + probe + " --json --count 4");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.err, "");
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["count"], 4);
  cv::Mat img = cv::imread(probe, cv::IMREAD_UNCHANGED);  // BGR float
  ASSERT_EQ(img.type(), CV_32FC3);
  cv::Vec3d total(0, 0, 0);
  const double dPhi = 2 * CV_PI / img.cols;
  for (int v = 0; v < img.rows; ++v) {
    const double omega = dPhi * (std::cos(CV_PI * v / img.rows) - std::cos(CV_PI * (v + 1) / img.rows));
    for (int u = 0; u < img.cols; ++u) {
      const cv::Vec3f bgr = img.at<cv::Vec3f>(v, u);
      total += omega * cv::Vec3d(bgr[2], bgr[1], bgr[0]);
    }
  }
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(j["total_power"][c].get<double>(), total[c], 1e-4 * total[c]) << c;
  // The lights and the SH remainder hold it all, and the brightest light comes from the sky above.
  double lit = 0, best = 0, bestZ = 0;
  for (const auto& l : j["estimated"]) {
    const double p = l["power"][1].get<double>();
    lit += p;
    if (p > best) best = p, bestZ = l["direction"][2].get<double>();
  }
  EXPECT_GT(bestZ, 0.5);
  EXPECT_LT(lit, total[1] * 1.0001);
  // lights[] is a scene's lights, as written: `mrgi lights --json` wrote keys a scene file refused
  // ("lights[0].power: unknown key"). Each is the estimate's cap as a directional light: travelling away from
  // where the light is, with the cap's normal irradiance.
  const std::string sceneText = nlohmann::json{{"lights", j["lights"]}}.dump();
  const mrgi::lighting::SceneDescription scene = mrgi::lighting::parseScene(sceneText, "probe-lights.json");
  ASSERT_EQ(scene.lights.size(), 4u);
  for (size_t i = 0; i < 4; ++i) {
    const auto& e = j["estimated"][i];
    const double r = scene.lights[i].extent;
    EXPECT_NEAR(r * 180 / CV_PI, j["lights"][i]["angular_radius_deg"].get<double>(), 1e-9);
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(scene.lights[i].direction[k], -e["direction"][k].get<double>(), 1e-9);
      EXPECT_NEAR(scene.lights[i].irradiance[k], e["power"][k].get<double>() * 0.5 * (1 + std::cos(r)),
                  1e-9 * e["power"][k].get<double>());
    }
  }
  // Damaged, it is one line naming the file.
  const fs::path cut = fs::temp_directory_path() / ("mrgi_cli_probe_" + std::to_string(::getpid()) + ".hdr");
  const std::string bytes = slurp(probe);
  std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 3);
  expectOneLineError(runMrgi("lights " + cut.string()), cut.string() + ": cannot decode Radiance HDR (truncated");
  fs::remove(cut);
}

TEST(Cli, BadInputsAreOneLineErrors) {
  expectOneLineError(runMrgi("info /nonexistent/session"), "/nonexistent/session: does not exist");
  expectOneLineError(runMrgi("replay /nonexistent/session --out /tmp/x"), "/nonexistent/session");
  expectOneLineError(runMrgi("replay " + session().string() + " --out /tmp/x --gl vulkan"), "--gl");
  expectOneLineError(runMrgi("nosuchcommand"), "nosuchcommand");
  expectOneLineError(runMrgi("info openni2://"), "openni2://");
  // A corrupt frame in a copy of the session: the error names the file.
  const fs::path copy = fs::temp_directory_path() / ("mrgi_cli_corrupt_" + std::to_string(::getpid()));
  fs::remove_all(copy);
  fs::copy(session(), copy, fs::copy_options::recursive);
  std::ofstream(copy / "colour/000001.png", std::ios::trunc) << "garbage";
  const fs::path out = copy.string() + "_out";
  fs::remove_all(out);
  expectOneLineError(runMrgi("replay " + copy.string() + " --out " + out.string()), "colour/000001.png: cannot decode");
  fs::remove_all(copy);
  fs::remove_all(out);
}

namespace {

std::vector<nlohmann::json> jsonLines(const std::string& text) {
  std::vector<nlohmann::json> out;
  std::stringstream ss(text);
  std::string line;
  while (std::getline(ss, line))
    if (!line.empty()) out.push_back(nlohmann::json::parse(line));
  return out;
}

cv::Matx44d matFromRows(const nlohmann::json& rows) {
  cv::Matx44d T;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) T(r, c) = rows[r][c];
  return T;
}

cv::Matx44d matFromFlat(const nlohmann::json& v) {
  cv::Matx44d T;
  for (int i = 0; i < 16; ++i) T(i / 4, i % 4) = v[i];
  return T;
}

}  // namespace

TEST(Cli, TrackFollowsTheMarkerOfTheBundledSession) {
  const fs::path rec = fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-synth";
  for (const bool smooth : {false, true}) {
    const Result r = runMrgi("track " + rec.string() + " --json" + (smooth ? "" : " --no-smooth"));
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const auto out = jsonLines(r.out);
    ASSERT_EQ(out.size(), 20u);
    const auto manifest = nlohmann::json::parse(slurp(rec / "manifest.json"));
    const cv::Matx44d T_world_marker = matFromFlat(manifest["ground_truth"]["T_world_marker"]);
    const auto frames = jsonLines(slurp(rec / "frames.jsonl"));
    double worstT = 0, worstR = 0;
    for (size_t i = 0; i < out.size(); ++i) {
      EXPECT_EQ(out[i]["frame"], static_cast<int>(i));
      EXPECT_EQ(out[i]["status"], "tracked");
      EXPECT_EQ(out[i]["id"], manifest["marker"]["id"]);
      const cv::Matx44d got = matFromRows(out[i]["T_camera_tag"]);
      const cv::Matx44d truth = matFromFlat(frames[i]["T_world_camera"]).inv() * T_world_marker;
      worstT = std::max(worstT, mrgi::reconstruction::translationError(got, truth));
      worstR = std::max(worstR, mrgi::reconstruction::rotationErrorDeg(got, truth));
    }
    // Synthetic 640x480 frames, 16 cm tag at ~1 m, camera orbiting ~2 deg per frame. Measured worst
    // 5.6 mm / 0.33 deg raw; smoothing trades up to 1.7 deg of lag at this speed for 3x less jitter.
    EXPECT_LT(worstT, 6e-3) << smooth;
    EXPECT_LT(worstR, smooth ? 2.5 : 0.5);
  }
}

TEST(Cli, AnOpen3dFolderOpensWithItsTrajectoryAndSaysWhichCalibration) {
  // Open3D's RGB-D layout (color/, depth/, calibration JSON, trajectory.log): info names it, track follows it
  // at its own poses, and the one line on stderr says which of its two calibration files was taken.
  const std::string dir = std::string(MRGI_SHARED_DATA) + "/rgbd-open3d-iclnuim";
  const Result info = runMrgi("info " + dir);
  ASSERT_EQ(info.exitCode, 0) << info.err;
  const auto j = nlohmann::json::parse(info.out);
  EXPECT_EQ(j["kind"], "open3d");
  EXPECT_EQ(j["frame_count"], 5);
  EXPECT_EQ(j["has_ground_truth"], true);
  const Result gt = runMrgi("track " + dir + " --pose ground-truth --json");
  ASSERT_EQ(gt.exitCode, 0) << gt.err;
  const auto lines = jsonLines(gt.out);
  ASSERT_EQ(lines.size(), 5u);
  for (const auto& l : lines) EXPECT_EQ(l["by"], "ground-truth");
  // T_camera_world of frame 0: the inverse of trajectory.log's first camera-to-world pose (its translation
  // -0.311, 0.573, 2.126 m).
  const cv::Matx44d T = matFromRows(lines[0]["T_camera_world"]).inv();
  EXPECT_NEAR(T(2, 3), 2.1264800183565487, 1e-9);
  EXPECT_NE(gt.err.find("note: " + dir + ": 2 calibration files disagree; camera_primesense.json takes"),
            std::string::npos)
      << gt.err;
  const Result given = runMrgi("track " + dir + " --pose odometry --json --intrinsics 525,525,319.5,239.5");
  ASSERT_EQ(given.exitCode, 0) << given.err;
  EXPECT_EQ(given.err.find("note:"), std::string::npos) << given.err;
  expectOneLineError(runMrgi("track " + dir + " --pose odometry --depth-scale 0"), "--depth-scale");
}

TEST(Cli, TrackSingleImageAndItsErrors) {
  const std::string img = std::string(MRGI_SHARED_DATA) + "/apriltag-visp/AprilTag.png";
  const Result r = runMrgi("track " + img + " --intrinsics 615.167,615.168,312.189,243.437 --size 0.053 --json");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto out = jsonLines(r.out);
  ASSERT_EQ(out.size(), 12u);  // ids 8-19
  for (const auto& l : out) {
    EXPECT_EQ(l["status"], "tracked");
    EXPECT_EQ(l["T_camera_tag"].size(), 4u);
    EXPECT_GT(l["T_camera_tag"][2][3].get<double>(), 0.3);
  }
  const Result one =
      runMrgi("track " + img + " --intrinsics 615.167,615.168,312.189,243.437 --size 0.053 --id 13 --json");
  ASSERT_EQ(one.exitCode, 0) << one.err;
  ASSERT_EQ(jsonLines(one.out).size(), 1u);
  EXPECT_EQ(jsonLines(one.out)[0]["id"], 13);
  expectOneLineError(runMrgi("track " + img), "needs --intrinsics");
  expectOneLineError(runMrgi("track " + img + " --intrinsics 1,2,x,4"), "not a number");
  // A tag that is not there: each frame reports it lost, then one line and a non-zero exit.
  const Result missing = runMrgi("track " + img + " --intrinsics 615,615,312,243 --id 300 --json");
  expectOneLineError(missing, "marker never seen");
  ASSERT_EQ(jsonLines(missing.out).size(), 1u);
  EXPECT_EQ(jsonLines(missing.out)[0]["status"], "lost");
  EXPECT_TRUE(jsonLines(missing.out)[0]["T_camera_tag"].is_null());
  expectOneLineError(runMrgi("track " + img + " --intrinsics 615,615,312,243 --family tag99h1"), "unknown tag family");
}

TEST(Cli, CalibrateFisheyeReproducesTheRosCalibration) {
  const std::string dir = std::string(MRGI_SHARED_DATA) + "/fisheye-ros-calib";
  const fs::path out = fs::temp_directory_path() / ("mrgi_calib_" + std::to_string(::getpid()) + ".yaml");
  const Result r = runMrgi("calibrate-fisheye " + dir + " --board 6x8 --out " + out.string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto summary = nlohmann::json::parse(r.out);
  EXPECT_EQ(summary["views_used"], 24);
  EXPECT_LT(summary["rms_px"].get<double>(), 0.8);  // measured 0.50 px (ROS's own run: 0.70)
  // Same form as ost.yaml: our reader (which reads ROS files) reads it back.
  const auto mine = mrgi::capture::readFisheyeCalibration(out.string());
  const auto ros = mrgi::capture::readFisheyeCalibration(dir + "/ost.yaml");
  EXPECT_EQ(mine.width, 800);
  EXPECT_EQ(mine.height, 503);
  EXPECT_NEAR(mine.K(0, 0), ros.K(0, 0), 0.005 * ros.K(0, 0));
  EXPECT_NEAR(mine.K(1, 1), ros.K(1, 1), 0.005 * ros.K(1, 1));
  EXPECT_NEAR(mine.K(0, 2), ros.K(0, 2), 2.0);
  EXPECT_NEAR(mine.K(1, 2), ros.K(1, 2), 2.0);
  // D's coefficients trade off against each other; compare the models where it matters: the pixel each
  // direction lands on, out to 90 degrees from the axis.
  std::vector<cv::Point3d> dirs;
  for (double th = 0.05; th < CV_PI / 2; th += 0.05)
    for (double ph = 0; ph < 2 * CV_PI; ph += 0.3)
      dirs.emplace_back(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th));
  std::vector<cv::Point2d> a, b;
  cv::fisheye::projectPoints(dirs, a, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), mine.K, mine.D);
  cv::fisheye::projectPoints(dirs, b, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), ros.K, ros.D);
  double worst = 0;
  for (size_t i = 0; i < a.size(); ++i) worst = std::max(worst, cv::norm(a[i] - b[i]));
  std::printf("max model difference to ost.yaml within 90 deg: %.2f px\n", worst);
  EXPECT_LT(worst, 3.0);
  // The file says who wrote it, so a later run may replace it; a YAML the user has is never replaced.
  EXPECT_EQ(slurp(out).substr(0, 38), "# generated by mrgi calibrate-fisheye\n");
  const fs::path users = out.string() + ".users.yaml";
  fs::copy_file(dir + "/ost.yaml", users, fs::copy_options::overwrite_existing);
  expectOneLineError(runMrgi("calibrate-fisheye " + dir + " --board 6x8 --out " + users.string()),
                     "refusing to overwrite");
  EXPECT_EQ(slurp(users), slurp(dir + "/ost.yaml"));
  fs::remove(users);
  fs::remove(out);
  expectOneLineError(runMrgi("calibrate-fisheye " + dir + " --board 6by8 --out " + out.string()), "--board");
  expectOneLineError(runMrgi("calibrate-fisheye /nonexistent --out " + out.string()), "/nonexistent");
  EXPECT_FALSE(fs::exists(out));
}

TEST(Cli, SingleFileOutputsNeverReplaceAFileTheUserHas) {
  // Every flag naming one file to write refuses, before any work, a file its command did not write; its
  // own earlier output (recognised by content: JSON generated_by, PNG Software text, HTML generator meta,
  // the CSV's header) may be replaced.
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_users_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const auto users = [&](const std::string& name, const std::string& content) {
    std::ofstream(dir / name) << content;
    return (dir / name).string();
  };
  struct Case {
    std::string args, file;
  };
  const std::string png =
      users("photo.png", slurp(fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-synth/colour/000000.png"));
  const std::string s = session().string();
  const std::vector<Case> cases = {
      {"bench --session " + s + " --quick --json ", users("results.json", "{\"mine\": 1}\n")},
      {"bench --session " + s + " --quick --csv ", users("table.csv", "a,b\n1,2\n")},
      {"bench --session " + s + " --quick --html ", users("page.html", "<html>my page</html>\n")},
      {"bench --session " + s + " --quick --presets ", users("presets.json", "{\"generated_by\": \"me\"}\n")},
      {"insert --session " + s + " --model " + std::string(MRGI_SOURCE_DIR) + "/recordings/models/sphere.ply --save " +
           (dir / "scene.json").string() + " --preview ",
       png},
      {"room-lights /nonexistent/room --map ", png},
      {"calibrate-fisheye " + std::string(MRGI_SHARED_DATA) + "/fisheye-ros-calib --out ",
       users("calib.yaml", "camera_name: mine\n")},
      {"live --source " + s + " --frames 1 --screenshot ", png},
  };
  for (const Case& c : cases) {
    const std::string before = slurp(c.file);
    const Result r = runMrgi(c.args + c.file);
    SCOPED_TRACE(c.args);
    expectOneLineError(r, c.file);
    EXPECT_NE(r.err.find("refusing to overwrite"), std::string::npos) << c.args << ": " << r.err;
    EXPECT_EQ(slurp(c.file), before) << c.args;
  }
  EXPECT_FALSE(fs::exists(dir / "scene.json"));
  // Its own earlier output passes the check (the run then fails on the missing session, after it).
  const std::vector<Case> ours = {
      {"bench --session /nonexistent/s --json ",
       users("ours.json", "{\"generated_by\": \"mrgi bench\", \"records\": []}\n")},
      {"bench --session /nonexistent/s --csv ",
       users("ours.csv", std::string("technique,varied,knobs,ms_total,ms_lighting,gpu_mb,rmse_delta,rel_error_delta,"
                                     "rel_error_delta_near,rel_error_virtual,ssim,flicker") +
                             "\n")},  // an earlier version's columns
      {"bench --session /nonexistent/s --csv ",
       users("ours_now.csv",
             "technique,varied,knobs,ms_total,ms_lighting,ms_view,ms_replay,gpu_mb,rmse_delta,rel_error_delta,"
             "rel_error_delta_near,rel_error_virtual,ssim,flicker\n")},
      {"bench --session /nonexistent/s --html ",
       users("ours.html", "<!DOCTYPE html><html><head><meta name=\"generator\" content=\"mrgi bench\">")},
  };
  for (const Case& c : ours) expectOneLineError(runMrgi(c.args + c.file), "/nonexistent/s");
  fs::remove_all(dir);
}

TEST(Cli, LightsFromAnHdrFisheyeImage) {
  const std::string calib = std::string(MRGI_SHARED_DATA) + "/fisheye-ros-calib/ost.yaml";
  const fs::path rec = fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-synth/fisheye/000000.exr";
  const Result r = runMrgi("lights " + rec.string() + " --calib " + calib + " --count 8 --json");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["lights"].size(), 8u);
  double sum[3] = {0, 0, 0};
  for (const auto& l : j["estimated"]) {
    double n = 0;
    for (int k = 0; k < 3; ++k)
      sum[k] += l["power"][k].get<double>(), n += std::pow(l["direction"][k].get<double>(), 2);
    EXPECT_NEAR(n, 1.0, 1e-9);
  }
  // The lights and the remainder's SH (band 0 times 2 sqrt(pi) is its sum of L dOmega) hold the total.
  ASSERT_EQ(j["ambient_sh"].size(), 9u);
  for (int k = 0; k < 3; ++k) {
    const double rest = j["ambient_sh"][0][k].get<double>() * 2 * std::sqrt(CV_PI);
    EXPECT_GT(rest, 0.0);
    EXPECT_NEAR(sum[k] + rest, j["total_power"][k].get<double>(), 1e-7 * (sum[k] + rest));  // the lights' part is float
  }
  // Without a remainder every bit of light goes to the lights, as before.
  const auto all = nlohmann::json::parse(
      runMrgi("lights " + rec.string() + " --calib " + calib + " --count 8 --json --ambient-threshold 0").out);
  double allSum[3] = {0, 0, 0};
  for (const auto& l : all["estimated"])
    for (int k = 0; k < 3; ++k) allSum[k] += l["power"][k].get<double>();
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(allSum[k], all["total_power"][k].get<double>(), 1e-9 * allSum[k]);
  EXPECT_EQ(all["ambient_sh"][0][0].get<double>(), 0.0);
  // LDR input, automatic count, variance split.
  const fs::path png = fs::temp_directory_path() / ("mrgi_fish_" + std::to_string(::getpid()) + ".png");
  cv::Mat ldr(503, 800, CV_8UC3, cv::Scalar(40, 40, 40));
  cv::circle(ldr, {300, 200}, 6, cv::Scalar(255, 255, 255), cv::FILLED);
  cv::imwrite(png.string(), ldr);
  const Result auto_ = runMrgi("lights " + png.string() + " --calib " + calib + " --count 0 --variance --json");
  ASSERT_EQ(auto_.exitCode, 0) << auto_.err;
  EXPECT_GT(nlohmann::json::parse(auto_.out)["saturated_fraction"].get<double>(), 0.0);
  expectOneLineError(runMrgi("lights " + png.string() + " --calib /nonexistent.yaml"), "/nonexistent.yaml");
  const fs::path small = fs::temp_directory_path() / ("mrgi_small_" + std::to_string(::getpid()) + ".png");
  cv::imwrite(small.string(), cv::Mat(10, 10, CV_8UC3, cv::Scalar(1, 2, 3)));
  expectOneLineError(runMrgi("lights " + small.string() + " --calib " + calib), "calibration");
  fs::remove(png), fs::remove(small);
}

namespace {
fs::path writeScene(const std::string& name, const std::string& text) {
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_scenes_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / name) << text;
  return dir / name;
}
const std::string kModels = std::string(MRGI_SOURCE_DIR) + "/recordings/models/";

/// A fresh folder `dir` (under the temp directory, named after the test and the process) holding `frames`
/// frames of `source` recorded into dir/s: a session the test may damage. Returns dir.
fs::path scratchSession(const std::string& name, const fs::path& source, int frames) {
  const fs::path dir = fs::temp_directory_path() / (name + std::to_string(::getpid()));
  fs::remove_all(dir);
  const Result r = runMrgi("record --source " + source.string() + " --frames " + std::to_string(frames) + " --out " +
                           (dir / "s").string());
  EXPECT_EQ(r.exitCode, 0) << r.err;
  return dir;
}
// A sphere on the marker under the session's lights, Kinect-VAL at small maps: a quick scene for replay's options.
fs::path smallSphereScene(const std::string& name) {
  return writeScene(name, R"({"objects": [{"model": ")" + kModels +
                              R"(sphere.ply", "translate": [0, 0, 0.06], "scale": 0.06}],
      "lights": "manifest", "technique": "kinect-val", "frame": {"rsm_size": 64, "shadow_size": 128},
      "val": {"sparse_points": 64}})");
}
}  // namespace

TEST(Cli, OutputFoldersAreClaimedForTheirRunAndAKilledRunIsReplaced) {
  const std::string session = (fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-synth").string();
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_claim_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path out = dir / "out";
  const std::string replay = "replay " + session + " --frames 1 --mp4 '' --out " + out.string();
  // A run in progress holds the folder's claim (here this process stands in for it): a second run is refused at
  // once, naming the folder and the process; two replays into one folder both ran and mixed their frames.
  fs::create_directories(out);
  {
    const int fd = ::open((out / ".mrgi-claim").c_str(), O_RDWR | O_CREAT, 0644);
    ASSERT_GE(fd, 0);
    const std::string text = R"({"generated_by": "mrgi replay", "pid": )" + std::to_string(::getpid()) + "}\n";
    ASSERT_EQ(::write(fd, text.data(), text.size()), static_cast<ssize_t>(text.size()));
    ASSERT_EQ(::flock(fd, LOCK_EX | LOCK_NB), 0);
    std::ofstream(out / "frame_0000.png") << "the other run's frame";
    expectOneLineError(runMrgi(replay), out.string() + ": is being written by another run of mrgi (process " +
                                            std::to_string(::getpid()) + ")");
    EXPECT_EQ(slurp(out / "frame_0000.png"), "the other run's frame");  // untouched
    ::close(fd);  // the run ends (or is killed): its lock goes with it
  }
  // Killed before it wrote its summary, its folder is still recognised by its claim: a rerun replaces it.
  Result r = runMrgi(replay);
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_TRUE(fs::exists(out / "summary.json"));
  EXPECT_NE(slurp(out / "frame_0000.png"), "the other run's frame");
  // A folder another command claimed is not this one's.
  const fs::path room = dir / "room";
  fs::create_directories(room);
  std::ofstream(room / ".mrgi-claim") << R"({"generated_by": "mrgi room", "pid": 1})"
                                      << "\n";
  std::ofstream(room / "room.ply") << "a room";
  expectOneLineError(runMrgi("replay " + session + " --frames 1 --mp4 '' --out " + room.string()),
                     room.string() + ": is not empty and holds no earlier output of mrgi replay");
  EXPECT_EQ(slurp(room / "room.ply"), "a room");
  // A control character in a path is refused before anything is made.
  r = runMrgi("replay " + session + " --frames 1 --out '" + (dir / "a").string() + "\nb'");
  expectOneLineError(r, "--out");
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("control character"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "a\nb"));
  fs::remove_all(dir);
}

TEST(Cli, ASessionManifestThatIsNoFileSaysWhatItIs) {
  // A folder, a pipe or a device where manifest.json should be: "missing: not an mrgi session" before.
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_manifest_kind_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const fs::path synth = fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-synth";
  for (const char* kind : {"folder", "fifo", "device"}) {
    const fs::path s = dir / kind;
    fs::create_directories(s);
    fs::copy_file(synth / "frames.jsonl", s / "frames.jsonl");
    const fs::path m = s / "manifest.json";
    if (std::string(kind) == "folder") fs::create_directories(m);
    if (std::string(kind) == "fifo") ASSERT_EQ(::mkfifo(m.c_str(), 0644), 0);
    if (std::string(kind) == "device") fs::create_symlink("/dev/zero", m);
    const Result r = runMrgi("info " + s.string());
    expectOneLineError(r, m.string() + (std::string(kind) == "folder" ? ": is a folder, not a session manifest"
                                                                      : ": is not a regular file (a device, pipe or "
                                                                        "socket), not a session manifest"));
  }
  fs::remove_all(dir);
}

TEST(Cli, InsertSavesIntoABareFileName) {
  // `--save x.json` (no folder): "filesystem error: cannot make absolute path" before; `./x.json` worked.
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_bare_save_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string session = (fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-synth").string();
  const std::string sphere = (fs::path(MRGI_SOURCE_DIR) / "recordings/models/sphere.ply").string();
  const std::string cmd = "cd " + dir.string() + " && " + MRGI_BINARY + " insert --session " + session + " --model " +
                          sphere + " --scale 0.05 --save x.json > out.txt 2> err.txt";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << slurp(dir / "err.txt");
  const auto scene = mrgi::lighting::loadScene((dir / "x.json").string());
  ASSERT_EQ(scene.objects.size(), 1u);
  fs::remove_all(dir);
}

TEST(Cli, InfoSaysWhatReplayWouldSayOfARecording) {
  // A raw ViSP folder was refused without a hint; a folder whose calibration is a fallback was reported silently
  // by info while replay printed a note.
  const std::string visp = std::string(MRGI_SHARED_DATA) + "/rgbd-visp-apriltag";
  expectOneLineError(runMrgi("info " + visp),
                     visp + ": a ViSP RGB-D sequence: convert it into a session with mrgi import-visp " + visp);
  const std::string icl = std::string(MRGI_SHARED_DATA) + "/rgbd-open3d-iclnuim";
  const Result r = runMrgi("info " + icl);
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("note: " + icl + ": 2 calibration files disagree"), std::string::npos) << r.err;
  // The commands' help says what they do now: the camera is tracked, not only the marker.
  const Result help = runMrgi("--help");
  EXPECT_EQ(help.out.find("Track an AprilTag marker"), std::string::npos) << help.out;
  EXPECT_EQ(help.out.find("every frame's marker pose"), std::string::npos) << help.out;
  EXPECT_NE(help.out.find("Track the camera through a recording"), std::string::npos) << help.out;
}

TEST(Cli, AMisspeltSubcommandFlagTechniqueOrKeySaysWhatItMeant) {
  const std::string session = (fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-synth").string();
  const std::string out = (fs::temp_directory_path() / ("mrgi_cli_misspelt_" + std::to_string(::getpid()))).string();
  fs::remove_all(out);
  expectOneLineError(runMrgi("replya " + session), "did you mean 'replay'?");
  expectOneLineError(runMrgi("replay " + session + " --out " + out + " --per-frame-mes"),
                     "did you mean '--per-frame-mesh'?");
  expectOneLineError(runMrgi("replay " + session + " --out " + out + " --technique dlvp"), "did you mean 'dlpv'?");
  const fs::path scene = writeScene("misspelt_key.json", R"({"objects": [], "ligths": "auto"})");
  expectOneLineError(runMrgi("replay " + session + " --scene " + scene.string() + " --out " + out),
                     "ligths: unknown key (did you mean 'lights'?)");
  EXPECT_FALSE(fs::exists(out));
}

TEST(Cli, ABareRecordingIsLitFromItsRoomByDefault) {
  // The ViSP desk recording lists no lights and has no fisheye: insert places an object without a scene file
  // (its preview lit from the room fused from every frame), saves "lights": "auto", and replay lights it from
  // the same room, fused first. One line on stderr says so each time.
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_bare_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string session = (dir / "visp").string();
  ASSERT_EQ(runMrgi("import-visp " + std::string(MRGI_SHARED_DATA) + "/rgbd-visp-apriltag --out " + session).exitCode,
            0);
  const Result ins = runMrgi("insert --session " + session + " --model " + kModels +
                             "sphere.ply --scale 0.045 --at 480,380 --snap --save " + (dir / "scene.json").string() +
                             " --preview " + (dir / "preview.png").string());
  ASSERT_EQ(ins.exitCode, 0) << ins.err;
  EXPECT_NE(ins.err.find("lists no lights and has no fisheye camera"), std::string::npos) << ins.err;
  EXPECT_EQ(messageLines(ins.err), 1) << ins.err;
  const auto scene = nlohmann::json::parse(slurp(dir / "scene.json"));
  EXPECT_EQ(scene["lights"], "auto");
  const Result rep = runMrgi("replay " + session + " --scene " + (dir / "scene.json").string() +
                             " --frames 3 --dump-delta --out " + (dir / "out").string());
  ASSERT_EQ(rep.exitCode, 0) << rep.err;
  EXPECT_NE(rep.err.find("the scene is lit from the room"), std::string::npos) << rep.err;
  // Every frame draws the object, lit: its pixels neither black nor clipped.
  for (int f = 0; f < 3; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "%04d.png", f);
    const cv::Mat mask = cv::imread((dir / "out" / (std::string("mask_") + name)).string(), cv::IMREAD_GRAYSCALE);
    const cv::Mat frame = cv::imread((dir / "out" / (std::string("frame_") + name)).string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(mask.empty() || frame.empty()) << f;
    EXPECT_GT(cv::countNonZero(mask), 2000) << f;
    const double level = cv::mean(frame, mask)[0];
    EXPECT_GT(level, 60) << f;
    EXPECT_LT(level, 250) << f;
  }
  fs::remove_all(dir);
}

TEST(Cli, ReplayWithSceneWritesCompositesDeltaAndMask) {
  const fs::path scene = writeScene("sphere.json", R"({"objects": [{"model": ")" + kModels +
                                                       R"(sphere.ply", "translate": [0, 0, 0.06], "scale": 0.06}],
      "lights": "manifest", "lpv": {"resolution": 16, "steps": 8, "rsm_size": 128}})");
  for (const std::string technique : {"dlpv", "lpv-diff", "kinect-val", "dlpv+kinect-val"}) {
    const fs::path out = fs::temp_directory_path() / ("mrgi_cli_dlpv_" + technique + std::to_string(::getpid()));
    const bool lpv = technique != "kinect-val", val = technique.find("kinect-val") != std::string::npos;
    fs::remove_all(out);
    // Each frame's own depth mesh: the techniques' per-frame work (with the default fused room their world-space
    // passes run on the first frame only).
    // Per-stage timings per frame with --verbose only (lpv-diff runs without it), in the pipeline's order.
    const bool verbose = technique != "lpv-diff";
    const Result r = runMrgi("replay " + session().string() + " --scene " + scene.string() + " --out " + out.string() +
                             " --frames 2 --dump-delta --pose ground-truth --per-frame-mesh --technique " + technique +
                             (verbose ? " --verbose" : ""));
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(r.out.find("frame 2/2:") != std::string::npos, verbose) << r.out;
    if (verbose) {
      EXPECT_EQ(r.out.find("lpv.propagate") != std::string::npos, lpv) << r.out;
      EXPECT_EQ(r.out.find("val.gather") != std::string::npos, val) << r.out;
      const std::string first = r.out.substr(r.out.find("frame 1/2:"));
      const size_t read = first.find(" read "), gbuffer = first.find(" gbuffer "),
                   own = first.find(lpv ? " lpv.inject " : " val.upload "), shade = first.find(" shade "),
                   composite = first.find(" composite ");
      EXPECT_LT(read, gbuffer) << first;
      EXPECT_LT(gbuffer, own) << first;
      EXPECT_LT(own, shade) << first;
      EXPECT_LT(shade, composite) << first;
      EXPECT_NE(composite, std::string::npos) << first;
    }
    // The last line names the folder and what it holds.
    EXPECT_NE(r.out.find("wrote " + out.string() + ": delta_NNNN.exr x 2, frame_NNNN.png x 2, mask_NNNN.png x 2"),
              std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("summary.json"), std::string::npos) << r.out;
    const cv::Mat delta = cv::imread((out / "delta_0001.exr").string(), cv::IMREAD_UNCHANGED);
    const cv::Mat mask = cv::imread((out / "mask_0001.png").string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(delta.type(), CV_32FC3);
    ASSERT_EQ(mask.type(), CV_8UC1);
    EXPECT_GT(cv::countNonZero(mask == 255), 50);  // the sphere covers pixels
    EXPECT_EQ(cv::countNonZero((mask != 255) & (mask != 0)), 0);
    double lo, hi;
    cv::minMaxLoc(delta.reshape(1), &lo, &hi);
    EXPECT_LT(lo, 0.0) << technique;  // its shadow
    EXPECT_TRUE(std::isfinite(lo) && std::isfinite(hi));
    // Real pixels: composite = background + delta; virtual pixels differ from the camera image.
    const cv::Mat composite = cv::imread((out / "frame_0001.png").string());
    const cv::Mat colour = cv::imread((session() / "colour/000001.png").string());
    cv::Mat diff;
    cv::absdiff(composite, colour, diff);
    cv::Mat diffGrey;
    cv::cvtColor(diff, diffGrey, cv::COLOR_BGR2GRAY);
    EXPECT_GT(cv::countNonZero((diffGrey > 10) & (mask == 255)), 20);
    const auto s = nlohmann::json::parse(slurp(out / "summary.json"));
    EXPECT_EQ(s["technique"], technique);
    EXPECT_EQ(s["roles"]["virtual"], val ? "kinect-val" : "dlpv");
    EXPECT_EQ(s["roles"]["real"], lpv ? "dlpv" : "none");
    EXPECT_EQ(s["knobs"].contains("lpv") && s["knobs"]["lpv"].contains("resolution"), lpv);
    EXPECT_EQ(s["knobs"]["frame"]["rsm_size"], 128);
    EXPECT_EQ(s["stages_ms"].contains("lpv.inject"), lpv);
    if (val) {
      // Kinect-VAL: real VALs from the frame, virtual ones from the RSM, the default 1024 sparse points,
      // the real surfaces fused over the two frames, and the bounce light's frame-to-frame change.
      const auto& f = s["per_frame"][1]["techniques"]["kinect-val"];
      EXPECT_GT(f["real_vals"].get<int>(), 1000);
      EXPECT_GT(f["virtual_vals"].get<int>(), 10);
      EXPECT_EQ(f["receivers"].get<int>(), 1024);
      EXPECT_GE(s["per_frame"][1]["surfels"].get<int>(), f["real_vals"].get<int>());
      EXPECT_GT(f["mean_irradiance"].get<double>(), 0.0);
      const double flicker = s["flicker_mean"]["kinect-val"].get<double>();  // 2 frames far apart on the orbit
      EXPECT_TRUE(flicker > 0.0 && flicker < 1.0) << flicker;
      EXPECT_EQ(s["knobs"]["val"]["sparse_points"], 1024);
    }
    fs::remove_all(out);
  }
}

TEST(Cli, ReplayWithEmptySceneEqualsTheBackground) {
  const fs::path scene = writeScene("empty.json", R"({"objects": [], "lights": "manifest"})");
  const fs::path out = fs::temp_directory_path() / ("mrgi_cli_empty_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const Result r = runMrgi("replay " + session().string() + " --scene " + scene.string() + " --out " + out.string() +
                           " --frames 2 --dump-delta");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  for (int i = 0; i < 2; ++i) {
    const std::string n = std::to_string(i);
    const cv::Mat composite = cv::imread((out / ("frame_000" + n + ".png")).string());
    const cv::Mat colour = cv::imread((session() / ("colour/00000" + n + ".png")).string());
    EXPECT_LE(cv::norm(composite, colour, cv::NORM_INF), 1.0);  // <= 1/255
    const cv::Mat delta = cv::imread((out / ("delta_000" + n + ".exr")).string(), cv::IMREAD_UNCHANGED);
    EXPECT_EQ(cv::norm(delta, cv::NORM_INF), 0.0);
  }
  fs::remove_all(out);
}

TEST(Cli, BadSceneFilesAreOneLineErrors) {
  fs::remove_all("/tmp/mrgi_never_written");
  const std::string base = "replay " + session().string() + " --out /tmp/mrgi_never_written --scene ";
  expectOneLineError(runMrgi(base + "/nonexistent/scene.json"), "/nonexistent/scene.json: is missing");
  expectOneLineError(runMrgi(base + writeScene("typo.json", R"({"objets": []})").string()), "objets: unknown key");
  expectOneLineError(runMrgi(base + writeScene("nomodel.json", R"({"objects": [{"model": "gone.obj"}]})").string()),
                     "objects[0].model:");
  expectOneLineError(runMrgi(base + writeScene("knob.json", R"({"lpv": {"steps": -1}})").string()), "lpv.steps");
  EXPECT_FALSE(fs::exists("/tmp/mrgi_never_written"));
}

TEST(Cli, ReplayEstimatesLightsFromTheSessionFisheye) {
  const fs::path scene = writeScene("fisheye.json", R"({"objects": [{"model": ")" + kModels +
                                                        R"(sphere.ply", "translate": [0, 0, 0.06], "scale": 0.06}],
      "lights": "fisheye", "fisheye_light_count": 4, "lpv": {"resolution": 16, "steps": 4, "rsm_size": 64}})");
  const fs::path out = fs::temp_directory_path() / ("mrgi_cli_fisheye_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const Result r = runMrgi("replay " + session().string() + " --scene " + scene.string() + " --out " + out.string() +
                           " --frames 2 --dump-delta --pose ground-truth");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto s = nlohmann::json::parse(slurp(out / "summary.json"));
  EXPECT_EQ(s["per_frame"][0]["lights_estimated"], 4);           // the session has a fisheye image on frame 0
  EXPECT_FALSE(s["per_frame"][1].contains("lights_estimated"));  // none on frame 1: lights kept, not re-estimated
  const cv::Mat delta = cv::imread((out / "delta_0001.exr").string(), cv::IMREAD_UNCHANGED);
  double lo;
  cv::minMaxLoc(delta.reshape(1), &lo);
  EXPECT_LT(lo, 0.0);  // the estimated lights cast a shadow
  fs::remove_all(out);
  // A session without a fisheye calibration is a one-line error naming the scene.
  const fs::path noFisheye = fs::temp_directory_path() / ("mrgi_cli_nofisheye_" + std::to_string(::getpid()));
  fs::remove_all(noFisheye);
  ASSERT_EQ(
      runMrgi("synth --out " + noFisheye.string() + " --frames 1 --width 160 --height 120 --fisheye-every 0").exitCode,
      0);
  expectOneLineError(runMrgi("replay " + noFisheye.string() + " --scene " + scene.string() + " --out " + out.string()),
                     "has no fisheye calibration");
  fs::remove_all(noFisheye);
}

TEST(Cli, ReplayFusesEveryNthFrameAndRefreshesByTheFramesFused) {
  const fs::path scene = smallSphereScene("fuse_every.json");
  const fs::path out = fs::temp_directory_path() / ("mrgi_cli_fuse_every_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const Result r = runMrgi("replay " + session().string() + " --scene " + scene.string() + " --out " + out.string() +
                           " --pose ground-truth --frames 3 --mp4 \"\" --fuse-every 2 --fuse-refresh 1");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto s = nlohmann::json::parse(slurp(out / "summary.json"));
  ASSERT_EQ(s["frames"], 3);
  // Frames 0 and 2 fused, each refreshing the surface (every frame fused refreshes it); frame 1 left out.
  for (int i : {0, 2}) {
    EXPECT_EQ(s["per_frame"][i]["room_fusion"]["integrated"], true) << i;
    EXPECT_TRUE(s["per_frame"][i]["room_fusion"].contains("refreshed")) << i;
  }
  EXPECT_EQ(s["per_frame"][1]["room_fusion"]["integrated"], false);
  EXPECT_EQ(s["per_frame"][1]["room_fusion"]["skipped"], "fuse every 2");
  fs::remove_all(out);
  expectOneLineError(runMrgi("replay " + session().string() + " --scene " + scene.string() + " --out " + out.string() +
                             " --fuse-every 0"),
                     "--fuse-every");
  EXPECT_FALSE(fs::exists(out));
}

TEST(Cli, ReplayFinishingEachStageWritesTheSameCompositesAndSaysSo) {
  const fs::path scene = smallSphereScene("finish_stages.json");
  std::vector<fs::path> outs;
  for (const std::string mode : {"", " --finish-stages"}) {
    const fs::path out = fs::temp_directory_path() /
                         ("mrgi_cli_finish_" + std::to_string(outs.size()) + "_" + std::to_string(::getpid()));
    fs::remove_all(out);
    const Result r = runMrgi("replay " + session().string() + " --scene " + scene.string() + " --out " + out.string() +
                             " --pose ground-truth --frames 2 --mp4 \"\" --sequential" + mode);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const auto s = nlohmann::json::parse(slurp(out / "summary.json"));
    EXPECT_EQ(s["finish_stages"], !mode.empty());
    EXPECT_GT(s["stages_ms"]["shade"]["gpu_ms"].get<double>(), 0.0);
    outs.push_back(out);
  }
  for (const char* name : {"frame_0000.png", "frame_0001.png"}) {
    const cv::Mat a = cv::imread((outs[0] / name).string()), b = cv::imread((outs[1] / name).string());
    ASSERT_FALSE(a.empty() || b.empty()) << name;
    EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0) << name;
  }
  for (const auto& out : outs) fs::remove_all(out);
}

TEST(Cli, ReplayPreparesTheNextFrameWhileRenderingAndWritesTheSameComposites) {
  // Frame n + 1's CPU half (marker, depth filter, albedo, real mesh and VALs) runs on a worker while GL works
  // on frame n. What it changes (the lights of its frame, estimated from the fisheye or moved by the session,
  // the surfels, the reuse cache) must not reach frame n: the composites equal those of --sequential bit for
  // bit. Lights estimated on frames 0 and 2 (the shared session's fisheye), and a lamp that moves every frame.
  const fs::path moving = fs::temp_directory_path() / ("mrgi_cli_overlap_moving_" + std::to_string(::getpid()));
  fs::remove_all(moving);
  ASSERT_EQ(
      runMrgi("synth --out " + moving.string() +
              " --frames 4 --width 96 --height 72 --render raycast --fisheye-every 0 --static-camera --move-light")
          .exitCode,
      0);
  const std::string sphere =
      R"({"objects": [{"model": ")" + kModels + R"(sphere.ply", "translate": [0, 0, 0.06], "scale": 0.06}], )";
  const fs::path fisheyeScene =
      writeScene("overlap_fisheye.json", sphere + R"("lights": "fisheye", "fisheye_light_count": 2,
      "technique": "kinect-val", "frame": {"rsm_size": 64, "shadow_size": 128}, "val": {"sparse_points": 64}})");
  const fs::path movingScene = smallSphereScene("overlap_moving.json");
  // Both real scenes: each frame's depth mesh, and the room fused as the frames come (the default; the fusion
  // thread fuses frame n while frame n + 1 is measured, and a frame that refreshes the surface, here every
  // other one, is lit by it).
  for (const auto& [source, scene, frames, fused] :
       {std::tuple{session(), fisheyeScene, 3, false}, std::tuple{moving, movingScene, 4, false},
        std::tuple{session(), fisheyeScene, 3, true}, std::tuple{moving, movingScene, 4, true}}) {
    std::vector<fs::path> outs;
    for (const std::string mode : {fused ? " --fuse-refresh 2" : " --per-frame-mesh",
                                   fused ? " --fuse-refresh 2 --sequential" : " --per-frame-mesh --sequential"}) {
      const fs::path out = fs::temp_directory_path() /
                           ("mrgi_cli_overlap_" + std::to_string(outs.size()) + "_" + std::to_string(::getpid()));
      fs::remove_all(out);
      const Result r = runMrgi("replay " + source.string() + " --scene " + scene.string() + " --out " + out.string() +
                               " --pose ground-truth --mp4 \"\"" + mode);
      ASSERT_EQ(r.exitCode, 0) << r.err;
      const auto s = nlohmann::json::parse(slurp(out / "summary.json"));
      EXPECT_EQ(s["frames"], frames);
      EXPECT_EQ(s["overlapped"], mode.find("--sequential") == std::string::npos) << mode;
      // The worker's stages are reported as their frame's.
      for (const char* stage : fused ? std::vector<const char*>{"depth_filter", "room_fusion", "room_mesh"}
                                     : std::vector<const char*>{"depth_filter", "albedo", "mesh", "technique_inputs"})
        EXPECT_GT(s["stages_ms"][stage]["cpu_ms"].get<double>(), 0.0) << stage << mode;
      if (fused) {
        // The surface refreshed on the first frame, then every other frame fused.
        for (int i = 0; i < frames; ++i)
          EXPECT_EQ(s["per_frame"][i]["room_fusion"].contains("refreshed"), i % 2 == 0) << i << mode;
      }
      if (source == moving)
        for (int i = 0; i < frames; ++i) EXPECT_EQ(s["per_frame"][i]["lights_from_frame"], 1) << i;
      else
        EXPECT_EQ(s["per_frame"][2]["lights_estimated"], 2);
      outs.push_back(out);
    }
    for (int i = 0; i < frames; ++i) {
      char name[32];
      std::snprintf(name, sizeof name, "frame_%04d.png", i);
      const cv::Mat a = cv::imread((outs[0] / name).string()), b = cv::imread((outs[1] / name).string());
      ASSERT_FALSE(a.empty() || b.empty()) << name;
      EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0) << source << " " << name;
    }
    // The lamp moved: the frames differ from each other (so equal composites are not equal by accident).
    if (source == moving) {
      const cv::Mat f0 = cv::imread((outs[0] / "frame_0000.png").string()),
                    f3 = cv::imread((outs[0] / "frame_0003.png").string());
      EXPECT_GT(cv::norm(f0, f3, cv::NORM_L1) / static_cast<double>(f0.total()), 1.0);
    }
    for (const fs::path& o : outs) fs::remove_all(o);
  }
  fs::remove_all(moving);
}

TEST(Cli, InsertSnapsOntoTheTableAndSavesAScene) {
  const fs::path rec = fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-synth";
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_insert_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path scene = dir / "placed.json";
  // Floating 0.3 m above the marker and rotated: --snap rests the 5 cm sphere on the table (the marker plane).
  Result r = runMrgi("insert --session " + rec.string() + " --model " + kModels +
                     "sphere.ply --scale 0.05 --translate 0.1,0.05,0.3" + " --rotate-deg 30,0,10 --snap --save " +
                     scene.string() + " --preview " + (dir / "preview.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  auto doc = nlohmann::json::parse(slurp(scene));
  ASSERT_EQ(doc["objects"].size(), 1u);
  const auto t = doc["objects"][0]["translate"];
  EXPECT_NEAR(t[0].get<double>(), 0.1, 0.01);
  EXPECT_NEAR(t[1].get<double>(), 0.05, 0.01);
  EXPECT_NEAR(t[2].get<double>(), 0.05, 0.008);  // centre one radius above the table (depth noise, tag pose)
  const auto rd = doc["objects"][0]["rotate_deg"];
  EXPECT_LT(std::abs(rd[0].get<double>()) + std::abs(rd[1].get<double>()), 4.0);  // up turned onto the normal
  EXPECT_EQ(doc["lights"], "fisheye");                                            // the session has a fisheye camera
  EXPECT_EQ(doc["objects"][0]["model"], fs::proximate(kModels + "sphere.ply", dir).generic_string());
  const auto report = nlohmann::json::parse(r.out);
  EXPECT_GT(report["plane"]["normal"][2].get<double>(), 0.99);
  // The preview shows the object: it differs from the camera image.
  const cv::Mat preview = cv::imread((dir / "preview.png").string());
  const cv::Mat colour = cv::imread((rec / "colour/000000.png").string());
  ASSERT_EQ(preview.size(), colour.size());
  EXPECT_GT(cv::norm(preview, colour, cv::NORM_L1) / preview.total(), 1.0);
  // A second insert into the same file keeps the first object.
  r = runMrgi("insert --session " + rec.string() + " --model " + kModels +
              "cube.obj --scale 0.04 --translate -0.1,0,0.02 --save " + scene.string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  doc = nlohmann::json::parse(slurp(scene));
  ASSERT_EQ(doc["objects"].size(), 2u);
  EXPECT_NEAR(doc["objects"][0]["translate"][2].get<double>(), t[2].get<double>(), 1e-12);
  // Replay reads it.
  const fs::path out = dir / "replay";
  r = runMrgi("replay " + rec.string() + " --scene " + scene.string() + " --out " + out.string() + " --frames 1");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_TRUE(fs::exists(out / "frame_0000.png"));
  // User errors: one line, the scene untouched.
  const std::string before = slurp(scene);
  const std::string base = "insert --session " + rec.string() + " --save " + scene.string();
  expectOneLineError(runMrgi(base + " --model /nonexistent/m.obj"), "/nonexistent/m.obj: model file not found");
  expectOneLineError(runMrgi(base + " --model " + kModels + "cube.obj --replace 7"), "--replace 7");
  expectOneLineError(runMrgi(base + " --model " + kModels + "cube.obj --frame 999"), "has no frame 999");
  expectOneLineError(runMrgi(base + " --model " + kModels + "cube.obj --at 5000,1"), "--at 5000,1: outside");
  expectOneLineError(
      runMrgi("insert --session /nonexistent/s --model " + kModels + "cube.obj --save " + scene.string()),
      "/nonexistent/s");
  EXPECT_EQ(slurp(scene), before);
  fs::remove_all(dir);
}

TEST(Cli, BenchKinectValWritesSparseAndBruteForceRecords) {
  const fs::path out = fs::temp_directory_path() / ("mrgi_cli_bench_" + std::to_string(::getpid()) + ".json");
  const std::string rec = (fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-synth").string();
  const Result r = runMrgi("bench --against bruteforce --technique kinect-val --session " + rec + " --model " +
                           kModels + "sphere.ply --vals 512,2048 --sparse 64,642 --repeats 1 --json " + out.string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto doc = nlohmann::json::parse(slurp(out));
  ASSERT_EQ(doc["records"].size(), 8u);  // 2 VAL counts × 2 sparse counts × occlusion off/on
  for (const auto& rec : doc["records"]) {
    EXPECT_EQ(rec["technique"], "kinect-val");
    EXPECT_GT(rec["ms_sparse"].get<double>(), 0.0);
    EXPECT_GT(rec["ms_bruteforce"].get<double>(), 0.0);
    const double e = rec["rel_error_vs_bruteforce"].get<double>();
    EXPECT_TRUE(std::isfinite(e));
    EXPECT_GE(e, 0.0);
    EXPECT_LT(e, 0.25);
  }
  // More sparse points, less error (same VALs, no occlusion): records 0 (64) and 2 (642).
  EXPECT_LT(doc["records"][2]["rel_error_vs_bruteforce"].get<double>(),
            doc["records"][0]["rel_error_vs_bruteforce"].get<double>());
  fs::remove(out);
  expectOneLineError(runMrgi("bench --against bruteforce --technique dlpv --json " + out.string()), "--technique dlpv");
}

TEST(Cli, BenchWritesWhatItsFlagsNameAndReplayTakesItsPresets) {
  // The command line over the bench's harness (whose sweep of every technique is BenchRun.*): one technique,
  // the files its flags name, said on stdout, and presets replay takes.
  const fs::path scene = writeScene("bench_sphere.json", R"({"objects": [{"model": ")" + kModels +
                                                             R"(sphere.ply", "translate": [0, 0, 0.06], "scale": 0.06}],
      "lights": "manifest", "lpv": {"resolution": 16, "steps": 8, "rsm_size": 128}})");
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_sweep_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const Result r = runMrgi("bench --quick --technique dlpv --session " + session().string() + " --scene " +
                           scene.string() + " --frames 2 --ref-frames 1 --ref-spp 4 --json " +
                           (dir / "b.json").string() + " --csv " + (dir / "b.csv").string() + " --html " +
                           (dir / "b.html").string() + " --presets " + (dir / "presets.json").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto doc = nlohmann::json::parse(slurp(dir / "b.json"));
  std::set<std::string> techniques;
  for (const auto& rec : doc["records"]) techniques.insert(rec["technique"].get<std::string>());
  EXPECT_EQ(techniques, (std::set<std::string>{"dlpv", "lpv-diff"}));
  EXPECT_EQ(lines(slurp(dir / "b.csv")), static_cast<int>(doc["records"].size()) + 1);
  EXPECT_NE(slurp(dir / "b.html").find("<svg"), std::string::npos);
  for (const char* file : {"b.json", "b.csv", "b.html", "presets.json"})
    EXPECT_NE(r.out.find(fs::absolute(dir / file).string()), std::string::npos) << file << ": " << r.out;
  const auto presets = nlohmann::json::parse(slurp(dir / "presets.json"));
  for (const char* name : {"fast", "balanced", "accurate"}) ASSERT_TRUE(presets["presets"].contains(name)) << name;
  // What its timings were measured under (runtime/threads.h): the settings the process ran with.
  for (const auto* j : {&doc, &presets})
    EXPECT_EQ((*j)["process"]["GLIBC_TUNABLES"],
              std::getenv("GLIBC_TUNABLES") ? std::getenv("GLIBC_TUNABLES") : mrgi::runtime::kGlibcTunables);
  const fs::path out = dir / "replay";
  const Result rp = runMrgi("replay " + session().string() + " --scene " + scene.string() +
                            " --frames 1 --pose ground-truth"
                            " --preset accurate --presets " +
                            (dir / "presets.json").string() + " --out " + out.string());
  ASSERT_EQ(rp.exitCode, 0) << rp.err;
  const auto summary = nlohmann::json::parse(slurp(out / "summary.json"));
  EXPECT_EQ(summary["preset"], "accurate");
  EXPECT_EQ(summary["technique"], presets["presets"]["accurate"]["technique"]);
  expectOneLineError(runMrgi("replay " + session().string() + " --scene " + scene.string() +
                             " --preset fast --presets " + scene.string() + " --out " + out.string()),
                     "has no preset \"fast\"");
  expectOneLineError(runMrgi("bench --quick --technique dlvp --session " + session().string()), "--technique");
  fs::remove_all(dir);
}

// The bench's HTML report as a reader sees it: rendered by headless Chromium at 1,000 and 1,600 px, nothing
// runs off the page's right edge; in every plot the tick labels of an axis differ from each other, each
// series has its own colour and marker, and each legend name fits inside its plot (6.2 px a character at
// 11 px). CI installs Chromium; without it here the rendering is skipped, not the rest.
TEST(Cli, TheBenchReportReadsAtAThousandToSixteenHundredPixels) {
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_report_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const Result r = runMrgi("bench --quick --technique imperfect-volumes+kinect-val --session " + session().string() +
                           " --frames 2 --ref-frames 1 --ref-spp 4 --html " + (dir / "r.html").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const std::string html = slurp(dir / "r.html");
  const std::regex svgRe("<svg([^>]*width='([0-9.]+)'[^>]*)>([\\s\\S]*?)</svg>");
  const std::regex plainTextRe("<text x='([0-9.]+)' y='[0-9.]+'>([^<]*)</text>");
  const std::regex tickRe("<text class='([xy]tick)'[^>]*>([^<]*)</text>");
  const std::regex legendRe("<(circle|rect|polygon)[^>]*fill='(#[0-9a-f]+)'[^>]*><title>legend</title>");
  const std::regex nameRe("<text class='legend' x='([0-9.]+)'[^>]*>([^<]*)</text>");
  int plots = 0, legends = 0;
  for (auto it = std::sregex_iterator(html.begin(), html.end(), svgRe); it != std::sregex_iterator(); ++it) {
    const double width = std::stod((*it)[2].str());
    const std::string body = (*it)[3].str();
    // Within the page's 968 px of content at 1,000 px, and scalable (a viewBox); every left-aligned text (the
    // stage bars' totals, in whole ms however slow the machine) inside its picture.
    EXPECT_LE(width, 968) << (*it)[1].str();
    EXPECT_NE((*it)[1].str().find("viewBox"), std::string::npos) << (*it)[1].str();
    for (auto t = std::sregex_iterator(body.begin(), body.end(), plainTextRe); t != std::sregex_iterator(); ++t)
      EXPECT_LE(std::stod((*t)[1].str()) + 6.2 * static_cast<double>((*t)[2].str().size()), width) << (*t)[2].str();
    std::map<std::string, std::vector<std::string>> ticks;
    for (auto t = std::sregex_iterator(body.begin(), body.end(), tickRe); t != std::sregex_iterator(); ++t)
      ticks[(*t)[1].str()].push_back((*t)[2].str());
    if (ticks.empty()) continue;  // not a plot (the stage bars)
    ++plots;
    for (const auto& [axis, labels] : ticks) {
      EXPECT_GE(labels.size(), 2u) << axis;
      EXPECT_EQ(std::set<std::string>(labels.begin(), labels.end()).size(), labels.size())
          << axis << ": " << ::testing::PrintToString(labels);
    }
    std::set<std::pair<std::string, std::string>> styles;
    int marks = 0;
    for (auto m = std::sregex_iterator(body.begin(), body.end(), legendRe); m != std::sregex_iterator(); ++m, ++marks)
      styles.insert({(*m)[1].str(), (*m)[2].str()});
    EXPECT_EQ(static_cast<int>(styles.size()), marks);
    for (auto n = std::sregex_iterator(body.begin(), body.end(), nameRe); n != std::sregex_iterator(); ++n, ++legends)
      EXPECT_LE(std::stod((*n)[1].str()) + 6.2 * static_cast<double>((*n)[2].str().size()), width) << (*n)[2].str();
  }
  EXPECT_GE(plots, 3);
  EXPECT_GE(legends, 3);
  EXPECT_NE(html.find(">imperfect-volumes+kinect-val<"), std::string::npos);
  // Rendered: the right edge stays the page's background at both widths.
  const char* browser = nullptr;
  for (const char* b : {"/usr/bin/chromium", "/usr/bin/chromium-browser"})
    if (fs::exists(b)) browser = b;
  if (!browser) {
    fs::remove_all(dir);
    GTEST_SKIP() << "no Chromium to render the report";
  }
  for (const int w : {1000, 1600}) {
    const fs::path shot = dir / ("shot_" + std::to_string(w) + ".png");
    // Bounded in time, without the sandbox and the /dev/shm a CI container may not give it.
    const std::string cmd =
        "timeout 120 " + std::string(browser) +
        " --headless=new --no-sandbox --disable-dev-shm-usage --disable-gpu --hide-scrollbars --window-size=" +
        std::to_string(w) + ",4000 --screenshot=" + shot.string() + " file://" + (dir / "r.html").string() +
        " > /dev/null 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    const cv::Mat img = cv::imread(shot.string(), cv::IMREAD_GRAYSCALE);
    ASSERT_EQ(img.cols, w);
    cv::Mat content;
    cv::compare(img, 245, content, cv::CMP_LT);
    EXPECT_GT(cv::countNonZero(content), img.total() / 50) << w;  // a page, not a blank
    EXPECT_EQ(cv::countNonZero(content.colRange(w - 6, w)), 0) << w << " px: something runs off the right edge";
  }
  fs::remove_all(dir);
}

TEST(Cli, ReferencePathTracesRhoMuDeltaAndComposite) {
  const fs::path scene = writeScene("ref_sphere.json", R"({"objects": [{"model": ")" + kModels +
                                                           R"(sphere.ply", "translate": [0, 0, 0.06], "scale": 0.06}],
      "lights": "manifest"})");
  const fs::path out = fs::temp_directory_path() / ("mrgi_cli_reference_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const std::string base = "reference " + session().string() + " --scene " + scene.string() + " --pose ground-truth ";
  const Result r = runMrgi(base + "--frame 1 --spp 8 --bounces 2 --out " + out.string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const cv::Mat rho = cv::imread((out / "rho.exr").string(), cv::IMREAD_UNCHANGED);
  const cv::Mat mu = cv::imread((out / "mu.exr").string(), cv::IMREAD_UNCHANGED);
  const cv::Mat delta = cv::imread((out / "delta.exr").string(), cv::IMREAD_UNCHANGED);
  const cv::Mat mask = cv::imread((out / "mask.png").string(), cv::IMREAD_UNCHANGED);
  const cv::Mat composite = cv::imread((out / "composite.png").string());
  ASSERT_EQ(rho.type(), CV_32FC3);
  ASSERT_EQ(delta.size(), cv::Size(160, 120));
  ASSERT_EQ(mask.type(), CV_8UC1);
  EXPECT_GT(cv::countNonZero(mask), 50);  // the sphere
  // delta = ρ − μ on real pixels, ρ on virtual ones; the shadow is negative, and far from the object most
  // real pixels are exactly unchanged (ρ and μ share their random numbers).
  cv::Mat expect = rho - mu;
  rho.copyTo(expect, mask);
  EXPECT_LT(cv::norm(expect, delta, cv::NORM_INF), 1e-6);
  double lo, hi;
  cv::minMaxLoc(delta.reshape(1), &lo, &hi);
  EXPECT_LT(lo, -0.01);
  cv::Mat realZero;
  cv::cvtColor(cv::abs(delta), realZero, cv::COLOR_BGR2GRAY);
  EXPECT_GT(cv::countNonZero((realZero == 0) & (mask == 0)), 160 * 120 / 2);
  // Composite: the camera image wherever delta is exactly 0.
  const cv::Mat colour = cv::imread((session() / "colour/000001.png").string());
  cv::Mat diff;
  cv::absdiff(composite, colour, diff);
  cv::cvtColor(diff, diff, cv::COLOR_BGR2GRAY);
  EXPECT_EQ(cv::countNonZero((diff > 0) & (realZero == 0) & (mask == 0)), 0);
  const auto info = nlohmann::json::parse(slurp(out / "reference.json"));
  EXPECT_EQ(info["spp"], 8);
  EXPECT_EQ(info["frame"], 1);
  // Deterministic: the same seed gives the same images; the folder is recognised as ours.
  const Result again = runMrgi(base + "--frame 1 --spp 8 --bounces 2 --out " + out.string());
  ASSERT_EQ(again.exitCode, 0) << again.err;
  EXPECT_EQ(cv::norm(rho, cv::imread((out / "rho.exr").string(), cv::IMREAD_UNCHANGED), cv::NORM_INF), 0.0);
  expectOneLineError(runMrgi(base + "--frame 7 --out " + out.string()), "has no frame 7");
  expectOneLineError(runMrgi(base + "--out " + (fs::path(MRGI_SOURCE_DIR) / "recordings").string()),
                     "refusing to overwrite");
  fs::remove_all(out);
}

TEST(Cli, SynthLetsTheSunInThroughAWindow) {
  // --window-sun: a window in the right wall and the sun through it onto the table, beside the lamp; the manifest
  // lists the sun as the directional light it is, and the table shows its patch: the frame is brighter where the
  // sun reaches than the same frame without it.
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_window_sun_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string common = " --render raycast --frames 1 --fisheye-every 0 --width 160 --height 120 --out ";
  ASSERT_EQ(runMrgi("synth --window-sun" + common + (dir / "sun").string()).exitCode, 0);
  ASSERT_EQ(runMrgi("synth" + common + (dir / "lamp").string()).exitCode, 0);
  const auto manifest = nlohmann::json::parse(slurp(dir / "sun" / "manifest.json"));
  const auto& lights = manifest["ground_truth"]["lights"];
  ASSERT_EQ(lights.size(), 2u);
  EXPECT_EQ(lights[0]["type"], "point");
  EXPECT_EQ(lights[1]["type"], "directional");
  EXPECT_NEAR(lights[1]["irradiance_w_m2"][0].get<double>(), 14.0, 1e-6);
  EXPECT_LT(lights[1]["direction"][0].get<double>(), -0.9);  // travelling from the window (x = +2 m) inwards
  const cv::Mat sun = cv::imread((dir / "sun" / "colour" / "000000.png").string(), cv::IMREAD_GRAYSCALE),
                lamp = cv::imread((dir / "lamp" / "colour" / "000000.png").string(), cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(sun.empty() || lamp.empty());
  cv::Mat brighter;
  cv::subtract(sun, lamp, brighter);
  EXPECT_GT(cv::countNonZero(brighter > 40), static_cast<int>(sun.total() / 20));  // the sunlit patch
  expectOneLineError(runMrgi("synth --window-sun --environment x.exr --out " + (dir / "x").string()), "--window-sun");
  fs::remove_all(dir);
}

TEST(Cli, ARoomFusedAsTheFramesComeFindsTheSunThroughItsWindow) {
  // Replay fusing the room as the frames come (as the live window does with a sensor), lit from that room: the sun
  // the camera never sees is searched for as the room grows (a quarter more of it each time; measured from its
  // direction at the refreshes between), as a room fused before the first frame is searched once.
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_fused_sun_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  ASSERT_EQ(runMrgi("synth --window-sun --render raycast --frames 4 --scan 40 --fisheye-every 0 --width 160 --height "
                    "120 --out " +
                    (dir / "ws").string())
                .exitCode,
            0);
  nlohmann::json scene;
  scene["objects"] = {{{"model", (fs::path(MRGI_SOURCE_DIR) / "recordings/models/sphere.ply").string()},
                       {"translate", {0.0, 0.0, 0.06}},
                       {"scale", 0.06}}};
  scene["lights"] = "room";
  std::ofstream(dir / "room.json") << scene.dump();
  const Result r = runMrgi("replay " + (dir / "ws").string() + " --scene " + (dir / "room.json").string() +
                           " --pose ground-truth --fuse-room --fuse-refresh 10 --out " + (dir / "r").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("the room shows a light the camera never saw"), std::string::npos) << r.err;
  const auto summary = nlohmann::json::parse(slurp(dir / "r" / "summary.json"));
  int found = 0;
  for (const auto& f : summary["per_frame"]) {
    if (!f.contains("room") || !f["room"].contains("lights") || f["room"]["lights"]["distant"].is_null()) continue;
    ++found;
    const auto& towards = f["room"]["lights"]["distant"]["towards"];
    // The sun shines in through the window in the right wall (+x in the marker frame), 21 degrees up.
    EXPECT_GT(towards[0].get<double>(), 0.9) << towards;
    EXPECT_NEAR(towards[2].get<double>(), 0.36, 0.05) << towards;
  }
  // The window comes into view late in the look-around: the room refreshed at frame 40 shows it.
  EXPECT_GE(found, 1) << "the sun is not found from the room fused as the frames come";
  fs::remove_all(dir);
}

TEST(Cli, TrackPixelsMeasuresOursAndOpen3DsOdometryOnTheRealDeskAndRefusesAFolderWithoutTags) {
  // The harness on the first frames of the real ViSP desk: every row tracked, the board's own poses at its floor.
  const std::string visp = std::string(MRGI_SHARED_DATA) + "/rgbd-visp-apriltag";
  const Result r = runMrgi("track-pixels " + visp + " --frames 4 --json");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["rows"].size(), 12u);
  for (const auto& row : j["rows"]) {
    EXPECT_EQ(row["tracked"], 3) << row["poses"];
    EXPECT_LT(row["rms_px"].get<double>(), 3.0) << row["poses"];
  }
  EXPECT_LT(j["rows"][0]["rms_px"].get<double>(), 0.3);
  // A folder that is not a ViSP tag sequence: one line naming what it lacks.
  const std::string icl = std::string(MRGI_SHARED_DATA) + "/rgbd-open3d-iclnuim";
  expectOneLineError(runMrgi("track-pixels " + icl), icl + "/cam.json");
}

TEST(Cli, CompareHoldsAReplayAgainstTheReferenceComposites) {
  // mrgi compare on a session with path-traced references (their shadows; ray-cast ones have none): a "replay" whose
  // frames are the references themselves measures brightness 1, L1 0, the brightest side where it is and the whole
  // shadow; one whose frames are the bare frames measures no shadow; a real replay lit by the true lights measures the
  // technique's own error, finite.
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_compare_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string scene = (fs::path(MRGI_SOURCE_DIR) / "recordings/scenes/tabletop.json").string();
  ASSERT_EQ(runMrgi("synth --spp 8 --frames 2 --fisheye-every 0 --width 160 --height 120 --scene " + scene + " --out " +
                    (dir / "s").string())
                .exitCode,
            0);
  const auto fake = [&](const std::string& name, const std::string& pattern) {
    fs::create_directories(dir / name);
    for (int i = 0; i < 2; ++i) {
      char from[64], to[64];
      std::snprintf(from, sizeof from, pattern.c_str(), i);
      std::snprintf(to, sizeof to, "frame_%04d.png", i);
      fs::copy_file(dir / "s" / from, dir / name / to);
    }
    std::ofstream(dir / name / "summary.json")
        << R"({"per_frame": [{"index": 0, "frame": 0}, {"index": 1, "frame": 1}]})";
    return (dir / name).string();
  };
  const auto judged = [&](const std::string& replay) {
    const Result r = runMrgi("compare " + (dir / "s").string() + " " + replay + " --json");
    EXPECT_EQ(r.exitCode, 0) << r.err;
    return nlohmann::json::parse(r.out);
  };
  const auto same = judged(fake("same", "reference/%06d.png"));
  ASSERT_EQ(same["frames"].size(), 2u);
  for (const auto& f : same["frames"]) {
    EXPECT_GT(f["object_pixels"].get<int>(), 50);
    EXPECT_DOUBLE_EQ(f["brightness"].get<double>(), 1.0);
    EXPECT_DOUBLE_EQ(f["relative_l1"].get<double>(), 0.0);
    EXPECT_DOUBLE_EQ(f["brightest_side_radii"].get<double>(), 0.0);
    EXPECT_GT(f["reference_shadow"].get<double>(), 1.0);  // the sphere's shadow on the table
    EXPECT_DOUBLE_EQ(f["shadow_energy"].get<double>(), 1.0);
  }
  const auto bare = judged(fake("bare", "colour/%06d.png"));
  for (const auto& f : bare["frames"]) EXPECT_DOUBLE_EQ(f["shadow_energy"].get<double>(), 0.0);
  const Result rp = runMrgi("replay " + (dir / "s").string() + " --scene " + scene + " --pose ground-truth --out " +
                            (dir / "r").string());
  ASSERT_EQ(rp.exitCode, 0) << rp.err;
  const auto real = judged((dir / "r").string());
  ASSERT_EQ(real["frames"].size(), 2u);
  for (const char* m : {"brightness", "relative_l1", "brightest_side_radii", "shadow_energy"}) {
    EXPECT_TRUE(std::isfinite(real[m]["mean"].get<double>())) << m;
    EXPECT_GE(real[m]["interval_95"].get<double>(), 0.0) << m;
  }
  EXPECT_GT(real["brightness"]["mean"].get<double>(), 0.5);
  EXPECT_LT(real["brightness"]["mean"].get<double>(), 1.5);
  // A table without --json: a row per frame and the means.
  const Result table = runMrgi("compare " + (dir / "s").string() + " " + (dir / "r").string());
  EXPECT_NE(table.out.find("| mean, 95 % interval |"), std::string::npos) << table.out;
  expectOneLineError(runMrgi("compare " + (dir / "s").string() + " " + (dir / "nope").string()), "summary.json");
  fs::remove_all(dir);
}

TEST(Cli, SynthMovesTheLightAndReplayRelightsEachFrame) {
  const fs::path out = fs::temp_directory_path() / ("mrgi_cli_synth_light_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const Result r =
      runMrgi("synth --out " + out.string() +
              " --frames 3 --width 96 --height 72 --render raycast --fisheye-every 0 --static-camera --move-light");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto manifest = nlohmann::json::parse(slurp(out / "manifest.json"));
  const auto start = manifest["ground_truth"]["lights"][0]["position"];
  std::istringstream index(slurp(out / "frames.jsonl"));
  std::string line;
  std::vector<cv::Vec3d> at;
  while (std::getline(index, line)) {
    const auto j = nlohmann::json::parse(line);
    ASSERT_TRUE(j.contains("lights")) << line;
    const auto p = j["lights"][0]["position"];
    at.push_back({p[0].get<double>(), p[1].get<double>(), p[2].get<double>()});
    EXPECT_EQ(j["lights"][0]["radius_m"], manifest["ground_truth"]["lights"][0]["radius_m"]);
  }
  ASSERT_EQ(at.size(), 3u);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(at[0][c], start[c].get<double>(), 1e-6);  // frame 0: the manifest's lamp
  // A third of the way round the vertical axis through the tag, at the same height.
  const double a0 = std::atan2(at[0][2], at[0][0]), a2 = std::atan2(at[2][2], at[2][0]);
  EXPECT_NEAR(std::remainder(a2 - a0, 2 * CV_PI), 2 * CV_PI / 3, 1e-6);
  EXPECT_NEAR(at[2][1], at[0][1], 1e-6);
  // The camera stays: the images change by the light alone (the box's shadow moves).
  const cv::Mat f0 = cv::imread((out / "colour/000000.png").string()),
                f2 = cv::imread((out / "colour/000002.png").string());
  EXPECT_GT(cv::norm(f0, f2, cv::NORM_L1) / static_cast<double>(f0.total()), 3.0);

  // Replay with the session's lights: each frame's own, with precomputed illuminance composition on the object.
  const fs::path scene = writeScene("moving_light.json", R"({"objects": [{"model": ")" + kModels +
                                                             R"(sphere.ply", "translate": [0, 0, 0.06], "scale": 0.06}],
                                                             "lights": "manifest", "technique": "imperfect-volumes+pic",
                                                             "pic": {"surfels": 512, "grid": 3, "links": 32, "receivers": 32}})");
  const fs::path replay = out.string() + "_replay";
  fs::remove_all(replay);
  const Result rr = runMrgi("replay " + out.string() + " --scene " + scene.string() + " --out " + replay.string() +
                            " --pose ground-truth");
  ASSERT_EQ(rr.exitCode, 0) << rr.err;
  const auto summary = nlohmann::json::parse(slurp(replay / "summary.json"));
  ASSERT_EQ(summary["per_frame"].size(), 3u);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(summary["per_frame"][i]["lights_from_frame"], 1) << i;
  // Not with the outdoor environment (no lamp to move).
  const Result bad =
      runMrgi("synth --out " + out.string() + "_env --frames 1 --width 32 --height 24 --move-light --environment " +
              std::string(MRGI_SHARED_DATA) + "/hdr-blender-world/forest.exr");
  EXPECT_NE(bad.exitCode, 0);
  EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << bad.err;
  EXPECT_NE(bad.err.find("--move-light needs the room's lamp"), std::string::npos) << bad.err;
  fs::remove_all(out.string() + "_env");
  fs::remove_all(out);
  fs::remove_all(replay);
}

TEST(Cli, SynthPathTracesFramesAndTheirReferenceComposites) {
  const fs::path scene =
      writeScene("synth_ref.json", R"({"objects": [{"model": ")" + kModels +
                                       R"(sphere.ply", "translate": [0, 0, 0.06], "scale": 0.06}]})");
  const fs::path out = fs::temp_directory_path() / ("mrgi_cli_synth_pt_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const Result r = runMrgi("synth --out " + out.string() +
                           " --frames 2 --width 96 --height 72 --spp 8 --bounces 2"
                           " --fisheye-every 0 --scene " +
                           scene.string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto manifest = nlohmann::json::parse(slurp(out / "manifest.json"));
  EXPECT_NE(manifest["ground_truth"]["scene"]["generator"].get<std::string>().find("path traced"), std::string::npos);
  // Named relative to the session directory.
  EXPECT_TRUE(fs::equivalent(out / manifest["ground_truth"]["reference"]["scene"].get<std::string>(), scene));
  for (int i = 0; i < 2; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "%06d.png", i);
    const cv::Mat frame = cv::imread((out / "colour" / name).string());
    const cv::Mat ref = cv::imread((out / "reference" / name).string());
    std::snprintf(name, sizeof name, "mask_%06d.png", i);
    const cv::Mat mask = cv::imread((out / "reference" / name).string(), cv::IMREAD_UNCHANGED);
    std::snprintf(name, sizeof name, "delta_%06d.exr", i);
    const cv::Mat delta = cv::imread((out / "reference" / name).string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(frame.empty());
    ASSERT_EQ(ref.size(), frame.size());
    ASSERT_EQ(delta.type(), CV_32FC3);
    EXPECT_GT(cv::countNonZero(mask), 20);  // the sphere on the tag
    // Same seed and sensor noise: far from the sphere the reference equals the camera frame exactly.
    cv::Mat diff;
    cv::absdiff(frame, ref, diff);
    cv::cvtColor(diff, diff, cv::COLOR_BGR2GRAY);
    EXPECT_GT(cv::countNonZero(diff == 0), static_cast<int>(frame.total() / 2));
    EXPECT_GT(cv::countNonZero((diff > 20) & (mask == 255)), 10);  // the sphere itself
    double lo;
    cv::minMaxLoc(delta.reshape(1), &lo, nullptr);
    EXPECT_LT(lo, 0.0);  // its shadow
  }
  // The bench measures the whole pipeline against these true references, per session and averaged over sessions.
  const fs::path json = out.string() + "_bench.json";
  const Result b =
      runMrgi("bench --quick --technique dlpv --session " + out.string() + " --session " + session().string() +
              " --scene " + scene.string() + " --frames 2 --ref-frames 1 --ref-spp 2 --json " + json.string());
  ASSERT_EQ(b.exitCode, 0) << b.err;
  const auto doc = nlohmann::json::parse(slurp(json));
  ASSERT_EQ(doc["references"].size(), 2u);
  EXPECT_EQ(doc["references"][0]["true_reference_frames"], 2);
  EXPECT_FALSE(doc["references"][1].contains("true_reference_frames"));  // a session without true references
  for (const auto& ref : doc["references"]) {  // marker tracking against the true camera poses, every frame
    const auto& m = ref["marker_pose_error"];
    EXPECT_EQ(m["frames"].get<int>() + m["lost"].get<int>(), 2);
    EXPECT_GE(m["position_mm_max"].get<double>(), m["position_mm_mean"].get<double>());
  }
  for (const auto& rec : doc["records"]) {
    ASSERT_EQ(rec["sessions"].size(), 2u);
    const auto& whole = rec["sessions"][0]["whole_pipeline"];
    EXPECT_EQ(whole["frames"], 2);
    for (const char* key : {"rel_error_delta", "rel_error_virtual"}) {
      EXPECT_GT(whole[key].get<double>(), 0.0) << key;
      EXPECT_LT(whole[key].get<double>(), 2.0) << key;
    }
    EXPECT_GT(whole["ssim"].get<double>(), 0.5);
    EXPECT_FALSE(rec["sessions"][1].contains("whole_pipeline"));
    const double mean = 0.5 * (rec["sessions"][0]["rel_error_virtual"].get<double>() +
                               rec["sessions"][1]["rel_error_virtual"].get<double>());
    EXPECT_NEAR(rec["rel_error_virtual"].get<double>(), mean, 1e-12);
  }
  fs::remove(json);
  fs::remove_all(out);
}

TEST(Cli, ReplaySkipsStagesWhoseInputsDidNotChange) {
  // A static camera: only the sensor noise changes from frame to frame.
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_static_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  Result r = runMrgi("synth --out " + (dir / "s").string() +
                     " --frames 3 --width 96 --height 72 --render raycast"
                     " --fisheye-every 0 --static-camera");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const fs::path scene =
      writeScene("static_sphere.json", R"({"objects": [{"model": ")" + kModels +
                                           R"(sphere.ply", "translate": [0, 0, 0.06], "scale": 0.06}],
      "lights": "manifest", "lpv": {"resolution": 8, "steps": 4, "rsm_size": 64}})");
  auto replay = [&](const std::string& out, const std::string& extra) {
    return runMrgi("replay " + (dir / "s").string() + " --scene " + scene.string() +
                   " --per-frame-mesh --pose ground-truth --dump-delta --out " + (dir / out).string() + extra);
  };
  auto exr = [&](const std::string& out, int i) {
    return cv::imread((dir / out / ("delta_000" + std::to_string(i) + ".exr")).string(), cv::IMREAD_UNCHANGED);
  };
  r = replay("reuse", "");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  auto summary = nlohmann::json::parse(slurp(dir / "reuse" / "summary.json"));
  for (const char* stage : {"depth_filter", "normals", "albedo", "mesh", "gbuffer", "rsm", "dlpv", "shade"})
    EXPECT_EQ(summary["skipped_frames"].value(stage, 0), 2) << stage;
  EXPECT_FALSE(summary["per_frame"][0].contains("skipped"));
  // The kept lighting is exactly the first frame's; the composites still follow the camera (new noise).
  ASSERT_FALSE(exr("reuse", 0).empty());
  EXPECT_EQ(cv::norm(exr("reuse", 0), exr("reuse", 2), cv::NORM_INF), 0.0);
  const cv::Mat f0 = cv::imread((dir / "reuse" / "frame_0000.png").string()),
                f2 = cv::imread((dir / "reuse" / "frame_0002.png").string());
  EXPECT_GT(cv::norm(f0, f2, cv::NORM_INF), 0.0);
  // --recompute-all runs everything: the noisy depth changes the delta a little on every frame.
  r = replay("all", " --recompute-all");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  summary = nlohmann::json::parse(slurp(dir / "all" / "summary.json"));
  EXPECT_TRUE(summary["skipped_frames"].empty());
  EXPECT_GT(cv::norm(exr("all", 0), exr("all", 2), cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(exr("all", 0), exr("reuse", 0), cv::NORM_INF), 0.0);  // the first frame is the same either way
  fs::remove_all(dir);
}

/// Starts mrgi in the background; returns its pid (stdout/stderr to `log`).
pid_t spawnMrgi(const std::string& args, const fs::path& log) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    const std::string cmd = "exec " + std::string(MRGI_BINARY) + " " + args + " >" + log.string() + " 2>&1";
    ::execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    std::_Exit(127);
  }
  return pid;
}

/// Waits (up to `seconds`) for a file to appear.
bool waitForFile(const fs::path& p, double seconds) {
  for (int i = 0; i < static_cast<int>(seconds * 20); ++i) {
    if (fs::exists(p)) return true;
    ::usleep(50000);
  }
  return false;
}

// The bundled scene with four more lights of the room (two spots aimed away, two dim lamps across it): only
// the objects' lamp is rendered, and each frame names the lights left out; with light_cutoff 0 none is.
TEST(Cli, ReplayNamesTheLightsTooDimAtTheObjectsToRender) {
  const fs::path out = fs::temp_directory_path() / ("mrgi_cli_lamps_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const std::string rec = std::string(MRGI_SOURCE_DIR) + "/recordings/tabletop-pt";
  const std::string lamps = std::string(MRGI_SOURCE_DIR) + "/recordings/scenes/tabletop-lamps.json";
  const Result r = runMrgi("replay " + rec + " --scene " + lamps + " --frames 2 --out " + out.string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto summary = nlohmann::json::parse(slurp(out / "summary.json"));
  for (int i = 0; i < 2; ++i) EXPECT_EQ(summary["per_frame"][i]["lights_skipped"], nlohmann::json({1, 2, 3, 4})) << i;
  EXPECT_EQ(summary["knobs"]["frame"]["light_cutoff"], 0.01);
  // The same scene with every light rendered.
  auto scene = nlohmann::json::parse(slurp(lamps));
  for (auto& o : scene["objects"]) o["model"] = std::string(MRGI_SOURCE_DIR) + "/recordings/models/sphere.ply";
  scene["frame"] = {{"light_cutoff", 0}};
  const fs::path all = out.string() + "_all.json";
  std::ofstream(all) << scene.dump();
  const fs::path outAll = out.string() + "_all";
  fs::remove_all(outAll);
  const Result a = runMrgi("replay " + rec + " --scene " + all.string() + " --frames 1 --out " + outAll.string());
  ASSERT_EQ(a.exitCode, 0) << a.err;
  EXPECT_FALSE(nlohmann::json::parse(slurp(outAll / "summary.json"))["per_frame"][0].contains("lights_skipped"));
  fs::remove_all(out);
  fs::remove_all(outAll);
  fs::remove(all);
}

TEST(Cli, CtrlCDuringReplayLeavesCompleteFramesVideoAndSummary) {
  const fs::path out = fs::temp_directory_path() / ("mrgi_cli_interrupt_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const fs::path rec = fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-pt";
  const pid_t pid = spawnMrgi("replay " + rec.string() + " --scene " + MRGI_SOURCE_DIR +
                                  "/recordings/scenes/tabletop.json"
                                  " --recompute-all --out " +
                                  out.string(),
                              out.string() + ".log");
  ASSERT_TRUE(waitForFile(out / "frame_0000.png", 120));
  ::kill(pid, SIGINT);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status)) << slurp(out.string() + ".log");
  EXPECT_EQ(WEXITSTATUS(status), 130);
  const auto summary = nlohmann::json::parse(slurp(out / "summary.json"));
  EXPECT_TRUE(summary["interrupted"].get<bool>());
  const int frames = summary["frames"];
  EXPECT_GE(frames, 1);
  EXPECT_LT(frames, 12);  // stopped early
  int pngs = 0;
  for (const auto& e : fs::directory_iterator(out)) {
    const std::string name = e.path().filename().string();
    EXPECT_EQ(name.find("partial"), std::string::npos) << name;  // nothing half written
    if (name.rfind("frame_", 0) == 0) {
      ++pngs;
      EXPECT_FALSE(cv::imread(e.path().string()).empty()) << name;
    }
  }
  EXPECT_EQ(pngs, frames);
  EXPECT_EQ(summary["video"]["frames"], frames);
  cv::VideoCapture video((out / "replay.mp4").string());
  ASSERT_TRUE(video.isOpened());
  int decoded = 0;
  for (cv::Mat f; video.read(f);) {
    if (decoded == 0) {  // the video shows what the PNG shows (MPEG-4 loses a little)
      const cv::Mat png = cv::imread((out / "frame_0000.png").string());
      ASSERT_EQ(f.size(), png.size());
      EXPECT_LT(cv::norm(f, png, cv::NORM_L1) / static_cast<double>(png.total() * 3), 6.0);
    }
    ++decoded;
  }
  EXPECT_EQ(decoded, frames);
  fs::remove_all(out);
  fs::remove(out.string() + ".log");
}

TEST(Cli, LiveAndRecordWithoutASensorSayWhatToDoInOneLine) {
  expectOneLineError(runMrgi("live --device openni2://no-such-device"), "--source");
  const fs::path out = fs::temp_directory_path() / ("mrgi_cli_rec_nodev_" + std::to_string(::getpid()));
  expectOneLineError(runMrgi("record --device openni2://no-such-device --out " + out.string()), "no depth sensor");
  EXPECT_FALSE(fs::exists(out));  // nothing half made
  expectOneLineError(runMrgi("live --source " + session().string() + " --screenshot x.png"),
                     "--screenshot needs --frames");
  if (!std::getenv("DISPLAY"))  // headless (CI): the live window cannot open, and says what runs headless
    expectOneLineError(runMrgi("live --source " + session().string() + " --frames 1"), "mrgi replay runs headless");
}

TEST(Cli, RecordCopiesFramesAndTheFisheyeCalibrationIntoANewSession) {
  const fs::path out = fs::temp_directory_path() / ("mrgi_cli_record_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const fs::path rec = fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-synth";
  const Result r = runMrgi("record --source " + rec.string() + " --frames 3 --out " + out.string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto summary = nlohmann::json::parse(r.out);
  EXPECT_EQ(summary["frames"], 3);
  EXPECT_GE(summary["fisheye_frames"].get<int>(), 1);
  const auto info = nlohmann::json::parse(runMrgi("info " + out.string()).out);
  EXPECT_EQ(info["frame_count"], 3);
  const auto manifest = nlohmann::json::parse(slurp(out / "manifest.json"));
  EXPECT_TRUE(manifest.contains("fisheye"));
  for (const char* name : {"000000.png", "000002.png"}) {
    const cv::Mat a = cv::imread((rec / "colour" / name).string()), b = cv::imread((out / "colour" / name).string());
    ASSERT_FALSE(b.empty()) << name;
    EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0) << name;
  }
  // Never overwrites: a recording there (a killed one keeps its complete frames) is said as such.
  expectOneLineError(runMrgi("record --source " + rec.string() + " --frames 1 --out " + out.string()),
                     out.string() + ": already holds a recording of 3 frames");
  fs::remove_all(out);
}

TEST(Cli, RealOniRecordingReplaysAndRecordsIntoASessionThatReadsBack) {
  // OpenNI 1.x Kinect recording: colour field of view 0, recorded mirrored (../shared/data/oni-kinect-3dj).
  const std::string oni = std::string(MRGI_SHARED_DATA) + "/oni-kinect-3dj/test.oni";
  const Result infoRun = runMrgi("info " + oni);
  const auto info = nlohmann::json::parse(infoRun.out);
  ASSERT_TRUE(info["colour_intrinsics"]["fx"].is_number()) << info.dump();
  // The colour stream's missing field of view is said once per command, info included, as a note.
  auto timesSaid = [](const std::string& err) {
    size_t n = 0;
    for (size_t at = err.find("using the depth stream's"); at != std::string::npos;
         at = err.find("using the depth stream's", at + 1))
      ++n;
    return n;
  };
  EXPECT_EQ(timesSaid(infoRun.err), 1u) << infoRun.err;
  EXPECT_NE(infoRun.err.find("note: " + oni + ": the colour stream reports no field of view"), std::string::npos)
      << infoRun.err;
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_oni_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  // Replay with no scene reproduces its colour.
  Result r = runMrgi("replay " + oni + " --frames 2 --mp4 \"\" --out " + (dir / "replay").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(timesSaid(r.err), 1u) << r.err;
  // record writes a session that info and replay open, frame for frame the same colour.
  r = runMrgi("record --source " + oni + " --frames 3 --out " + (dir / "session").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const Result i = runMrgi("info " + (dir / "session").string());
  ASSERT_EQ(i.exitCode, 0) << i.err;
  EXPECT_EQ(nlohmann::json::parse(i.out)["frame_count"], 3);
  r = runMrgi("replay " + (dir / "session").string() + " --mp4 \"\" --out " + (dir / "replay2").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  for (const char* name : {"frame_0000.png", "frame_0001.png"}) {
    const cv::Mat a = cv::imread((dir / "replay" / name).string()), b = cv::imread((dir / "replay2" / name).string());
    ASSERT_FALSE(a.empty() || b.empty()) << name;
    EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0) << name;
  }
  fs::remove_all(dir);
}

TEST(Cli, AnObjectInsertedIntoARecordingWithoutAMarkerStaysOnItsFloorInEveryReplayedFrame) {
  // The mirrored Kinect recording holds no tag: its first frame founds the world (z up along the floor, the
  // dominant plane below the view's centre), insert --at --snap rests a sphere on that floor and the scene
  // records the world; replay tracks every frame by odometry from there and draws the sphere in each.
  const std::string oni = std::string(MRGI_SHARED_DATA) + "/oni-kinect-3dj/test.oni";
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_markerless_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string base =
      R"({"lights": [{"type": "directional", "direction": [0.3, 0.2, -1.0], "irradiance": [2.5, 2.4, 2.2]}],
                               "ambient_radiance": [0.1, 0.1, 0.1], "technique": "kinect-val"})";
  std::ofstream(dir / "base.json") << base;
  const std::string sphere = (fs::path(MRGI_SOURCE_DIR) / "recordings/models/sphere.ply").string();
  Result r =
      runMrgi("insert --session " + oni + " --model " + sphere + " --scale 0.1 --scene " +
              (dir / "base.json").string() + " --save " + (dir / "scene.json").string() + " --at 320,240 --snap");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  // insert opens the recording three times (the frame, the room, the world) and says its note once.
  EXPECT_EQ(r.err.find("using the depth stream's"), r.err.rfind("using the depth stream's")) << r.err;
  const auto report = nlohmann::json::parse(r.out);
  EXPECT_EQ(report["pose"]["by"], "first-frame");
  // Resting on the floor: the support plane is the world's z = 0 and the unit sphere of radius 0.1 sits on it.
  EXPECT_GT(report["plane"]["normal"][2].get<double>(), 0.999);
  EXPECT_NEAR(report["plane"]["d"].get<double>(), 0.0, 1e-3);
  EXPECT_NEAR(report["translate"][2].get<double>(), 0.1, 2e-3);
  const auto scene = nlohmann::json::parse(slurp(dir / "scene.json"));
  ASSERT_EQ(scene["world"]["first_frame_T_world_camera"].size(), 16u);
  // The same world without the object: the background each frame would show.
  auto empty = scene;
  empty["objects"] = nlohmann::json::array();
  std::ofstream(dir / "empty.json") << empty.dump();
  for (const char* name : {"scene", "empty"}) {
    r = runMrgi("replay " + oni + " --scene " + (dir / (std::string(name) + ".json")).string() + " --mp4 \"\" --out " +
                (dir / name).string());
    ASSERT_EQ(r.exitCode, 0) << r.err;
  }
  const auto summary = nlohmann::json::parse(slurp(dir / "scene" / "summary.json"));
  ASSERT_EQ(summary["per_frame"].size(), 12u);
  EXPECT_EQ(summary["frames_with_pose"], 12);
  EXPECT_EQ(summary["per_frame"][0]["pose"]["by"], "first-frame");
  for (size_t f = 0; f < 12; ++f) {
    const auto& pose = summary["per_frame"][f]["pose"];
    EXPECT_EQ(pose["status"], "tracked") << f;
    char name[32];
    std::snprintf(name, sizeof name, "frame_%04zu.png", f);
    const cv::Mat with = cv::imread((dir / "scene" / name).string()),
                  without = cv::imread((dir / "empty" / name).string());
    ASSERT_FALSE(with.empty() || without.empty()) << name;
    // The sphere covers about 40 x 40 pixels near the bottom centre in every frame, and stays there.
    cv::Mat diff;
    cv::absdiff(with, without, diff);
    cv::cvtColor(diff, diff, cv::COLOR_BGR2GRAY);
    const cv::Mat changed = diff > 30;
    EXPECT_GT(cv::countNonZero(changed), 800) << name;
    const cv::Moments m = cv::moments(changed, true);
    if (m.m00 > 0) {
      EXPECT_NEAR(m.m10 / m.m00, 302, 15) << name;
      EXPECT_NEAR(m.m01 / m.m00, 425, 15) << name;
    }
  }
  fs::remove_all(dir);
}

TEST(Cli, ABareOniRecordingIsRoomedAndLitFromItsRoom) {
  // The marker-less .oni could not be roomed ("no frame has a trusted camera pose (0 lost, 0 held)") nor placed
  // in with its lights left to the room ("0 of 0 posed"): each read the recording again while an opening of it
  // was held, and OpenNI2 gave the second reader the first one's player.
  const std::string oni = std::string(MRGI_SHARED_DATA) + "/oni-kinect-3dj/test.oni";
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_bare_oni_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  Result r = runMrgi("room " + oni + " --out " + (dir / "room").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir / "room" / "room.ply"));
  const std::string sphere = (fs::path(MRGI_SOURCE_DIR) / "recordings/models/sphere.ply").string();
  r = runMrgi("insert --session " + oni + " --model " + sphere + " --scale 0.1 --at 260,450 --snap --save " +
              (dir / "scene.json").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(slurp(dir / "scene.json"))["lights"], "auto");
  // A pixel a few pixels from depth takes the nearest one with depth, in one note; one far from any fails.
  r = runMrgi("insert --session " + oni + " --model " + sphere + " --scale 0.1 --at 320,38 --save " +
              (dir / "near.json").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("note: frame 0: no depth at pixel 320,38; placed at 320,41, the nearest pixel with depth\n"),
            std::string::npos)
      << r.err;
  r = runMrgi("insert --session " + oni + " --model " + sphere + " --scale 0.1 --at 320,20 --save " +
              (dir / "far.json").string());
  EXPECT_FALSE(r.signalled);
  EXPECT_EQ(r.exitCode, 1) << r.err;
  // The recording's notes (its calibration, its lights), then the one error line.
  EXPECT_EQ(lines(r.err), 3) << r.err;
  EXPECT_EQ(r.err.find("mrgi: "), r.err.rfind("\nmrgi: ") + 1) << r.err;
  EXPECT_NE(r.err.find(oni + ": frame 0: no depth at pixel 320,20 (the nearest pixel with depth is 320,41"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(dir / "far.json"));
  fs::remove_all(dir);
}

TEST(Cli, InsertsPreviewAndReplayLightABareRecordingAlike) {
  // "lights": "auto" on a recording without lights: insert's preview lit frame 0 by the room of every frame,
  // replay by the room fused up to that frame (frame 0: what frame 0 alone saw): a shaded sphere with a shadow in
  // the preview, a flat disc in replay. Both now light it by the room of the whole recording, fused first.
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_auto_alike_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string icl = std::string(MRGI_SHARED_DATA) + "/rgbd-open3d-iclnuim";
  const std::string sphere = (fs::path(MRGI_SOURCE_DIR) / "recordings/models/sphere.ply").string();
  const std::string scene = (dir / "icl.json").string();
  Result r = runMrgi("insert --session " + icl + " --model " + sphere + " --scale 0.2 --at 320,400 --snap --save " +
                     scene + " --preview " + (dir / "preview.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  r = runMrgi("replay " + icl + " --scene " + scene + " --frames 1 --mp4 '' --out " + (dir / "replay").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto summary = nlohmann::json::parse(slurp(dir / "replay" / "summary.json"));
  EXPECT_EQ(summary["room"]["fused"], "before the replay, from every frame") << summary["room"].dump();
  EXPECT_EQ(summary["room"]["integrated"], 5);  // every frame of the recording, not only the one replayed
  const cv::Mat preview = cv::imread((dir / "preview.png").string()),
                replayed = cv::imread((dir / "replay" / "frame_0000.png").string());
  ASSERT_FALSE(preview.empty() || replayed.empty());
  cv::Mat diff;
  cv::absdiff(preview, replayed, diff);
  cv::cvtColor(diff, diff, cv::COLOR_BGR2GRAY);
  EXPECT_LT(cv::mean(diff)[0], 0.5);
  EXPECT_GT(cv::countNonZero(diff <= 2) / static_cast<double>(diff.total()), 0.99);
  // --fuse-room still lights each frame by the room fused up to it, as asked.
  r = runMrgi("replay " + icl + " --scene " + scene + " --frames 1 --fuse-room --mp4 '' --out " +
              (dir / "asitcomes").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(slurp(dir / "asitcomes" / "summary.json"))["room"]["fused"], "as the frames came");
  fs::remove_all(dir);
}

TEST(Cli, TrackPrintsHowEveryFrameWasPosedAndRoomSaysWhatItRefused) {
  const std::string synth = (fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-synth").string();
  Result r = runMrgi("track " + synth + " --pose odometry --json");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  std::istringstream printed(r.out);
  int n = 0;
  for (std::string line; std::getline(printed, line); ++n) {
    const auto j = nlohmann::json::parse(line);
    EXPECT_EQ(j["frame"], n);
    EXPECT_EQ(j["status"], "tracked") << line;
    EXPECT_EQ(j["by"], n == 0 ? "marker" : "odometry") << line;
    ASSERT_EQ(j["T_camera_world"].size(), 4u);
    for (const auto& row : j["T_camera_world"]) EXPECT_EQ(row.size(), 4u);
    EXPECT_EQ(j["T_camera_world"][3], nlohmann::json::parse("[0.0, 0.0, 0.0, 1.0]"));
  }
  EXPECT_EQ(n, 20);
  EXPECT_NE(r.err.find("20 frames (--pose odometry): 1 marker, 19 odometry"), std::string::npos) << r.err;
  expectOneLineError(runMrgi("track " + synth + " --pose markr"), "--pose");
  // A frame the sensor lost (no depth, a flat grey image) cannot be posed: `room` refuses it, says so once on
  // stderr and counts it.
  const fs::path dir =
      scratchSession("mrgi_cli_room_tracked_", fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-pt", 3);
  cv::imwrite((dir / "s" / "colour" / "000001.png").string(), cv::Mat(240, 320, CV_8UC3, cv::Scalar(90, 90, 90)));
  cv::imwrite((dir / "s" / "depth" / "000001.png").string(), cv::Mat::zeros(240, 320, CV_16U));
  r = runMrgi("room " + (dir / "s").string() + " --out " + (dir / "room").string() + " --json");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  // Two lines: the refused frame, and how little of the room around the object three orbit frames cover.
  EXPECT_EQ(messageLines(r.err), 2) << r.err;
  EXPECT_NE(r.err.find("1 of 3 frames not fused for their pose (1 lost, 0 held: --pose tracked)"), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("of the directions around the object's place"), std::string::npos) << r.err;
  const auto summary = nlohmann::json::parse(r.out);
  EXPECT_EQ(summary["pose"]["lost"], 1);
  EXPECT_EQ(summary["integrated"], 2);
  fs::remove_all(dir);
}

TEST(Cli, CorruptPngFramesAreOneLineWithNoLibraryMessages) {
  // A recorded session whose frame PNGs are damaged: a CRC error in the image data, a truncated file, a
  // header promising an image of 10^5 x 10^5. libpng's own "libpng error: ..." lines must not precede ours.
  const fs::path dir = scratchSession("mrgi_cli_png_", session(), 2);
  const fs::path png = dir / "s" / "colour" / "000001.png";
  const std::string original = slurp(png);
  ASSERT_GT(original.size(), 1000u);
  auto replayWith = [&](const std::string& bytes) {
    std::ofstream(png, std::ios::binary | std::ios::trunc) << bytes;
    fs::remove_all(dir / "out");
    return runMrgi("replay " + (dir / "s").string() + " --mp4 \"\" --out " + (dir / "out").string());
  };
  std::string crc = original;
  crc[crc.size() / 2] = static_cast<char>(crc[crc.size() / 2] ^ 0x55);  // inside IDAT: its CRC no longer matches
  expectOneLineError(replayWith(crc), png.string());
  // The frame before the damaged one is on disk, complete (its composite was still being read when the
  // damaged frame came).
  EXPECT_EQ(cv::imread((dir / "out" / "frame_0000.png").string()).cols, 160);
  expectOneLineError(replayWith(original.substr(0, original.size() / 2)), png.string());
  std::string huge = original;  // IHDR width and height (big-endian at bytes 16 and 20) = 100000
  for (int at : {16, 20}) {
    huge[at] = 0, huge[at + 1] = 0x01, huge[at + 2] = static_cast<char>(0x86), huge[at + 3] = static_cast<char>(0xA0);
  }
  expectOneLineError(replayWith(huge), png.string());
  // The undamaged file still decodes to the same colour as before.
  const Result ok = replayWith(original);
  EXPECT_EQ(ok.exitCode, 0) << ok.err;
  fs::remove_all(dir);
}

TEST(Cli, FisheyeImagesOfNanNegativeOrNoLightAreRefused) {
  const fs::path dir = scratchSession("mrgi_cli_fisheye_", fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-hdr", 1);
  fs::path exr;
  for (const auto& e : fs::directory_iterator(dir / "s" / "fisheye")) exr = e.path();
  ASSERT_EQ(exr.extension(), ".exr");
  const cv::Mat original = cv::imread(exr.string(), cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(original.empty());
  const std::string scene = (fs::path(MRGI_SOURCE_DIR) / "recordings/scenes/tabletop-fisheye.json").string();
  // NaN is refused by the image reader (every float image), the others by the fisheye's own checks.
  const std::tuple<float, const char*, const char*> cases[] = {
      {std::numeric_limits<float>::quiet_NaN(), ": holds a non-finite value at pixel (0, 0)", ""},
      {-1.f, ": fisheye image", "negative radiance"},
      {0.f, ": fisheye image", "black everywhere"}};
  for (const auto& [value, prefix, message] : cases) {
    cv::imwrite(exr.string(), cv::Mat(original.size(), original.type(), cv::Scalar::all(value)));
    fs::remove_all(dir / "out");
    const Result r =
        runMrgi("replay " + (dir / "s").string() + " --scene " + scene + " --mp4 \"\" --out " + (dir / "out").string());
    expectOneLineError(r, exr.string() + prefix);
    EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
  }
  fs::remove_all(dir);
}

TEST(Cli, AbsurdTimestampsStillGiveAVideoWithNothingOnStderr) {
  // Frames 1e-300 s apart: no usable rate, so the video plays at 30 fps; FFmpeg printed its own error before.
  const fs::path dir = scratchSession("mrgi_cli_ts_", session(), 3);
  std::istringstream lines(slurp(dir / "s" / "frames.jsonl"));
  std::string out, line;
  for (int i = 0; std::getline(lines, line); ++i) {
    auto j = nlohmann::json::parse(line);
    j["t"] = i * 1e-300;
    out += j.dump() + "\n";
  }
  std::ofstream(dir / "s" / "frames.jsonl", std::ios::trunc) << out;
  const Result r = runMrgi("replay " + (dir / "s").string() + " --out " + (dir / "out").string());
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.err, "") << r.err;
  const auto summary = nlohmann::json::parse(slurp(dir / "out" / "summary.json"));
  EXPECT_EQ(summary["video"]["fps"], 30.0);
  EXPECT_EQ(summary["video"]["frames"], 3);
  fs::remove_all(dir);
}

TEST(Cli, ConfigurationsThatCannotFitAreRefusedBeforeAllocating) {
  // 16 lights with 4096² RSMs need about 11 GB: refused in one line naming the scene and the knob, at once.
  std::string lights;
  for (int i = 0; i < 16; ++i)
    lights += std::string(i ? ", " : "") + R"({"type": "point", "position": [0.)" + std::to_string(i) +
              R"(, 0, 1], "intensity": [1, 1, 1]})";
  const fs::path scene =
      writeScene("huge_rsm.json", R"({"objects": [{"model": ")" + kModels + R"(sphere.ply", "scale": 0.06}],
      "lights": [)" + lights + R"(], "frame": {"rsm_size": 4096}})");
  const fs::path out = fs::temp_directory_path() / ("mrgi_cli_huge_" + std::to_string(::getpid()));
  const auto t0 = std::chrono::steady_clock::now();
  expectOneLineError(
      runMrgi("replay " + session().string() + " --scene " + scene.string() + " --frames 1 --out " + out.string()),
      scene.string() + ": frame.rsm_size 4096 with 16 lights");
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 30.0);
  // More lights than the pipeline carries: named too.
  const fs::path many = writeScene("many_lights.json", R"({"objects": [{"model": ")" + kModels +
                                                           R"(sphere.ply", "scale": 0.06}],
      "lights": [)" + lights + ", " + lights + R"(]})");
  expectOneLineError(
      runMrgi("replay " + session().string() + " --scene " + many.string() + " --frames 1 --out " + out.string()),
      many.string() + ": lights: 32 lights, at most 16 are supported");
  fs::remove_all(out);
}

TEST(Cli, CtrlCDuringRecordKeepsEveryCompleteFrame) {
  const fs::path out = fs::temp_directory_path() / ("mrgi_cli_record_int_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const fs::path rec = fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-pt";
  const pid_t pid =
      spawnMrgi("record --source " + rec.string() + " --rate 4 --out " + out.string(), out.string() + ".log");
  ASSERT_TRUE(waitForFile(out / "colour" / "000001.png", 60));
  ::kill(pid, SIGINT);
  int status = 0;
  ::waitpid(pid, &status, 0);
  const std::string log = slurp(out.string() + ".log");
  ASSERT_TRUE(WIFEXITED(status)) << log;
  EXPECT_EQ(WEXITSTATUS(status), 130) << log;
  EXPECT_NE(log.find("\"stopped\":\"interrupted\""), std::string::npos) << log;
  const auto info = nlohmann::json::parse(runMrgi("info " + out.string()).out);
  EXPECT_GE(info["frame_count"].get<int>(), 2);
  EXPECT_LT(info["frame_count"].get<int>(), 12);
  for (const auto& e : fs::recursive_directory_iterator(out))
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
  fs::remove_all(out);
  fs::remove(out.string() + ".log");
}

namespace {
/// The share of the live window's view (its top-left 640 x 480, a 320 x 240 session at 2x) within 2 levels
/// of an image headless replay wrote (0 when that image is missing).
double shareLikeReplay(const cv::Mat& shot, const fs::path& png) {
  cv::Mat expected = cv::imread(png.string()), diff;
  if (expected.empty() || shot.cols < 640 || shot.rows < 480) return 0.0;
  cv::resize(expected, expected, {640, 480}, 0, 0, cv::INTER_NEAREST);
  cv::absdiff(shot(cv::Rect(0, 0, 640, 480)), expected, diff);
  cv::cvtColor(diff, diff, cv::COLOR_BGR2GRAY);
  return cv::countNonZero(diff <= 2) / static_cast<double>(diff.total());
}
}  // namespace

// Needs a display: run by CTest under Xvfb (Window.LiveShowsCompositeUnderXvfb).
TEST(LiveWindow, DISABLED_AMisspeltViewIsOneLineNamingTheFlagAndTheViews) {
  // `--view deltaa` showed the composite without a word; the views depend on the technique, so the flag is
  // checked once the pipeline is built: one line naming it and what there is, exit 2.
  const std::string rec = std::string(MRGI_SOURCE_DIR) + "/recordings/tabletop-pt";
  const std::string scene = std::string(MRGI_SOURCE_DIR) + "/recordings/scenes/tabletop.json";
  const Result r = runMrgi("live --source " + rec + " --scene " + scene +
                           " --pose ground-truth --gl window --frames 1 --view deltaa");
  expectOneLineError(r, "--view: no view 'deltaa'");
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("delta, gbuffer_albedo"), std::string::npos) << r.err;
}

TEST(LiveWindow, DISABLED_ShowsTheCompositeNextToItsPanel) {
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_live_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string rec = std::string(MRGI_SOURCE_DIR) + "/recordings/tabletop-pt";
  const std::string scene = std::string(MRGI_SOURCE_DIR) + "/recordings/scenes/tabletop.json";
  const Result r = runMrgi("live --source " + rec + " --scene " + scene +
                           " --pose ground-truth --gl window --frames 3"
                           " --screenshot " +
                           (dir / "live.png").string() + " --record " + (dir / "rec").string() + " --record-now");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto summary = nlohmann::json::parse(r.out);
  EXPECT_EQ(summary["frames"], 3);
  // Its throughput: the loop's time per frame holds the pipeline's.
  EXPECT_GT(summary["fps"].get<double>(), 0.0);
  EXPECT_GE(summary["wall_ms_per_frame"].get<double>(), summary["pipeline_ms_per_frame"].get<double>());
  EXPECT_NEAR(summary["fps"].get<double>() * summary["wall_ms_per_frame"].get<double>(), 1000.0, 1e-6);
  EXPECT_TRUE(summary["process"].contains("GLIBC_TUNABLES")) << summary.dump();  // what the times were measured under
  EXPECT_EQ(summary["prepared_ahead"], 2);  // frames 2 and 3 were prepared while GL rendered the one before
  // The record toggle wrote the frames it showed into a session.
  EXPECT_EQ(summary["recorded"]["frames"], 3);
  EXPECT_EQ(nlohmann::json::parse(runMrgi("info " + (dir / "rec").string()).out)["frame_count"], 3);
  const cv::Mat shot = cv::imread((dir / "live.png").string());
  ASSERT_EQ(shot.cols, 320 * 2 + 360);  // the 320x240 session at 2x, then the panel
  ASSERT_EQ(shot.rows, 240 * 2 + 24);   // as tall as the image and its caption line: no band under the image
  {
    // The image reaches the caption: its last rows are the composite, not the window's background.
    cv::Scalar mean, dev;
    cv::meanStdDev(shot(cv::Rect(0, 470, 640, 10)), mean, dev);
    EXPECT_GT(mean[0] + mean[1] + mean[2], 3 * 40.0);
  }
  // The view shows the same composite headless replay makes of the third frame, at 2x (marker axes aside).
  ASSERT_EQ(runMrgi("replay " + rec + " --scene " + scene + " --pose ground-truth --frames 3 --mp4 '' --out " +
                    (dir / "replay").string())
                .exitCode,
            0);
  EXPECT_GT(shareLikeReplay(shot, dir / "replay" / "frame_0002.png"), 0.95);
  // The panel holds text and widgets, not a blank strip.
  cv::Scalar mean, dev;
  cv::meanStdDev(shot(cv::Rect(640, 0, 360, shot.rows)), mean, dev);
  EXPECT_GT(dev[0], 8.0);
  fs::remove_all(dir);
}

// Needs a display: run by CTest under Xvfb (Window.LiveShowsCompositeUnderXvfb).
TEST(LiveWindow, DISABLED_LightsABareRecordingFromItsRoomAsReplayDoes) {
  // A scene insert saved for a recording without lights ("lights": "auto") drew the object black live, lit by
  // nothing ("lights: 0"): the window rebuilt its pipeline from the scene as loaded, not as resolved against the
  // source. It is lit from the room of the whole recording, fused first, as replay lights it: the same composite.
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_live_auto_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string icl = std::string(MRGI_SHARED_DATA) + "/rgbd-open3d-iclnuim";
  const std::string sphere = (fs::path(MRGI_SOURCE_DIR) / "recordings/models/sphere.ply").string();
  const std::string scene = (dir / "icl.json").string();
  ASSERT_EQ(
      runMrgi("insert --session " + icl + " --model " + sphere + " --scale 0.2 --at 320,400 --snap --save " + scene)
          .exitCode,
      0);
  ASSERT_EQ(nlohmann::json::parse(slurp(scene))["lights"], "auto");
  const Result r = runMrgi("live --source " + icl + " --scene " + scene + " --gl window --frames 2 --no-loop" +
                           " --screenshot " + (dir / "live.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto summary = nlohmann::json::parse(r.out);
  EXPECT_GT(summary["lights"].get<int>(), 0) << summary.dump();
  // And how much of the directions around the object its room covers (the panel says it too).
  EXPECT_GT(summary["room_coverage"].get<double>(), 0.2) << summary.dump();
  EXPECT_LE(summary["room_coverage"].get<double>(), 1.0) << summary.dump();
  ASSERT_EQ(runMrgi("replay " + icl + " --scene " + scene + " --frames 2 --mp4 '' --out " + (dir / "replay").string())
                .exitCode,
            0);
  const cv::Mat shot = cv::imread((dir / "live.png").string()),
                replayed = cv::imread((dir / "replay/frame_0001.png").string());
  ASSERT_FALSE(shot.empty() || replayed.empty());
  ASSERT_GE(shot.cols, 640);
  ASSERT_GE(shot.rows, 480);
  // The object's pixels (where the replayed frame differs from the recording) match replay's, not black.
  const cv::Mat shown = shot(cv::Rect(0, 0, 640, 480));
  cv::Mat diff;
  cv::absdiff(shown, replayed, diff);
  cv::cvtColor(diff, diff, cv::COLOR_BGR2GRAY);
  // The sphere's centre region: bright in replay, and the same live.
  const cv::Rect centre(290, 320, 40, 40);
  EXPECT_GT(cv::mean(replayed(centre))[1], 100.0);
  EXPECT_LT(cv::mean(diff(centre))[0], 3.0);
  fs::remove_all(dir);
}

TEST(LiveWindow, DISABLED_BuildsTheRoomAsItGoesAndShowsIt) {
  // live --fuse-room: the demo fuses the room from the frames it shows, lights the object from it, shows
  // the fused room's radiance in the view (--view room_radiance), and saves the room when it ends.
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_live_room_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string rec = std::string(MRGI_SOURCE_DIR) + "/recordings/tabletop-scan";
  const std::string scene = std::string(MRGI_SOURCE_DIR) + "/recordings/scenes/tabletop-room.json";
  const Result r = runMrgi("live --source " + rec + " --scene " + scene +
                           " --pose ground-truth --gl window --frames 4 --fuse-room"
                           " --fuse-refresh 2 --view room_radiance --save-room " +
                           (dir / "room").string() + " --screenshot " + (dir / "live.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto summary = nlohmann::json::parse(r.out);
  EXPECT_EQ(summary["room"]["integrated"], 4);
  EXPECT_EQ(summary["room"]["saved"], (dir / "room").string());
  EXPECT_GT(mrgi::reconstruction::loadRoom((dir / "room").string()).positions.size(), 1000u);
  // The view is the fused room seen from the camera, as headless replay --debug draws it after the same
  // four frames (at 2x), not the composite.
  const cv::Mat shot = cv::imread((dir / "live.png").string());
  ASSERT_FALSE(shot.empty());
  ASSERT_EQ(runMrgi("replay " + rec + " --scene " + scene +
                    " --pose ground-truth --frames 4 --fuse-room --fuse-refresh 2 --debug"
                    " --mp4 '' --out " +
                    (dir / "replay").string())
                .exitCode,
            0);
  for (const char* name : {"debug_0003_room_radiance.png", "frame_0003.png"})
    ASSERT_TRUE(fs::exists(dir / "replay" / name)) << name;
  EXPECT_GT(shareLikeReplay(shot, dir / "replay" / "debug_0003_room_radiance.png"), 0.95) << "the room's radiance";
  EXPECT_LT(shareLikeReplay(shot, dir / "replay" / "frame_0003.png"), 0.9) << "not the composite";
  fs::remove_all(dir);
}

// Needs a display: run by CTest under Xvfb (Window.LiveShowsCompositeUnderXvfb).
TEST(InsertWindow, DISABLED_PreviewsThePlacementAndSavesIt) {
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_insert_win_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string rec = std::string(MRGI_SOURCE_DIR) + "/recordings/tabletop-synth";
  const Result r = runMrgi("insert --session " + rec + " --model " + kModels +
                           "sphere.ply --scale 0.05 --translate 0.1,0.05,0.3"
                           " --snap --gl window --frames 3 --screenshot " +
                           (dir / "insert.png").string() + " --save " + (dir / "scene.json").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto report = nlohmann::json::parse(r.out);
  EXPECT_TRUE(report["saved"].get<bool>());
  const auto doc = nlohmann::json::parse(slurp(dir / "scene.json"));
  ASSERT_EQ(doc["objects"].size(), 1u);
  EXPECT_NEAR(doc["objects"][0]["translate"][2].get<double>(), 0.05, 0.01);  // snapped: resting on the table
  const cv::Mat shot = cv::imread((dir / "insert.png").string());
  ASSERT_EQ(shot.cols, 640 + 360);
  ASSERT_EQ(shot.rows, 480 + 24);  // the 640x480 session at 1x and its caption line
  // The view is the camera image with the sphere: compare it with the session's frame away from the sphere,
  // and expect the sphere's pixels to differ.
  const cv::Mat frame = cv::imread(rec + "/colour/000000.png");
  cv::Mat diff;
  cv::absdiff(shot(cv::Rect(0, 0, 640, 480)), frame, diff);
  cv::cvtColor(diff, diff, cv::COLOR_BGR2GRAY);
  EXPECT_GT(cv::countNonZero(diff <= 8), static_cast<int>(0.8 * diff.total()));
  EXPECT_GT(cv::countNonZero(diff > 40), 200);  // the object (and the marker axes)
  cv::Mat grey;
  cv::cvtColor(shot(cv::Rect(0, 0, 640, 480)), grey, cv::COLOR_BGR2GRAY);
  EXPECT_GT(cv::mean(grey, diff > 40)[0], 90.0);  // lit by the session's lights, not black
  fs::remove_all(dir);
}

TEST(Cli, ReplayFailsInOneLineWhenTheMarkerIsNeverSeen) {
  // The session's manifest names a tag that is not in its images.
  const fs::path dir = fs::temp_directory_path() / ("mrgi_cli_nomarker_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  fs::copy(session(), dir / "s", fs::copy_options::recursive);
  auto manifest = nlohmann::json::parse(slurp(dir / "s" / "manifest.json"));
  manifest["marker"]["id"] = manifest["marker"]["id"].get<int>() + 1;
  std::ofstream(dir / "s" / "manifest.json") << manifest.dump(2);
  const fs::path scene = writeScene(
      "nomarker.json", R"({"objects": [{"model": ")" + kModels +
                           R"(sphere.ply", "translate": [0, 0, 0.06], "scale": 0.06}], "lights": "manifest"})");
  const Result r =
      runMrgi("replay " + (dir / "s").string() + " --scene " + scene.string() + " --out " + (dir / "out").string());
  expectOneLineError(r, "no frame could be placed in 3 frames");
  EXPECT_TRUE(fs::exists(dir / "out" / "frame_0002.png"));  // the camera images are still written
  const auto summary = nlohmann::json::parse(slurp(dir / "out" / "summary.json"));
  EXPECT_EQ(summary["frames_with_pose"], 0);
  fs::remove_all(dir);
}

TEST(Cli, SynthPutsTheTableOutdoorsUnderAnHdrEnvironment) {
  const fs::path out = fs::temp_directory_path() / ("mrgi_cli_synth_env_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const std::string env = std::string(MRGI_SHARED_DATA) + "/hdr-blender-world/forest.exr";
  const std::string base = "synth --frames 1 --width 64 --height 48 --spp 4 --bounces 1 --fisheye-every 1 ";
  const Result r = runMrgi(base + "--environment " + env + " --out " + out.string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto manifest = nlohmann::json::parse(slurp(out / "manifest.json"));
  const auto& gt = manifest["ground_truth"];
  EXPECT_EQ(gt["environment"]["file"], "forest.exr");
  EXPECT_GT(gt["environment"]["scale"].get<double>(), 0.0);
  EXPECT_TRUE(gt["lights"].empty());  // the environment is the only light
  // The fisheye looks up at the sky: its centre is bright, and every pixel inside the image circle sees the
  // environment (no room, so no ceiling).
  const cv::Mat fish = cv::imread((out / "fisheye" / "000000.exr").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(fish.type(), CV_32FC3);
  const cv::Vec3f centre = fish.at<cv::Vec3f>(fish.rows / 2, fish.cols / 2);
  EXPECT_GT(centre[0] + centre[1] + centre[2], 0.1f);
  const cv::Mat colour = cv::imread((out / "colour" / "000000.png").string());
  EXPECT_GT(cv::mean(colour)[0], 30.0);  // lit
  expectOneLineError(
      runMrgi(base + "--environment " + (out / "manifest.json").string() + " --out " + out.string() + "2"),
      "cannot be read as an HDR environment");
  expectOneLineError(runMrgi(base + "--render raycast --environment " + env + " --out " + out.string() + "3"),
                     "--environment needs --render pathtrace");
  EXPECT_FALSE(fs::exists(out.string() + "2"));
  fs::remove_all(out);
}

TEST(Cli, ABoxThatMovesInTheCarvingSessionLeavesNoGhost) {
  // recordings/tabletop-carve: the box moves to the front of the table at frame 4 (manifest: box_moves). The
  // room of the first four frames holds the box where it stood; the room of all twelve holds it where it went
  // and nothing where it was (the carving of a box seen longer than the views that see through it:
  // room_model_test).
  const std::string session = (fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-carve").string();
  const auto manifest = nlohmann::json::parse(slurp(fs::path(session) / "manifest.json"));
  const auto& gt = manifest["ground_truth"]["scene"];
  ASSERT_EQ(gt["box_moves"]["at_frame"], 4);
  const fs::path base = fs::temp_directory_path() / ("mrgi_cli_carve_" + std::to_string(::getpid()));
  fs::remove_all(base);
  // World (y up) -> marker frame (x = world x, y = -world z, z = world y - the tag's height).
  const double tagY = manifest["ground_truth"]["T_world_marker"][7].get<double>();  // row-major 4 x 4
  const auto inBox = [&](const cv::Vec3f& p, const nlohmann::json& box) {
    const cv::Vec3d w(p[0], p[2] + tagY, -p[1]);
    // More than 3 cm above the table top (nearer the table still seen, the running average of the fusion
    // decides, not the carving), within 1 cm of the box's extent.
    return w[1] > box["min"][1].get<double>() + 0.03 && w[1] < box["max"][1].get<double>() + 0.01 &&
           w[0] > box["min"][0].get<double>() - 0.01 && w[0] < box["max"][0].get<double>() + 0.01 &&
           w[2] > box["min"][2].get<double>() - 0.01 && w[2] < box["max"][2].get<double>() + 0.01;
  };
  const auto count = [&](const mrgi::reconstruction::RoomMesh& m, const nlohmann::json& box) {
    return std::count_if(m.positions.begin(), m.positions.end(), [&](const cv::Vec3f& p) { return inBox(p, box); });
  };
  const fs::path before = base / "before", after = base / "after";
  ASSERT_EQ(runMrgi("room " + session + " --out " + before.string() + " --pose ground-truth --frames 4").exitCode, 0);
  ASSERT_EQ(runMrgi("room " + session + " --out " + after.string() + " --pose ground-truth").exitCode, 0);
  const mrgi::reconstruction::RoomMesh b = mrgi::reconstruction::loadRoom(before.string()),
                                       a = mrgi::reconstruction::loadRoom(after.string());
  EXPECT_GT(count(b, gt["box"]), 100) << "the box where it stood";
  EXPECT_EQ(count(b, gt["box_moves"]), 0);
  EXPECT_EQ(count(a, gt["box"]), 0) << "a ghost of the box where it stood";
  EXPECT_GT(count(a, gt["box_moves"]), 100) << "the box where it went";
  fs::remove_all(base);
}

TEST(Cli, ReplayBuildsTheRoomAsTheFramesComeAndLightsFromIt) {
  // replay --fuse-room: no saved room; every frame with a pose is fused, the room's surface is the real
  // scene from the first frame on and refreshed every 4 frames, the lights come from it, and --save-room
  // writes it as mrgi room does.
  const std::string session = (fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-scan").string();
  const std::string scene = (fs::path(MRGI_SOURCE_DIR) / "recordings/scenes/tabletop-room.json").string();
  const fs::path base = fs::temp_directory_path() / ("mrgi_cli_fuse_" + std::to_string(::getpid()));
  fs::remove_all(base);
  const fs::path out = base / "replay", saved = base / "room";
  const Result r = runMrgi("replay " + session + " --scene " + scene + " --fuse-room --fuse-refresh 4 --save-room " +
                           saved.string() + " --out " + out.string() + " --frames 9 --pose ground-truth --mp4 \"\"");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto s = nlohmann::json::parse(slurp(out / "summary.json"));
  EXPECT_EQ(s["room"]["integrated"], 9);
  const auto& frames = s["per_frame"];
  ASSERT_EQ(frames.size(), 9u);
  std::vector<int> refreshed;
  for (int i = 0; i < 9; ++i)
    if (frames[i]["room_fusion"].contains("refreshed")) refreshed.push_back(i);
  EXPECT_EQ(refreshed, (std::vector<int>{0, 4, 8}));
  EXPECT_LT(frames[0]["room_fusion"]["refreshed"].get<size_t>(), frames[8]["room_fusion"]["refreshed"].get<size_t>())
      << "the room grows";
  EXPECT_EQ(frames[0]["room"]["lights"]["count"], 4) << frames[0].dump();
  // Nine orbit frames see under half the directions around the object: said once, with the last estimate's share.
  const double coverage = frames[8]["room"]["lights"]["coverage"].get<double>();
  EXPECT_LT(coverage, 0.5);
  const size_t said = r.err.find("the room covers ");
  ASSERT_NE(said, std::string::npos) << r.err;
  EXPECT_NEAR(std::stod(r.err.substr(said + 16)), 100 * coverage, 0.51) << r.err;
  EXPECT_EQ(r.err.find("the room covers ", said + 1), std::string::npos) << r.err;  // once
  EXPECT_TRUE(frames[0].contains("view_mesh_detailed")) << "lit from the room on the first frame: " << frames[0].dump();
  const auto saved9 = mrgi::reconstruction::loadRoom(saved.string());
  EXPECT_GT(saved9.positions.size(), frames[8]["room_fusion"]["refreshed"].get<size_t>() / 2);
  // A saved room and a new one at once, or a room to save that is not being built: one-line errors.
  expectOneLineError(runMrgi("replay " + session + " --scene " + scene + " --fuse-room --room " + saved.string() +
                             " --out " + (base / "x").string()),
                     "--fuse-room");
  expectOneLineError(runMrgi("replay " + session + " --scene " + scene + " --per-frame-mesh --save-room " +
                             (base / "y").string() + " --out " + (base / "x").string()),
                     "--save-room");
  EXPECT_FALSE(fs::exists(base / "x"));
  fs::remove_all(base);
}

TEST(Cli, RoomFusesTheSessionIntoAModelThatLoadsBack) {
  const fs::path out = fs::temp_directory_path() / ("mrgi_cli_room_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const std::string session = (fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-synth").string();
  const Result r = runMrgi("room " + session + " --out " + out.string() + " --pose ground-truth --frames 8 --json");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto summary = nlohmann::json::parse(r.out);
  EXPECT_EQ(summary["frames"], 8);
  EXPECT_EQ(summary["integrated"], 8);
  EXPECT_GT(summary["triangles"].get<int>(), 10000);
  // An orbit of the table sees little of the room around the object: one line says so, nothing else.
  const double coverage = summary["coverage_at_object"].get<double>();
  EXPECT_GT(coverage, 0.05);
  EXPECT_LT(coverage, 0.5);
  EXPECT_EQ(messageLines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("the room covers"), std::string::npos) << r.err;
  // preview.png: the room from the first camera (radiance, albedo), from above, and its lights at the object;
  // from the first camera the room holds most of the view (the table and the wall behind it).
  EXPECT_EQ(summary["preview"], (out / "preview.png").string());
  const cv::Mat preview = cv::imread((out / "preview.png").string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(preview.empty());
  EXPECT_EQ(preview.cols, 640);
  EXPECT_GT(preview.rows, 2 * 240 + 320);
  cv::Mat firstView = preview(cv::Rect(0, 30, 320, 200)), unscanned;
  cv::inRange(firstView, cv::Scalar(70, 30, 30), cv::Scalar(70, 30, 30), unscanned);  // BGR of the dark blue
  EXPECT_LT(cv::countNonZero(unscanned), 0.3 * firstView.total());
  // The table top is the marker frame's z = 0 plane: the fused surface lies on it around the tag.
  mrgi::reconstruction::RoomInfo info;
  const auto mesh = mrgi::reconstruction::loadRoom(out.string(), &info);
  EXPECT_EQ(info.framesIntegrated, 8);
  int onTable = 0;
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    const cv::Vec3f& p = mesh.positions[i];
    if (std::abs(p[0]) > 0.12 || std::abs(p[1]) > 0.12 || std::abs(p[2]) > 0.05) continue;
    ++onTable;
    EXPECT_NEAR(p[2], 0.f, 0.006f);
    EXPECT_GT(mesh.normals[i][2], 0.9f);
  }
  EXPECT_GT(onTable, 50);
  // Replay lit from the room: the room's albedo is estimated once (skipped on the next frame), the composite
  // differs from the camera image where the sphere is.
  const fs::path replayOut = out.string() + "_replay";
  fs::remove_all(replayOut);
  const std::string scene = (fs::path(MRGI_SOURCE_DIR) / "recordings/scenes/tabletop.json").string();
  const Result rr = runMrgi("replay " + session + " --scene " + scene + " --room " + out.string() + " --out " +
                            replayOut.string() + " --frames 2 --pose ground-truth --mp4 \"\"");
  ASSERT_EQ(rr.exitCode, 0) << rr.err;
  const auto replaySummary = nlohmann::json::parse(slurp(replayOut / "summary.json"));
  const auto& frames = replaySummary["per_frame"];
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0]["room"]["vertices"].get<size_t>(), mesh.positions.size());
  EXPECT_NE(frames[1]["skipped"].dump().find("room_albedo"), std::string::npos) << frames[1].dump();
  // The view mesh takes the frame's texture over the room's albedo (the room blurs it over its voxels).
  EXPECT_GT(frames[0]["view_mesh_detailed"].get<size_t>(), 1000u) << frames[0].dump();
  // Lights from the room: replay with "lights": "room" and --debug shows the room's environment with its
  // lights; mrgi room-lights prints them as JSON (SH remainder of 9 RGB triples) and writes the same map.
  {
    const fs::path lit = out.string() + "_lit";
    fs::remove_all(lit);
    const std::string roomScene = (fs::path(MRGI_SOURCE_DIR) / "recordings/scenes/tabletop-room.json").string();
    const Result rl = runMrgi("replay " + session + " --scene " + roomScene + " --room " + out.string() + " --out " +
                              lit.string() + " --frames 1 --pose ground-truth --debug --mp4 \"\"");
    ASSERT_EQ(rl.exitCode, 0) << rl.err;
    const auto s = nlohmann::json::parse(slurp(lit / "summary.json"));
    EXPECT_EQ(s["per_frame"][0]["room"]["lights"]["count"], 4) << s["per_frame"][0].dump();
    const cv::Mat map = cv::imread((lit / "debug_0000_room_lights.png").string());
    EXPECT_EQ(map.cols, 256);
    EXPECT_EQ(map.rows, 128);
    // The fused room seen from the camera: its radiance at the frame's exposure reads as the camera image
    // (blurred over the voxels) wherever the room was scanned and the object is not; its albedo is shown too.
    {
      const cv::Mat seen = cv::imread((lit / "debug_0000_room_radiance.png").string()),
                    camera = cv::imread((lit / "frame_0000.png").string()),
                    object = cv::imread((lit / "debug_0000_gbuffer_mask.png").string(), cv::IMREAD_GRAYSCALE);
      ASSERT_FALSE(seen.empty() || camera.empty() || object.empty());
      EXPECT_TRUE(fs::exists(lit / "debug_0000_room_albedo.png"));
      double seenSum = 0, cameraSum = 0, diff = 0;
      int n = 0;
      for (int y = 0; y < seen.rows; ++y)
        for (int x = 0; x < seen.cols; ++x) {
          const cv::Vec3b a = seen.at<cv::Vec3b>(y, x), b = camera.at<cv::Vec3b>(y, x);
          if (object.at<uchar>(y, x) > 127 || a == cv::Vec3b(70, 30, 30)) continue;  // the object; unscanned (BGR)
          for (int c = 0; c < 3; ++c) seenSum += a[c], cameraSum += b[c], diff += std::abs(a[c] - b[c]);
          ++n;
        }
      ASSERT_GT(n, static_cast<int>(seen.total() / 2));
      EXPECT_NEAR(seenSum / cameraSum, 1.0, 0.05);
      EXPECT_LT(diff / (3.0 * n), 15.0);
      EXPECT_GT(s["per_frame"][0]["debug_room_radiance_coverage"].get<double>(), 0.5) << s["per_frame"][0].dump();
    }
    const fs::path png = lit / "map.png";
    const Result j = runMrgi("room-lights " + out.string() + " --at 0 0 0.06 --json --map " + png.string());
    ASSERT_EQ(j.exitCode, 0) << j.err;
    const auto lights = nlohmann::json::parse(j.out);
    EXPECT_EQ(lights["lights"].size(), 4u);
    EXPECT_EQ(lights["ambient_sh"].size(), 9u);
    EXPECT_GT(lights["coverage"].get<double>(), 0.2);
    EXPECT_TRUE(fs::exists(png));
    // Its own earlier map is replaced; a file the user has is not. --at takes commas as insert's flags do.
    const Result commas = runMrgi("room-lights " + out.string() + " --at 0,0,0.06 --json");
    ASSERT_EQ(commas.exitCode, 0) << commas.err;
    EXPECT_EQ(nlohmann::json::parse(commas.out)["lights"], lights["lights"]);
    expectOneLineError(runMrgi("room-lights " + out.string() + " --at 0,0"), "--at");
    EXPECT_EQ(runMrgi("room-lights " + out.string() + " --at 0 0 0.06 --map " + png.string()).exitCode, 0);
    EXPECT_EQ(cv::imread(png.string()).cols, 256);  // its Software text chunk keeps it a valid PNG
    const fs::path users = lit / "holiday.png";
    fs::copy_file(fs::path(MRGI_SOURCE_DIR) / "recordings/tabletop-synth/colour/000000.png", users);
    const std::string before = slurp(users);
    expectOneLineError(runMrgi("room-lights " + out.string() + " --at 0 0 0.06 --map " + users.string()),
                       "refusing to overwrite");
    EXPECT_EQ(slurp(users), before);
    expectOneLineError(runMrgi("room-lights /nonexistent/room"), "/nonexistent/room");
    fs::remove_all(lit);
  }
  // A session with neither listed lights nor a fisheye, a scene that does not say where lights come from,
  // and a room: the lights come from the room (without the room, the usual one-line error).
  {
    const fs::path bare = out.string() + "_bare";
    fs::remove_all(bare);
    fs::copy(session, bare, fs::copy_options::recursive);
    auto manifest = nlohmann::json::parse(slurp(bare / "manifest.json"));
    manifest.erase("fisheye");
    manifest["ground_truth"].erase("lights");
    std::ofstream(bare / "manifest.json", std::ios::trunc) << manifest.dump(2);
    std::string index;
    std::istringstream lines(slurp(bare / "frames.jsonl"));
    for (std::string line; std::getline(lines, line);) {
      auto j = nlohmann::json::parse(line);
      j.erase("fisheye");
      j.erase("exposure");
      index += j.dump() + "\n";
    }
    std::ofstream(bare / "frames.jsonl", std::ios::trunc) << index;
    const fs::path noLights = bare / "scene.json";
    std::ofstream(noLights) << R"({"objects": [{"model": ")" << MRGI_SOURCE_DIR
                            << R"(/recordings/models/sphere.ply", "translate": [0, 0, 0.06], "scale": 0.06}]})";
    const Result d = runMrgi("replay " + bare.string() + " --scene " + noLights.string() + " --room " + out.string() +
                             " --out " + (bare / "out").string() + " --frames 1 --pose ground-truth --mp4 \"\"");
    ASSERT_EQ(d.exitCode, 0) << d.err;
    const auto ds = nlohmann::json::parse(slurp(bare / "out" / "summary.json"));
    EXPECT_EQ(ds["per_frame"][0]["room"]["lights"]["count"], 4) << ds["per_frame"][0].dump();
    // Without a room the lights come from the room fused as the frames come, said in one line.
    const Result fused = runMrgi("replay " + bare.string() + " --scene " + noLights.string() + " --out " +
                                 (bare / "out2").string() + " --frames 1 --pose ground-truth --mp4 \"\"");
    ASSERT_EQ(fused.exitCode, 0) << fused.err;
    EXPECT_NE(fused.err.find("the scene is lit from the room"), std::string::npos) << fused.err;
    const auto fs2 = nlohmann::json::parse(slurp(bare / "out2" / "summary.json"));
    EXPECT_TRUE(fs2["per_frame"][0].contains("room")) << fs2["per_frame"][0].dump();
    fs::remove_all(bare);
  }
  // A bad room stops replay before anything is written.
  fs::remove_all(replayOut);
  expectOneLineError(
      runMrgi("replay " + session + " --scene " + scene + " --room /nonexistent/room --out " + replayOut.string()),
      "/nonexistent/room");
  EXPECT_FALSE(fs::exists(replayOut));
  // Writing again into its own output is fine; into someone else's folder is not, and nothing there changes.
  EXPECT_EQ(runMrgi("room " + session + " --out " + out.string() + " --pose ground-truth --frames 2 --json").exitCode,
            0);
  const fs::path mine = out.string() + "_mine";
  fs::create_directories(mine);
  std::ofstream(mine / "notes.txt") << "mine";
  expectOneLineError(runMrgi("room " + session + " --out " + mine.string() + " --frames 2"), mine.string());
  EXPECT_EQ(slurp(mine / "notes.txt"), "mine");
  EXPECT_FALSE(fs::exists(mine / "room.ply"));
  // Bad options and a session without any marker pose are one line each.
  expectOneLineError(runMrgi("room " + session + " --out " + out.string() + "_x --voxel 0.02 --trunc 0.01"),
                     "--trunc: must be at least 2 voxels");
  const fs::path noTag = scratchSession("mrgi_cli_room_notag_", ::session(), 2);
  for (const auto& e : fs::directory_iterator(noTag / "s" / "colour"))  // flat grey frames: no tag to see
    cv::imwrite(e.path().string(), cv::Mat(120, 160, CV_8UC3, cv::Scalar(90, 90, 90)));
  expectOneLineError(runMrgi("room " + (noTag / "s").string() + " --out " + (noTag / "room").string()),
                     "no frame has a trusted camera pose (2 lost");
  fs::remove_all(noTag);
  fs::remove_all(out);
  fs::remove_all(mine);
}
