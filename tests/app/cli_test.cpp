// The command contract, checked from outside: run the mrgi binary and inspect exit codes, stdout, stderr
// and the files it writes.
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

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

Result mrgi(const std::string& args) {
  static int n = 0;
  const fs::path tmp = fs::temp_directory_path() / ("mrgi_cli_" + std::to_string(::getpid()) + "_" + std::to_string(n++));
  const std::string cmd = std::string(MRGI_BINARY) + " " + args + " >" + tmp.string() + ".out 2>" + tmp.string() + ".err";
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

int lines(const std::string& s) { return static_cast<int>(std::count(s.begin(), s.end(), '\n')); }

/// One small synthetic session shared by the tests of this file.
const fs::path& session() {
  static const fs::path dir = [] {
    const fs::path d = fs::temp_directory_path() / ("mrgi_cli_session_" + std::to_string(::getpid()));
    fs::remove_all(d);
    const Result r = mrgi("synth --out " + d.string() + " --frames 3 --width 160 --height 120 --fisheye-every 2");
    EXPECT_EQ(r.exitCode, 0) << r.err;
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
  const Result r = mrgi("--help");
  EXPECT_EQ(r.exitCode, 0);
  for (const char* sub : {"info", "replay", "synth"}) EXPECT_NE(r.out.find(sub), std::string::npos) << sub;
}

TEST(Cli, InfoPrintsOneJsonObject) {
  const Result r = mrgi("info " + session().string());
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

TEST(Cli, ReplayWritesFramesAndSummary) {
  const fs::path out = fs::temp_directory_path() / ("mrgi_cli_replay_" + std::to_string(::getpid()));
  fs::remove_all(out);
  const Result r = mrgi("replay " + session().string() + " --out " + out.string() + " --frames 2");
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
  // Running again into the same folder (earlier output) works; a folder of user files is refused.
  EXPECT_EQ(mrgi("replay " + session().string() + " --out " + out.string() + " --frames 1").exitCode, 0);
  const fs::path mine = out.string() + "_user";
  fs::create_directories(mine);
  std::ofstream(mine / "thesis.tex") << "precious";
  expectOneLineError(mrgi("replay " + session().string() + " --out " + mine.string()), "refusing to overwrite");
  EXPECT_EQ(slurp(mine / "thesis.tex"), "precious");
  fs::remove_all(out);
  fs::remove_all(mine);
}

TEST(Cli, BadInputsAreOneLineErrors) {
  expectOneLineError(mrgi("info /nonexistent/session"), "/nonexistent/session: does not exist");
  expectOneLineError(mrgi("replay /nonexistent/session --out /tmp/x"), "/nonexistent/session");
  expectOneLineError(mrgi("replay " + session().string() + " --out /tmp/x --gl vulkan"), "--gl");
  expectOneLineError(mrgi("nosuchcommand"), "nosuchcommand");
  expectOneLineError(mrgi("info openni2://"), "openni2://");
  // A corrupt frame in a copy of the session: the error names the file.
  const fs::path copy = session().string() + "_corrupt";
  fs::remove_all(copy);
  fs::copy(session(), copy, fs::copy_options::recursive);
  std::ofstream(copy / "colour/000001.png", std::ios::trunc) << "garbage";
  const fs::path out = copy.string() + "_out";
  fs::remove_all(out);
  expectOneLineError(mrgi("replay " + copy.string() + " --out " + out.string()), "colour/000001.png: cannot decode");
  fs::remove_all(copy);
  fs::remove_all(out);
}
