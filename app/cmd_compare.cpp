// mrgi compare: a replay's composites against a synthetic session's reference composites
// (evaluation/composite_compare.h), printed as a table or one JSON object.
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>

#include "app/commands.h"
#include "capture/error.h"
#include "evaluation/composite_compare.h"

namespace mrgi::app {

namespace {

struct CompareOptions {
  std::string session, replay;
  bool json = false;
};

/// Mean, and the half-width of its 95 % interval over the frames (Student's t; 0 for one frame).
std::pair<double, double> meanInterval(const std::vector<double>& v) {
  if (v.empty()) return {0, 0};
  double mean = 0;
  for (double x : v) mean += x;
  mean /= static_cast<double>(v.size());
  if (v.size() < 2) return {mean, 0};
  double ss = 0;
  for (double x : v) ss += (x - mean) * (x - mean);
  const double sd = std::sqrt(ss / static_cast<double>(v.size() - 1));
  // Two-sided 95 % quantiles of Student's t for 1-9 degrees of freedom; 1.96 beyond.
  static const double t[] = {12.71, 4.30, 3.18, 2.78, 2.57, 2.45, 2.36, 2.31, 2.26};
  const size_t dof = v.size() - 1;
  return {mean, (dof <= 9 ? t[dof - 1] : 1.96) * sd / std::sqrt(static_cast<double>(v.size()))};
}

int compare(const CompareOptions& o) {
  const std::vector<ComposedFrame> frames = compareComposites(o.session, o.replay);
  if (frames.empty())
    throw capture::CaptureError(o.replay, "no frame of this replay has a reference composite in " + o.session +
                                              "/reference (a session made by mrgi synth --scene)");
  std::vector<double> brightness, l1, side, shadow;
  for (const auto& f : frames)
    brightness.push_back(f.brightness), l1.push_back(f.relativeL1), side.push_back(f.brightestSide),
        shadow.push_back(f.shadowEnergy);
  const auto summary = [](const std::vector<double>& v) {
    const auto [m, h] = meanInterval(v);
    return nlohmann::json{{"mean", m},
                          {"interval_95", h},
                          {"min", *std::min_element(v.begin(), v.end())},
                          {"max", *std::max_element(v.begin(), v.end())}};
  };
  if (o.json) {
    nlohmann::json j = {{"session", o.session}, {"replay", o.replay}, {"frames", nlohmann::json::array()}};
    for (const auto& f : frames)
      j["frames"].push_back({{"frame", f.frame},
                             {"object_pixels", f.objectPixels},
                             {"brightness", f.brightness},
                             {"relative_l1", f.relativeL1},
                             {"brightest_side_radii", f.brightestSide},
                             {"shadow_energy", f.shadowEnergy},
                             {"reference_shadow", f.referenceShadow}});
    j["brightness"] = summary(brightness);
    j["relative_l1"] = summary(l1);
    j["brightest_side_radii"] = summary(side);
    j["shadow_energy"] = summary(shadow);
    std::printf("%s\n", j.dump().c_str());
    return 0;
  }
  std::printf(
      "| frame | object brightness, ours / reference | object relative L1 | brightest side apart (radii) | "
      "shadow darkening energy, ours / reference |\n|---|---|---|---|---|\n");
  for (const auto& f : frames)
    std::printf("| %d | %.3f | %.3f | %.2f | %.3f |\n", f.frame, f.brightness, f.relativeL1, f.brightestSide,
                f.shadowEnergy);
  const auto row = [&](const std::vector<double>& v, const char* fmt) {
    const auto [m, h] = meanInterval(v);
    char s[64];
    std::snprintf(s, sizeof s, fmt, m, h);
    return std::string(s);
  };
  std::printf("| mean, 95 %% interval | %s | %s | %s | %s |\n", row(brightness, "%.3f ± %.3f").c_str(),
              row(l1, "%.3f ± %.3f").c_str(), row(side, "%.2f ± %.2f").c_str(), row(shadow, "%.3f ± %.3f").c_str());
  return 0;
}

}  // namespace

Action addCompare(CLI::App& app) {
  auto o = std::make_shared<CompareOptions>();
  app.add_option("SESSION", o->session, "synthetic session with reference composites (mrgi synth --scene)")->required();
  app.add_option("REPLAY", o->replay, "replay output folder of the same session (mrgi replay --out)")->required();
  app.add_flag("--json", o->json, "print one JSON object (per frame, and each measure's mean, interval and range)");
  return [o] { return compare(*o); };
}

}  // namespace mrgi::app
