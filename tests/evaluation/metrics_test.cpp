// The bench's measures on hand-made inputs: error sums against a known truth, flicker of an unchanged and of
// a changed delta, the Pareto front and presets, the sweep from the knob tables, and timing repeats that
// are full runs.
#include "evaluation/metrics.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "evaluation/bench.h"
#include "lighting/techniques/registry.h"
#include "tests/lighting/test_scene.h"

namespace mrgi::evaluation {
namespace {

/// A truth of w x h pixels: delta `d` on real pixels, radiance `v` on the virtual left column.
Truth truthOf(int w, int h, float d, float v) {
  Truth t;
  t.delta = cv::Mat(h, w, CV_32FC3, cv::Scalar::all(d));
  t.images.mask = cv::Mat(h, w, CV_8U, cv::Scalar(0));
  for (int y = 0; y < h; ++y) {
    t.delta.at<cv::Vec3f>(y, 0) = cv::Vec3f::all(v);
    t.images.mask.at<uchar>(y, 0) = 255;
  }
  return t;
}

/// A shading result like the pipeline's: rgb, a = 1 on virtual pixels (the left column).
cv::Mat shadeOf(int w, int h, float d, float v) {
  cv::Mat s(h, w, CV_32FC4, cv::Scalar(d, d, d, 0));
  for (int y = 0; y < h; ++y) s.at<cv::Vec4f>(y, 0) = {v, v, v, 1};
  return s;
}

TEST(Metrics, ErrorSumsAgainstAKnownTruth) {
  const Truth t = truthOf(8, 4, -0.2f, 0.5f);
  const ErrorSums exact = errorSums(shadeOf(8, 4, -0.2f, 0.5f), t);
  EXPECT_EQ(exact.relDelta(), 0.0);
  EXPECT_EQ(exact.relVirtual(), 0.0);
  EXPECT_EQ(exact.real, 28u);
  // 25 % too dark on real pixels, 10 % too bright on the object.
  const ErrorSums e = errorSums(shadeOf(8, 4, -0.25f, 0.55f), t);
  EXPECT_NEAR(e.relDelta(), 0.25, 1e-6);
  EXPECT_NEAR(e.relVirtual(), 0.1, 1e-6);
  EXPECT_NEAR(e.rmse(), 0.05, 1e-6);
  // A pixel virtual in one image only is left out and counted.
  cv::Mat s = shadeOf(8, 4, -0.2f, 0.5f);
  s.at<cv::Vec4f>(0, 3)[3] = 1;
  EXPECT_EQ(errorSums(s, t).mismatched, 1u);
  // Pixels the objects cover in part (the reference mixes them with what lies beside): left out of the real
  // and the virtual errors alike, whatever they hold, and counted.
  Truth mixed = t;
  mixed.delta = t.delta.clone();
  mixed.partial = cv::Mat(4, 8, CV_8UC1, cv::Scalar(0));
  mixed.partial.at<uchar>(1, 0) = mixed.partial.at<uchar>(1, 1) = 255;
  mixed.delta.at<cv::Vec3f>(1, 0) = mixed.delta.at<cv::Vec3f>(1, 1) = cv::Vec3f::all(9.f);
  const ErrorSums m = errorSums(shadeOf(8, 4, -0.2f, 0.5f), mixed);
  EXPECT_EQ(m.relDelta(), 0.0);
  EXPECT_EQ(m.relVirtual(), 0.0);
  EXPECT_EQ(m.partial, 2u);
  EXPECT_EQ(m.real, 27u);
  // Near the objects: only the real pixels whose surface point lies within 2 radii of their centre. Pixels
  // x < 2 sit 1 cm from it and carry the error; the others are 1 m away and exact.
  cv::Mat positions(4, 8, CV_32FC4), off = shadeOf(8, 4, -0.2f, 0.5f);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 8; ++x) {
      positions.at<cv::Vec4f>(y, x) = x < 2 ? cv::Vec4f(0.01f, 0, 0, 1) : cv::Vec4f(1, 0, 0, 1);
      if (x < 2 && off.at<cv::Vec4f>(y, x)[3] < 0.5f) off.at<cv::Vec4f>(y, x) = {-0.3f, -0.3f, -0.3f, 0.f};
    }
  NearObjects near{positions, {0, 0, 0}, 0.05, 2.0};
  const ErrorSums n = errorSums(off, t, &near);
  EXPECT_NEAR(n.relDeltaNear(), 0.5, 1e-6);  // 0.1 off a delta of 0.2
  EXPECT_LT(n.relDelta(), n.relDeltaNear());
  EXPECT_EQ(errorSums(off, t).relDeltaNear(), 0.0);  // none asked for
}

TEST(Metrics, TheRelativeErrorsIntervalHoldsItsExpectation) {
  // A delta of -0.2 everywhere and a result off it by |e| with e ~ N(0, 0.05): the relative L1 error's
  // expectation is E|e| / 0.2 = 0.05 sqrt(2 / pi) / 0.2. Over 40 seeds its 95 % interval holds it in most;
  // two frames narrow it by about sqrt 2; one block gives no width.
  const int W = 160, H = 128;
  const Truth t = truthOf(W, H, -0.2f, 0.5f);
  const double expected = 0.05 * std::sqrt(2 / CV_PI) / 0.2;
  int held = 0;
  double width1 = 0, width2 = 0;
  for (int seed = 0; seed < 40; ++seed) {
    cv::RNG rng(static_cast<uint64_t>(seed + 1));
    cv::Mat noise(H, W, CV_32FC3), noise2(H, W, CV_32FC3);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, 0.05);
    rng.fill(noise2, cv::RNG::NORMAL, 0.0, 0.05);
    cv::Mat a = shadeOf(W, H, -0.2f, 0.5f), b = a.clone();
    for (int y = 0; y < H; ++y)
      for (int x = 1; x < W; ++x)
        for (int c = 0; c < 3; ++c) {
          a.at<cv::Vec4f>(y, x)[c] += noise.at<cv::Vec3f>(y, x)[c];
          b.at<cv::Vec4f>(y, x)[c] += noise2.at<cv::Vec3f>(y, x)[c];
        }
    ErrorSums one = errorSums(a, t);
    EXPECT_EQ(one.blocks.size(), static_cast<size_t>(10 * 8));
    const auto i1 = one.relDeltaInterval();
    EXPECT_LE(i1[0], one.relDelta());
    EXPECT_GE(i1[1], one.relDelta());
    held += i1[0] <= expected && expected <= i1[1];
    width1 += i1[1] - i1[0];
    one.add(errorSums(b, t));
    const auto i2 = one.relDeltaInterval();
    width2 += i2[1] - i2[0];
  }
  EXPECT_GE(held, 34);  // 95 % of 40 is 38; a binomial's low tail
  EXPECT_GT(width1, 0);
  EXPECT_NEAR(width2 / width1, 1 / std::sqrt(2.0), 0.1);
  // The interval is about the block-to-block spread: per block |e|'s mean has sd 0.05 sqrt(1 - 2 / pi) /
  // sqrt(16 16 3), over 80 blocks; relative to 0.2, width 2 x 1.96 x that / sqrt(80).
  const double sd = 0.05 * std::sqrt(1 - 2 / CV_PI) / std::sqrt(16.0 * 16 * 3) / 0.2;
  EXPECT_NEAR(width1 / 40, 2 * 1.96 * sd / std::sqrt(80.0), 0.3 * 2 * 1.96 * sd / std::sqrt(80.0));
  // No blocks of real pixels beyond one: the interval is the value.
  const Truth small = truthOf(8, 4, -0.2f, 0.5f);
  const ErrorSums e = errorSums(shadeOf(8, 4, -0.25f, 0.55f), small);
  EXPECT_EQ(e.relDeltaInterval()[0], e.relDelta());
  EXPECT_EQ(e.relDeltaInterval()[1], e.relDelta());
}

TEST(Metrics, TwoNoisyReferencesGiveTheSquaredErrorWithoutTheirNoise) {
  // A known truth t (a smooth delta-like image), a result x = t + e with a known error pattern, and two
  // references r1, r2 = t + independent Gaussian noise far larger than e (as a few samples per pixel are).
  const int W = 320, H = 240;
  cv::Mat t(H, W, CV_32FC3), x(H, W, CV_32FC3), r1(H, W, CV_32FC3), r2(H, W, CV_32FC3), noise1(H, W, CV_32FC3),
      noise2(H, W, CV_32FC3);
  cv::RNG rng(7);
  rng.fill(noise1, cv::RNG::NORMAL, 0.0, 0.2);
  rng.fill(noise2, cv::RNG::NORMAL, 0.0, 0.3);
  double trueSq = 0, trueRef = 0;
  for (int y = 0; y < H; ++y)
    for (int i = 0; i < W; ++i) {
      const float v = -0.5f * std::exp(-((i - 160.f) * (i - 160.f) + (y - 120.f) * (y - 120.f)) / 4000.f) + 0.05f;
      const float e = 0.05f * std::sin(0.05f * i) * std::cos(0.07f * y);
      t.at<cv::Vec3f>(y, i) = {v, 0.8f * v, 0.6f * v};
      x.at<cv::Vec3f>(y, i) = t.at<cv::Vec3f>(y, i) + cv::Vec3f(e, e, e);
      for (int c = 0; c < 3; ++c) trueSq += e * e, trueRef += t.at<cv::Vec3f>(y, i)[c] * t.at<cv::Vec3f>(y, i)[c];
    }
  trueSq /= 3.0 * W * H;
  trueRef /= 3.0 * W * H;
  r1 = t + noise1;
  r2 = t + noise2;
  const mrgi::evaluation::UnbiasedError u = mrgi::evaluation::unbiasedSquaredError(x, r1, r2, cv::Mat());
  EXPECT_EQ(u.pixels, static_cast<size_t>(W * H));
  EXPECT_EQ(u.blocks, static_cast<size_t>(20 * 15));
  EXPECT_LE(u.meanSqLo, trueSq);
  EXPECT_GE(u.meanSqHi, trueSq);
  EXPECT_NEAR(u.meanSq, trueSq, 0.15 * trueSq);
  EXPECT_NEAR(u.refSq, trueRef, 0.02 * trueRef);
  EXPECT_NEAR(u.rel(), std::sqrt(trueSq / trueRef), 0.1 * std::sqrt(trueSq / trueRef));
  // Against one reference the squared error carries its noise variance (0.04): 30 times the true error.
  const double naive = cv::norm(x, r1, cv::NORM_L2SQR) / (3.0 * W * H);
  EXPECT_NEAR(naive, trueSq + 0.04, 0.002);
  // x equal to the truth: zero within the interval; a mask counts only its pixels.
  const mrgi::evaluation::UnbiasedError zero = mrgi::evaluation::unbiasedSquaredError(t, r1, r2, cv::Mat());
  EXPECT_LE(zero.meanSqLo, 0.0);
  EXPECT_GE(zero.meanSqHi, 0.0);
  EXPECT_LT(std::abs(zero.meanSq), 0.2 * trueSq);
  cv::Mat mask(H, W, CV_8UC1, cv::Scalar(0));
  mask(cv::Rect(0, 0, 40, 40)).setTo(255);
  EXPECT_EQ(mrgi::evaluation::unbiasedSquaredError(x, r1, r2, mask).pixels, 1600u);
  EXPECT_EQ(mrgi::evaluation::unbiasedSquaredError(x, r1, r2, mask).blocks, 9u);
}

TEST(Metrics, PresetsAreToldApartOnlyWhereTheirIntervalsDoNotOverlap) {
  auto record = [](double ms, double v, double lo, double hi) {
    return nlohmann::json{
        {"technique", "dlpv"},
        {"ms_lighting", ms},
        {"sessions", {{{"session", "s"}, {"rel_rms_delta_unbiased", {{"value", v}, {"lo", lo}, {"hi", hi}}}}}}};
  };
  nlohmann::json presets = {{"fast", record(10, 0.6, 0.5, 0.7)},
                            {"balanced", record(20, 0.3, 0.25, 0.35)},
                            {"accurate", record(40, 0.28, 0.2, 0.33)}};
  const nlohmann::json d = mrgi::evaluation::presetDifferences(presets);
  EXPECT_TRUE(d["fast_vs_balanced"]["resolved"].get<bool>());
  EXPECT_FALSE(d["balanced_vs_accurate"]["resolved"].get<bool>());
  EXPECT_EQ(d["balanced_vs_accurate"]["sessions"][0]["a"][0].get<double>(), 0.3);
  // The same record twice, or no intervals: nothing to say.
  presets["accurate"] = presets["balanced"];
  presets["fast"].erase("sessions");
  EXPECT_TRUE(mrgi::evaluation::presetDifferences(presets).empty());
}

TEST(Metrics, ShadowEnergyAndNearL1AgainstAKnownShadow) {
  // A flat table (positions on z = 0, the object of radius 0.1 at the origin), the reference's shadow a
  // smooth disc of darkening around it; a result with half of it: energy 0.5 and near L1 0.5 whatever the
  // reference's per-pixel noise (blurred out), and nothing counted beyond three radii or on the object.
  const int W = 200, H = 200;
  mrgi::evaluation::Truth truth;
  truth.images.mask = cv::Mat(H, W, CV_8UC1, cv::Scalar(0));
  truth.delta = cv::Mat(H, W, CV_32FC3, cv::Scalar::all(0));
  cv::Mat shade(H, W, CV_32FC4, cv::Scalar::all(0)), positions(H, W, CV_32FC4);
  cv::RNG rng(3);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const double px = (x - 100) * 0.003, py = (y - 100) * 0.003, r = std::hypot(px, py);  // 0.3 m across at the edge
      positions.at<cv::Vec4f>(y, x) = {static_cast<float>(px), static_cast<float>(py), 0.f, 1.f};
      if (r < 0.05) {  // the object itself
        truth.images.mask.at<uchar>(y, x) = 255;
        shade.at<cv::Vec4f>(y, x)[3] = 1.f;
        continue;
      }
      const float d = static_cast<float>(-0.4 * std::exp(-r * r / (2 * 0.08 * 0.08)));
      const float noise = static_cast<float>(rng.gaussian(0.002));
      truth.delta.at<cv::Vec3f>(y, x) = cv::Vec3f(d + noise, d + noise, d + noise);
      shade.at<cv::Vec4f>(y, x) = {0.5f * d, 0.5f * d, 0.5f * d, 0.f};
    }
  mrgi::evaluation::NearObjects near;
  near.positions = positions;
  near.radius = 0.1;
  near.radii = 3;
  const auto s = mrgi::evaluation::shadowSums(shade, truth, near);
  EXPECT_NEAR(s.energy(), 0.5, 0.01);
  EXPECT_NEAR(s.nearL1(), 0.5, 0.01);
  // The same shadow: energy 1, near L1 within the noise left after the blur.
  cv::Mat same = shade.clone();
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      if (same.at<cv::Vec4f>(y, x)[3] < 0.5f) {
        const float d = 2 * same.at<cv::Vec4f>(y, x)[0];
        same.at<cv::Vec4f>(y, x) = {d, d, d, 0.f};
      }
  const auto t = mrgi::evaluation::shadowSums(same, truth, near);
  EXPECT_NEAR(t.energy(), 1.0, 0.01);
  EXPECT_LT(t.nearL1(), 0.01);
  // Within one radius only fewer pixels count.
  near.radii = 1;
  EXPECT_LT(mrgi::evaluation::shadowSums(shade, truth, near).pixels, s.pixels);
}

TEST(Metrics, TheGalleryCropsAroundTheObjectsAndShowsEachTechnique) {
  cv::Mat mask(240, 320, CV_8UC1, cv::Scalar(0));
  cv::circle(mask, {200, 100}, 20, cv::Scalar(255), cv::FILLED);  // a box of 41 x 41 at (180, 80)
  EXPECT_EQ(mrgi::evaluation::galleryCrop(mask), cv::Rect(139, 39, 123, 123));
  EXPECT_EQ(mrgi::evaluation::galleryCrop(cv::Mat(240, 320, CV_8UC1, cv::Scalar(0))), cv::Rect(0, 0, 320, 240));
  cv::Mat nearEdge(240, 320, CV_8UC1, cv::Scalar(0));
  nearEdge(cv::Rect(300, 0, 20, 10)).setTo(255);
  EXPECT_EQ(mrgi::evaluation::galleryCrop(nearEdge), cv::Rect(280, 0, 40, 20));
  // The reference's shadow under the object, a technique with none: the reference's delta tile is black
  // there, the technique's mid grey.
  cv::Mat composite(240, 320, CV_8UC3, cv::Scalar(200, 180, 160)), delta(240, 320, CV_32FC3, cv::Scalar::all(0));
  cv::circle(delta, {200, 130}, 15, cv::Scalar::all(-0.5), cv::FILLED);
  cv::Mat none(240, 320, CV_32FC4, cv::Scalar::all(0));
  for (int y = 0; y < 240; ++y)
    for (int x = 0; x < 320; ++x) none.at<cv::Vec4f>(y, x)[3] = mask.at<uchar>(y, x) ? 1.f : 0.f;
  const cv::Mat g = mrgi::evaluation::galleryImage("test", composite, delta, mask,
                                                   {{"none", composite, none}, {"none again", composite, none}});
  ASSERT_EQ(g.type(), CV_8UC3);
  const int tile = 160;  // the 123-pixel crop, enlarged to 160
  EXPECT_EQ(g.cols, 8 + 3 * (2 * tile + 8 + 8));
  EXPECT_EQ(g.rows, 48 + 1 * (20 + tile + 8) + 8);
  // The shadow's centre (200, 130) is at (61, 91) in the crop, (79, 118) in a tile.
  const cv::Point refDelta(8 + tile + 8 + 79, 48 + 20 + 118),
      techDelta(8 + (2 * tile + 8 + 8) + tile + 8 + 79, 48 + 20 + 118);
  EXPECT_EQ(g.at<cv::Vec3b>(refDelta), cv::Vec3b(0, 0, 0));
  EXPECT_EQ(g.at<cv::Vec3b>(techDelta), cv::Vec3b(127, 127, 127));
}

TEST(Metrics, FlickerIsZeroForAnUnchangedDeltaAndRelativeOtherwise) {
  const int w = 16, h = 12;
  cv::Mat positions(h, w, CV_32FC4);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) positions.at<cv::Vec4f>(y, x) = {0.01f * (x - w / 2), 0.01f * (y - h / 2), 0.f, 1.f};
  capture::Intrinsics k{w, h, 10.0, 10.0, w / 2.0, h / 2.0};
  const capture::Pose T = capture::makePose(cv::Matx33d::eye(), {0, 0, -0.1});  // 10 cm in front of z = 0
  const FrameState a = frameState(shadeOf(w, h, -0.2f, 0.f), positions, T);
  const auto [n0, d0] = flickerSums(a, frameState(shadeOf(w, h, -0.2f, 0.f), positions, T), k);
  EXPECT_EQ(n0, 0.0);
  EXPECT_GT(d0, 0.0);
  const auto [n1, d1] = flickerSums(a, frameState(shadeOf(w, h, -0.3f, 0.f), positions, T), k);
  EXPECT_NEAR(n1 / d1, 0.5, 1e-5);  // |-0.3 - -0.2| / 0.2
}

TEST(Metrics, PresetsComeFromTheParetoFront) {
  auto rec = [](const char* t, double ms, double err) {
    return nlohmann::json{{"technique", t},
                          {"knobs", nlohmann::json::object()},
                          {"ms_lighting", ms},
                          {"rel_error_delta", err},
                          {"rel_error_virtual", err}};
  };
  const nlohmann::json records = {rec("a", 10, 0.5), rec("b", 20, 0.2), rec("c", 40, 0.1), rec("d", 50, 0.3),
                                  rec("e", 25, 0.15)};
  const nlohmann::json p = choosePresets(records);
  EXPECT_EQ(p["accurate"]["technique"], "c");  // least error
  EXPECT_EQ(p["fast"]["technique"], "b");      // fastest within twice the least error
  // Least ms/ms_min x err/err_min among the front's records more accurate than fast: e 3.75, c 4 (b's 4 and
  // a's 5 are not more accurate).
  EXPECT_EQ(p["balanced"]["technique"], "e");
  // With nothing more accurate than fast on the front, balanced is fast.
  const nlohmann::json two = choosePresets(nlohmann::json{rec("a", 10, 0.5), rec("b", 20, 0.2)});
  EXPECT_EQ(two["fast"]["technique"], "b");
  EXPECT_EQ(two["balanced"]["technique"], "b");
  // A front point 2 % more accurate than fast is no better within what a run resolves: balanced is the next.
  const nlohmann::json close = choosePresets(nlohmann::json{rec("a", 10, 0.2), rec("b", 12, 0.196), rec("c", 40, 0.1)});
  EXPECT_EQ(close["fast"]["technique"], "a");
  EXPECT_EQ(close["balanced"]["technique"], "c");
  EXPECT_TRUE(choosePresets(nlohmann::json::array()).empty());
}

// The cost the presets weigh is a frame's in replay over the room fused as the frames come (ms_replay): a
// configuration whose every-pass frame is dear but whose views are cheap wins where replay pays for views.
TEST(Metrics, PresetsWeighTheCostOfAFrameInReplay) {
  auto rec = [](const char* t, double everyPass, double replay, double err) {
    return nlohmann::json{{"technique", t},           {"knobs", nlohmann::json::object()},
                          {"ms_lighting", everyPass}, {"ms_replay", replay},
                          {"rel_error_delta", err},   {"rel_error_virtual", err}};
  };
  // "volume": dear to rebuild, cheap per view; "points": the reverse.
  const nlohmann::json records = {rec("points", 100, 90, 0.2), rec("volume", 400, 40, 0.2), rec("best", 800, 300, 0.1)};
  const nlohmann::json p = choosePresets(records);
  EXPECT_EQ(p["fast"]["technique"], "volume");
  EXPECT_EQ(p["accurate"]["technique"], "best");
  // Without the replay measure a record's cost is that of every pass: the same records then pick "points".
  nlohmann::json plain = records;
  for (auto& r : plain) r.erase("ms_replay");
  EXPECT_EQ(choosePresets(plain)["fast"]["technique"], "points");
}

// The moves that cost nothing are made together: from Kinect-VAL's sweep, those 10 % faster or more with the
// error within 1 % of the defaults', the fastest value per knob; a move that costs accuracy, one that saves
// too little and another technique's moves are left out; a technique with one free move gets no combination.
TEST(Metrics, FreeKnobMovesAreCombinedIntoOneConfiguration) {
  lighting::KnobSet base;
  lighting::completeKnobs(base);
  const std::vector<BenchConfig> all = sweepConfigs("", false, base);
  std::vector<BenchConfig> configs;
  nlohmann::json records = nlohmann::json::array();
  auto add = [&](const std::string& technique, const std::string& varied, double value, double ms, double err) {
    const auto it = std::find_if(all.begin(), all.end(), [&](const BenchConfig& c) {
      if (c.technique.name != technique || c.varied != varied) return false;
      if (varied.empty()) return true;
      const auto dot = varied.find('.');
      return c.knobs.at(varied.substr(0, dot)).at(varied.substr(dot + 1)) == value;
    });
    ASSERT_NE(it, all.end()) << technique << " " << varied << " " << value;
    configs.push_back(*it);
    records.push_back(
        {{"technique", technique}, {"ms_lighting", ms}, {"rel_error_delta", err}, {"rel_error_virtual", err}});
  };
  add("kinect-val", "", 0, 200, 0.25);
  add("kinect-val", "frame.rsm_size", 64, 170, 0.25);        // free
  add("kinect-val", "frame.rsm_size", 128, 175, 0.25);       // free, but 64 is faster
  add("kinect-val", "val.sparse_points", 256, 130, 0.2520);  // free: +0.8 %
  add("kinect-val", "val.stride", 8, 160, 0.2530);           // costs 1.2 %
  add("kinect-val", "val.occlusion", 0, 185, 0.25);          // saves 7.5 %: within the timing noise
  add("dlpv", "", 0, 600, 0.4);
  add("dlpv", "frame.rsm_size", 128, 450, 0.4);  // dlpv's only free move
  {
    const auto combined = combinedConfigs(configs, records);
    ASSERT_EQ(combined.size(), 1u);
    const BenchConfig& c = combined.front();
    EXPECT_EQ(c.technique.name, "kinect-val");
    EXPECT_EQ(c.varied, "combined");
    lighting::KnobSet expected = configs.front().knobs;
    expected["frame"]["rsm_size"] = 64;
    expected["val"]["sparse_points"] = 256;
    EXPECT_EQ(c.knobs, expected);
  }
  // A row at least 5 % more accurate than the defaults takes the free moves of the other knobs too (the most
  // accurate such row; a free move of its own knob is left out). DLPV's accurate row gets its one free move.
  add("kinect-val", "val.sparse_points", 4096, 400, 0.23);  // 8 % more accurate
  add("kinect-val", "val.stride", 2, 300, 0.24);            // 4 %: not enough
  add("dlpv", "lpv.resolution", 48, 900, 0.3);
  const auto combined = combinedConfigs(configs, records);
  ASSERT_EQ(combined.size(), 3u);
  EXPECT_EQ(combined[0].varied, "combined");
  EXPECT_EQ(combined[1].varied, "combined accurate");
  lighting::KnobSet expected = configs.front().knobs;
  expected["frame"]["rsm_size"] = 64;
  expected["val"]["sparse_points"] = 4096;
  EXPECT_EQ(combined[1].knobs, expected);
  EXPECT_EQ(combined[2].technique.name, "dlpv");
  EXPECT_EQ(combined[2].varied, "combined accurate");
  EXPECT_EQ(combined[2].knobs.at("frame").at("rsm_size"), 128);
  EXPECT_EQ(combined[2].knobs.at("lpv").at("resolution"), 48);
}

TEST(Metrics, TheSweepComesFromTheKnobTables) {
  lighting::KnobSet base;
  lighting::completeKnobs(base);
  const auto configs = sweepConfigs("", false, base);
  // Every technique's defaults, and every declared sweep value of its knobs and of the frame's.
  for (const auto& t : lighting::techniques()) {
    size_t expected = 1;
    for (const lighting::KnobGroup* g : {&lighting::frameKnobGroup(), &t.knobs})
      for (const auto& k : g->knobs)
        for (double v : k.sweep) expected += v != base.at(g->key).at(k.name);
    size_t got = 0;
    for (const auto& c : configs)
      if (c.technique == lighting::parseTechniqueChoice(t.name, nullptr) && c.technique.name == t.name) ++got;
    EXPECT_EQ(got, expected) << t.name;
  }
  for (const auto& c : configs) {
    if (c.varied.empty()) continue;
    const std::string group = c.varied.substr(0, c.varied.find('.')), knob = c.varied.substr(c.varied.find('.') + 1);
    EXPECT_NE(c.knobs.at(group).at(knob), base.at(group).at(knob)) << c.varied;
  }
}

TEST(GL, TimingRepeatsAreFullRuns) {
  auto ctx = test::makeContext();
  const test::TestScene s = test::makeScene(true, 0.15, {0, 0, 0.1});
  lighting::LightingPipeline pipe = test::makePipeline(test::testConfig(32, 24, 8, 32), s);
  std::map<std::string, int> runs;
  bestStages(pipe, test::topCamera(32, 24), 3, &runs);
  // Unchanged inputs would let every repeat after the first skip its stages; each must run every time.
  for (const char* stage : {"gbuffer", "shade"}) EXPECT_EQ(runs[stage], 3) << stage;
  for (const auto& [stage, n] : runs) EXPECT_EQ(n, 3) << stage;
}

}  // namespace
}  // namespace mrgi::evaluation
