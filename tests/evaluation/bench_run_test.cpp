// The bench's harness (evaluation/bench_run.h) without the command line: a quick sweep of every technique on
// a small synthetic session against its path-traced references, its records, CSV, HTML report and presets.
#include "evaluation/bench_run.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>

#include "evaluation/synth.h"

namespace fs = std::filesystem;

namespace mrgi::evaluation {
namespace {

std::string readText(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

TEST(BenchRun, AQuickSweepMeasuresEveryTechniqueAndPairingAndPicksPresets) {
  const fs::path dir = fs::temp_directory_path() / ("mrgi_bench_run_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  SynthOptions so;
  so.out = (dir / "session").string();
  so.frames = 3;
  so.width = 160;
  so.height = 120;
  so.render = "raycast";
  so.fisheyeEvery = 2;
  ASSERT_EQ(writeSynthSession(so), 3);
  const std::string models = std::string(MRGI_SOURCE_DIR) + "/recordings/models/";
  std::ofstream(dir / "scene.json") << R"({"objects": [{"model": ")" << models
                                    << R"(sphere.ply", "translate": [0, 0, 0.06], "scale": 0.06}],
      "lights": "manifest", "lpv": {"resolution": 16, "steps": 8, "rsm_size": 128}})";
  BenchOptions o;
  o.quick = true;
  o.sessions = {so.out};
  o.scene = (dir / "scene.json").string();
  o.frames = 2;
  o.refFrames = 1;
  o.refSpp = 4;
  o.json = (dir / "b.json").string();
  o.csv = (dir / "b.csv").string();
  o.html = (dir / "b.html").string();
  o.presets = (dir / "presets.json").string();
  ASSERT_EQ(runBench(o), 0);
  const auto doc = nlohmann::json::parse(readText(o.json));
  std::set<std::string> techniques;
  for (const auto& rec : doc["records"]) {
    techniques.insert(rec["technique"].get<std::string>());
    for (const char* key : {"ms_total", "ms_lighting", "rmse_delta", "rel_error_delta", "rel_error_delta_near",
                            "rel_error_virtual", "ssim", "flicker", "gpu_mb"}) {
      ASSERT_TRUE(rec.contains(key)) << key;
      const double v = rec[key].get<double>();
      EXPECT_TRUE(std::isfinite(v) && v >= 0) << key << " " << v;
    }
    EXPECT_GT(rec["ms_lighting"].get<double>(), 0.0);
    // The cost in replay: per view over the session's fused room, the world-space rest once per refresh (30 frames).
    ASSERT_TRUE(rec.contains("ms_view") && rec.contains("ms_replay"));
    const double view = rec["ms_view"], every = rec["ms_lighting"];
    EXPECT_GT(view, 0.0);
    EXPECT_NEAR(rec["ms_replay"].get<double>(), view + std::max(every - view, 0.0) / 30.0, 1e-9);
    EXPECT_GT(rec["rel_error_virtual"].get<double>(), 0.0);  // a real-time approximation is never exact
    EXPECT_LT(rec["rel_error_virtual"].get<double>(), 1.0);
    EXPECT_GT(rec["ssim"].get<double>(), 0.8);
    EXPECT_LE(rec["ssim"].get<double>(), 1.0);
    EXPECT_GT(rec["gpu_mb"].get<double>(), 0.1);
    EXPECT_TRUE(rec["ms_stages"].contains("gbuffer"));
  }
  // Every technique and alias, and each pairing of a technique that serves real pixels with another one for
  // the virtual object (Kinect-VAL and precomputed illuminance composition serve the virtual object only).
  EXPECT_EQ(techniques,
            (std::set<std::string>{"dlpv", "lpv-diff", "kinect-val", "imperfect-volumes", "splatting", "pic",
                                   "dlpv+kinect-val", "dlpv+imperfect-volumes", "dlpv+splatting", "dlpv+pic",
                                   "imperfect-volumes+dlpv", "imperfect-volumes+kinect-val",
                                   "imperfect-volumes+splatting", "imperfect-volumes+pic", "splatting+dlpv",
                                   "splatting+kinect-val", "splatting+imperfect-volumes", "splatting+pic"}));
  // DLPV's propagation is world-space: over the fused room the views skip it, so a view costs less than a frame
  // with every pass rerun (which each record's session measures on its own depth mesh).
  for (const auto& rec : doc["records"])
    if (rec["technique"] == "dlpv" && rec["varied"] == "") {
      EXPECT_TRUE(rec["ms_stages"].contains("lpv.propagate"));
      EXPECT_LT(rec["ms_view"].get<double>(), 0.8 * rec["ms_lighting"].get<double>());
    }
  // A coarser volume costs less GPU memory than the defaults.
  double mbDefault = 0, mbCoarse = 0;
  for (const auto& rec : doc["records"])
    if (rec["technique"] == "dlpv" && rec["varied"] == "")
      mbDefault = rec["gpu_mb"];
    else if (rec["technique"] == "dlpv" && rec["varied"] == "lpv.resolution")
      mbCoarse = rec["gpu_mb"];
  EXPECT_LT(mbCoarse, mbDefault);
  const std::string csv = readText(o.csv);
  EXPECT_EQ(static_cast<size_t>(std::count(csv.begin(), csv.end(), '\n')), doc["records"].size() + 1);
  const std::string html = readText(o.html);
  EXPECT_NE(html.find("<svg"), std::string::npos);
  EXPECT_NE(html.find("data:image/png;base64,"), std::string::npos);
  EXPECT_EQ(html.find("src='http"), std::string::npos);  // self-contained
  // Presets: three, from the records, the fast one no slower than the accurate one.
  const auto presets = nlohmann::json::parse(readText(o.presets));
  for (const char* name : {"fast", "balanced", "accurate"}) ASSERT_TRUE(presets["presets"].contains(name)) << name;
  EXPECT_LE(presets["presets"]["fast"]["ms_replay"].get<double>(),
            presets["presets"]["accurate"]["ms_replay"].get<double>());
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mrgi::evaluation
