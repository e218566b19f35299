// Session format: round trip, crash safety (truncation at every byte, SIGKILL at random moments), bad input.
#include "capture/session.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "capture/error.h"
#include "capture/frame_source.h"
#include "capture/image_io.h"

namespace fs = std::filesystem;
using namespace mrgi::capture;

namespace {

fs::path freshDir(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("mrgi_test_" + std::to_string(::getpid()) + "_" + name);
  fs::remove_all(p);
  return p;
}

SessionManifest smallManifest(int w = 32, int h = 24) {
  SessionManifest m;
  m.colour = {w, h, 30.0, 30.0, (w - 1) / 2.0, (h - 1) / 2.0};
  m.depth = m.colour;
  m.marker = MarkerSpec{"tag36h11", 0.1, 3};
  m.groundTruth = {{"note", "test"}};
  return m;
}

Frame syntheticFrame(int i, int w = 32, int h = 24) {
  Frame f;
  f.index = i;
  f.timestamp = 0.5 + i / 30.0;
  RgbdFrame r;
  r.colour = cv::Mat(h, w, CV_8UC3);
  r.depth = cv::Mat(h, w, CV_32FC1);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      r.colour.at<cv::Vec3b>(y, x) = {uchar(x * 7 + i), uchar(y * 9), uchar(i * 13)};
      r.depth.at<float>(y, x) = (x + y) % 7 == 0 ? 0.f : 0.5f + 0.001f * (x + 3 * y + i);  // mm-exact values
    }
  f.rgbd = r;
  f.groundTruthT_world_camera = Pose::eye();
  (*f.groundTruthT_world_camera)(0, 3) = 0.01 * i;
  return f;
}

void writeSession(const fs::path& dir, int frames) {
  SessionWriter w(dir.string(), smallManifest());
  for (int i = 0; i < frames; ++i) w.append(syntheticFrame(i));
}

std::string slurpFile(const fs::path& p) {
  std::ifstream f(p);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

std::string expectCaptureError(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const CaptureError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a CaptureError";
  return {};
}

}  // namespace

TEST(Session, RoundTripPreservesPixelsDepthAndPoses) {
  const fs::path dir = freshDir("roundtrip");
  writeSession(dir, 3);
  SessionSource s(dir.string());
  ASSERT_EQ(s.frameCount(), 3);
  EXPECT_EQ(s.manifest().marker->id, 3);
  EXPECT_EQ(s.manifest().groundTruth["note"], "test");
  EXPECT_TRUE(s.info().hasGroundTruth);
  for (int i = 0; i < 3; ++i) {
    const auto f = s.next();
    ASSERT_TRUE(f);
    const Frame ref = syntheticFrame(i);
    EXPECT_DOUBLE_EQ(f->timestamp, ref.timestamp);
    EXPECT_EQ(cv::norm(f->rgbd->colour, ref.rgbd->colour, cv::NORM_INF), 0.0);
    // Depth is stored in whole millimetres; the reference values are whole millimetres (float rounding only).
    EXPECT_LT(cv::norm(f->rgbd->depth, ref.rgbd->depth, cv::NORM_INF), 1e-6);
    EXPECT_DOUBLE_EQ((*f->groundTruthT_world_camera)(0, 3), 0.01 * i);
  }
  EXPECT_FALSE(s.next());
  fs::remove_all(dir);
}

TEST(Session, ColourCanBeStoredAsJpegFromAFrameOn) {
  // The first frame lossless (PNG), the next two JPEG at quality 95: named .jpg in the index, read back within
  // a few levels of what was written (a smooth ramp), depth untouched; quality 0 goes back to PNG.
  const fs::path dir = freshDir("jpeg");
  {
    SessionWriter w(dir.string(), smallManifest());
    w.append(syntheticFrame(0));
    w.setColourJpegQuality(95);
    w.append(syntheticFrame(1));
    w.append(syntheticFrame(2));
    w.setColourJpegQuality(0);
    w.append(syntheticFrame(3));
  }
  EXPECT_TRUE(fs::exists(dir / "colour" / "000000.png"));
  EXPECT_TRUE(fs::exists(dir / "colour" / "000001.jpg"));
  EXPECT_TRUE(fs::exists(dir / "colour" / "000002.jpg"));
  EXPECT_TRUE(fs::exists(dir / "colour" / "000003.png"));
  EXPECT_FALSE(fs::exists(dir / "colour" / "000001.png"));
  SessionSource s(dir.string());
  for (int i = 0; i < 4; ++i) {
    const auto f = s.next();
    ASSERT_TRUE(f);
    const Frame ref = syntheticFrame(i);
    const double err =
        cv::norm(f->rgbd->colour, ref.rgbd->colour, cv::NORM_L1) / static_cast<double>(ref.rgbd->colour.total() * 3);
    if (i == 1 || i == 2) {
      EXPECT_GT(err, 0.0) << i;  // lossy
      EXPECT_LT(err, 3.0) << i;  // mean levels off
    } else {
      EXPECT_EQ(err, 0.0) << i;
    }
    EXPECT_LT(cv::norm(f->rgbd->depth, ref.rgbd->depth, cv::NORM_INF), 1e-6);
  }
  fs::remove_all(dir);
}

TEST(Session, FramesCarryTheirOwnLightsWhenTheLightsMove) {
  const fs::path dir = freshDir("movinglights");
  {
    SessionWriter w(dir.string(), smallManifest());
    for (int i = 0; i < 3; ++i) {
      Frame f = syntheticFrame(i);
      if (i > 0) {  // frame 0 has none: the manifest's lights hold for it
        GroundTruthLight point, spot, sun;
        point.position = {0.1 * i, 2, 0.5};
        point.intensity = {9, 8.4, 7.6};
        point.radius = 0.04;
        spot.type = GroundTruthLight::Type::Spot;
        spot.position = {0, 1.5, 0};
        spot.direction = {0, -1, 0};
        spot.intensity = {3, 3, 3};
        spot.spotHalfAngleDeg = 30 + i;
        sun.type = GroundTruthLight::Type::Directional;
        sun.direction = cv::normalize(cv::Vec3d(1, -2, 0));
        sun.irradiance = {100, 90, 80};
        f.groundTruthLights = std::vector<GroundTruthLight>{point, spot, sun};
      }
      w.append(f);
    }
  }
  SessionSource s(dir.string());
  for (int i = 0; i < 3; ++i) {
    const auto f = s.next();
    ASSERT_TRUE(f);
    if (i == 0) {
      EXPECT_FALSE(f->groundTruthLights);
      continue;
    }
    ASSERT_TRUE(f->groundTruthLights);
    const auto& l = *f->groundTruthLights;
    ASSERT_EQ(l.size(), 3u);
    EXPECT_EQ(l[0].type, GroundTruthLight::Type::Point);
    EXPECT_DOUBLE_EQ(l[0].position[0], 0.1 * i);
    EXPECT_DOUBLE_EQ(l[0].radius, 0.04);
    EXPECT_EQ(l[1].type, GroundTruthLight::Type::Spot);
    EXPECT_DOUBLE_EQ(l[1].spotHalfAngleDeg, 30 + i);
    EXPECT_EQ(l[2].type, GroundTruthLight::Type::Directional);
    EXPECT_NEAR(l[2].irradiance[2], 80, 1e-12);
    EXPECT_NEAR(cv::norm(l[2].direction - cv::normalize(cv::Vec3d(1, -2, 0))), 0, 1e-12);
  }
  // A malformed frame light: one line naming the index line and the key.
  std::string text = slurpFile(dir / "frames.jsonl");
  const size_t at = text.find("\"point\"");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, 7, "\"lamp\"");
  std::ofstream(dir / "frames.jsonl", std::ios::trunc) << text;
  const std::string m = expectCaptureError([&] { SessionSource bad(dir.string()); });
  EXPECT_NE(m.find("frames.jsonl:2"), std::string::npos) << m;
  EXPECT_NE(m.find("lights[0].type 'lamp'"), std::string::npos) << m;
  EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  fs::remove_all(dir);
}

TEST(Session, WriterRefusesToOverwriteAnything) {
  const fs::path dir = freshDir("nooverwrite");
  fs::create_directories(dir);
  std::ofstream(dir / "precious.txt") << "user data";
  const std::string msg = expectCaptureError([&] { SessionWriter w(dir.string(), smallManifest()); });
  EXPECT_NE(msg.find("refusing to overwrite"), std::string::npos) << msg;
  EXPECT_TRUE(fs::exists(dir / "precious.txt"));
  fs::remove_all(dir);
}

TEST(Session, WriterRejectsNonIncreasingTimestamps) {
  const fs::path dir = freshDir("timestamps");
  SessionWriter w(dir.string(), smallManifest());
  w.append(syntheticFrame(1));
  expectCaptureError([&] { w.append(syntheticFrame(0)); });
  EXPECT_EQ(w.framesWritten(), 1);
  fs::remove_all(dir);
}

// A recording cut at any byte of its index replays exactly the frames whose lines are complete.
TEST(Session, TruncatedIndexAtEveryByteReplaysCompleteFrames) {
  const fs::path dir = freshDir("truncate");
  writeSession(dir, 4);
  const fs::path index = dir / "frames.jsonl";
  std::ifstream in(index, std::ios::binary);
  const std::string full((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<size_t> lineEnds;
  for (size_t i = 0; i < full.size(); ++i)
    if (full[i] == '\n') lineEnds.push_back(i + 1);
  ASSERT_EQ(lineEnds.size(), 4u);
  for (size_t cut = 0; cut <= full.size(); ++cut) {
    std::ofstream(index, std::ios::binary | std::ios::trunc).write(full.data(), static_cast<std::streamsize>(cut));
    const int64_t complete = std::count_if(lineEnds.begin(), lineEnds.end(), [&](size_t e) { return e <= cut; });
    if (complete == 0) {
      const std::string msg = expectCaptureError([&] { SessionSource s(dir.string()); });
      EXPECT_NE(msg.find("no complete frame"), std::string::npos) << "cut " << cut << ": " << msg;
      continue;
    }
    SessionSource s(dir.string());
    ASSERT_EQ(s.frameCount(), complete) << "cut at byte " << cut;
    int64_t n = 0;
    while (auto f = s.next()) {
      EXPECT_EQ(f->index, n);
      ++n;
    }
    EXPECT_EQ(n, complete);
  }
  fs::remove_all(dir);
}

// A writer killed (SIGKILL) at random moments leaves a session that replays up to its last complete frame,
// every replayed frame decoding intact.
TEST(Session, WriterKilledAtRandomMomentsLeavesReplayableSession) {
  std::mt19937 rng(1234);
  int withFrames = 0;
  // The kill moments scale with how long this build takes to write a session of 10 frames (a sanitizer
  // build is several times slower): from before the manifest lands to well past the 10th frame.
  const auto t0 = std::chrono::steady_clock::now();
  {
    const fs::path timing = freshDir("kill_timing");
    SessionWriter w(timing.string(), smallManifest(64, 48));
    for (int i = 0; i < 10; ++i) w.append(syntheticFrame(i, 64, 48));
    fs::remove_all(timing);
  }
  const int tenFramesUs = static_cast<int>(
      std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::steady_clock::now() - t0).count());
  for (int trial = 0; trial < 24; ++trial) {
    const fs::path dir = freshDir("kill" + std::to_string(trial));
    const pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      try {
        SessionWriter w(dir.string(), smallManifest(64, 48));
        for (int i = 0; i < 100000; ++i) w.append(syntheticFrame(i, 64, 48));
      } catch (...) {
      }
      _exit(0);
    }
    usleep(static_cast<useconds_t>(std::uniform_int_distribution<int>(tenFramesUs / 20, tenFramesUs * 3)(rng)));
    kill(pid, SIGKILL);
    int status = 0;
    waitpid(pid, &status, 0);
    if (!fs::exists(dir / "manifest.json")) {  // killed before the manifest landed: not a session yet
      expectCaptureError([&] { open(dir.string()); });
      fs::remove_all(dir);
      continue;
    }
    try {
      SessionSource s(dir.string());
      int64_t n = 0;
      while (auto f = s.next()) {
        const Frame ref = syntheticFrame(static_cast<int>(n), 64, 48);
        ASSERT_EQ(cv::norm(f->rgbd->colour, ref.rgbd->colour, cv::NORM_INF), 0.0)
            << "trial " << trial << " frame " << n;
        ++n;
      }
      EXPECT_EQ(n, s.frameCount());
      ++withFrames;
    } catch (const CaptureError& e) {
      EXPECT_NE(std::string(e.what()).find("no complete frame"), std::string::npos) << e.what();
    }
    fs::remove_all(dir);
  }
  EXPECT_GT(withFrames, 5) << "too few trials got past the first frame to test anything";
}

TEST(Session, BadInputsGiveOneLineErrorsNamingTheFile) {
  const fs::path dir = freshDir("bad");
  writeSession(dir, 3);
  // Each case corrupts a fresh copy of a good session.
  auto errorFor = [&](const std::function<void(const fs::path&)>& corrupt) {
    const fs::path copy = freshDir("badcopy");
    fs::copy(dir, copy, fs::copy_options::recursive);
    corrupt(copy);
    const std::string msg = expectCaptureError([&] {
      auto s = open(copy.string());
      while (s->next()) {
      }
    });
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    fs::remove_all(copy);
    return msg;
  };
  // Corrupt PNG.
  std::string m =
      errorFor([&](const fs::path& dir) { std::ofstream(dir / "colour/000001.png", std::ios::trunc) << "not a png"; });
  EXPECT_NE(m.find("colour/000001.png"), std::string::npos) << m;
  EXPECT_NE(m.find("cannot decode"), std::string::npos) << m;
  // Truncated PNG.
  m = errorFor([&](const fs::path& dir) { fs::resize_file(dir / "depth/000002.png", 40); });
  EXPECT_NE(m.find("depth/000002.png"), std::string::npos) << m;
  // Missing file.
  m = errorFor([&](const fs::path& dir) { fs::remove(dir / "colour/000000.png"); });
  EXPECT_NE(m.find("colour/000000.png: file is missing"), std::string::npos) << m;
  // Mismatched resolution.
  m = errorFor([&](const fs::path& dir) {
    cv::imwrite((dir / "colour/000001.png").string(), cv::Mat(10, 10, CV_8UC3, cv::Scalar(1, 2, 3)));
  });
  EXPECT_NE(m.find("manifest says 32x24"), std::string::npos) << m;
  // Non-monotonic timestamps.
  m = errorFor([&](const fs::path& dir) {
    std::ofstream f(dir / "frames.jsonl", std::ios::app);
    f << R"({"index":3,"t":0.1,"colour":"colour/000000.png","depth":"depth/000000.png"})"
      << "\n";
  });
  EXPECT_NE(m.find("frames.jsonl:4"), std::string::npos) << m;
  EXPECT_NE(m.find("does not increase"), std::string::npos) << m;
  // Unknown manifest version.
  m = errorFor([&](const fs::path& dir) {
    auto j = smallManifest().toJson();
    j["version"] = 99;
    std::ofstream(dir / "manifest.json", std::ios::trunc) << j.dump();
  });
  EXPECT_NE(m.find("manifest.json: unknown session version 99"), std::string::npos) << m;
  // Malformed manifest names the key.
  m = errorFor([&](const fs::path& dir) {
    auto j = smallManifest().toJson();
    j["colour"].erase("fx");
    std::ofstream(dir / "manifest.json", std::ios::trunc) << j.dump();
  });
  EXPECT_NE(m.find("missing key 'colour.fx'"), std::string::npos) << m;
  // Malformed JSON.
  m = errorFor([&](const fs::path& dir) { std::ofstream(dir / "manifest.json", std::ios::trunc) << "{ nope"; });
  EXPECT_NE(m.find("manifest.json: not valid JSON"), std::string::npos) << m;
  // Empty session.
  m = errorFor([&](const fs::path& dir) { std::ofstream(dir / "frames.jsonl", std::ios::trunc); });
  EXPECT_NE(m.find("no complete frame"), std::string::npos) << m;
  // NaN in a float depth file.
  m = errorFor([&](const fs::path& dir) {
    cv::Mat d(24, 32, CV_32FC1, cv::Scalar(1.0f));
    d.at<float>(5, 7) = std::numeric_limits<float>::quiet_NaN();
    cv::imwrite((dir / "depth/000000.tiff").string(), d);
    std::ofstream f(dir / "frames.jsonl", std::ios::trunc);
    f << R"({"index":0,"t":0.1,"colour":"colour/000000.png","depth":"depth/000000.tiff"})"
      << "\n";
  });
  EXPECT_NE(m.find("depth/000000.tiff: depth holds a non-finite"), std::string::npos) << m;
  // Not a session at all.
  m = expectCaptureError([&] { open((dir / "colour").string()); });
  EXPECT_NE(m.find("neither an mrgi session"), std::string::npos) << m;
  fs::remove_all(dir);
}

TEST(Session, WritingAFrameLeavesTheCallersImagesUntouched) {
  // PNG encoding converts RGB to OpenCV's BGR; it must do so into its own buffer, not the caller's.
  cv::Mat rgb(8, 8, CV_8UC3, cv::Scalar(10, 20, 30));
  const cv::Mat before = rgb.clone();
  const auto bytes = mrgi::capture::encodePng(rgb, "x.png");
  EXPECT_EQ(cv::norm(rgb, before, cv::NORM_INF), 0.0);
  const cv::Mat back = cv::imdecode(bytes, cv::IMREAD_COLOR);
  EXPECT_EQ(back.at<cv::Vec3b>(0, 0), cv::Vec3b(30, 20, 10));  // BGR in the file, RGB in memory
}

TEST(Session, FrameRatesOutsideWhatCanBeEncodedAreUnknown) {
  // Timestamps 1e-300 or 1e308 apart made FFmpeg print its own message before ours; no rate is known then.
  EXPECT_NEAR(mrgi::capture::medianRate({0.0, 1.0 / 30, 2.0 / 30, 3.0 / 30}), 30.0, 1e-9);
  EXPECT_EQ(mrgi::capture::medianRate({0.0, 1e-300, 2e-300}), 0.0);
  EXPECT_EQ(mrgi::capture::medianRate({0.0, 1e308}), 0.0);
  EXPECT_EQ(mrgi::capture::medianRate({5.0}), 0.0);
}
