// Knob tables, walked over the registry: every knob of the shared frame group and of each technique has a
// sane declaration, round-trips through a scene file, and out-of-range or mistyped values give one error
// naming the file and the key.
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "capture/checks.h"
#include "lighting/frame/frame.h"
#include "lighting/scene_file.h"
#include "lighting/techniques/registry.h"
#include "lighting/techniques/technique.h"

namespace mrgi::lighting {
namespace {

const char* kScenePath = MRGI_SOURCE_DIR "/recordings/scenes/knobs-test.json";

/// A JSON literal of a knob value of its type.
std::string literal(const KnobInfo& k, double v) {
  if (k.type == KnobType::Bool) return v != 0 ? "true" : "false";
  if (k.type == KnobType::Int) return std::to_string(static_cast<long long>(v));
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

std::string errorOf(const std::string& text) {
  try {
    parseScene(text, kScenePath);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "(accepted)";
}

TEST(Knobs, EveryDeclarationIsSane) {
  std::set<std::string> groups;
  for (const KnobGroup* g : knobGroups()) {
    EXPECT_TRUE(groups.insert(g->key).second) << "group key used twice: " << g->key;
    std::set<std::string> names;
    for (const KnobInfo& k : g->knobs) {
      const std::string where = g->key + "." + k.name;
      EXPECT_TRUE(names.insert(k.name).second) << where << " declared twice";
      EXPECT_LE(k.lo, k.hi) << where;
      EXPECT_TRUE(k.def >= k.lo && k.def <= k.hi) << where << " default " << k.def;
      EXPECT_FALSE(k.description.empty()) << where;
      for (const auto* values : {&k.sweep, &k.quickSweep})
        for (double v : *values) {
          EXPECT_TRUE(v >= k.lo && v <= k.hi) << where << " sweep value " << v;
          if (k.type != KnobType::Real) {
            EXPECT_EQ(v, std::floor(v)) << where << " sweep value " << v;
          }
        }
      if (k.type == KnobType::Bool) {
        EXPECT_TRUE(k.lo == 0 && k.hi == 1) << where;
      }
    }
  }
  // The frame's knobs may appear inside a technique's section (older files): no technique may reuse them.
  const KnobGroup& frame = frameKnobGroup();
  for (const TechniqueInfo& t : techniques())
    for (const KnobInfo& k : frame.knobs)
      EXPECT_EQ(t.knobs.find(k.name), nullptr) << t.name << " redeclares " << k.name;
}

TEST(Knobs, EveryKnobRoundTripsThroughASceneFile) {
  for (const KnobGroup* g : knobGroups())
    for (const KnobInfo& k : g->knobs) {
      const std::string where = g->key + "." + k.name;
      // A value other than the default: a sweep value, else the other end of the range.
      double v = k.def == k.hi ? k.lo : k.hi;
      for (double s : k.sweep)
        if (s != k.def) {
          v = s;
          break;
        }
      const std::string text = "{\"" + g->key + "\": {\"" + k.name + "\": " + literal(k, v) + "}}";
      const SceneDescription s = parseScene(text, kScenePath);
      EXPECT_EQ(s.knobs.at(g->key).at(k.name), v) << where;
      // Every other knob of every group keeps its default.
      for (const KnobGroup* other : knobGroups())
        for (const KnobInfo& o : other->knobs)
          if (other != g || o.name != k.name) {
            EXPECT_EQ(s.knobs.at(other->key).at(o.name), o.def) << where << " moved " << o.name;
          }
      // Out of the JSON and back: the used-knobs JSON of a choice using the group restores the value.
      KnobSet back;
      completeKnobs(back);
      TechniqueChoice all;
      for (const TechniqueInfo& t : techniques())
        if (t.knobs.key == g->key) all = parseTechniqueChoice(t.name, nullptr);
      applyKnobsJson(usedKnobsJson(all, s.knobs), back);
      EXPECT_EQ(back.at(g->key).at(k.name), v) << where;
    }
}

TEST(Knobs, OutOfRangeOrMistypedValuesNameTheFileAndTheKey) {
  for (const KnobGroup* g : knobGroups())
    for (const KnobInfo& k : g->knobs) {
      const std::string key = g->key + "." + k.name;
      std::vector<std::pair<std::string, std::string>> bad;  // literal, expected message part
      if (k.type == KnobType::Bool) {
        bad.push_back({"1", key + ": must be true or false"});
      } else {
        const double below = k.lo - (k.type == KnobType::Int ? 1 : std::max(1e-3, std::abs(k.lo)));
        const double above = k.hi + std::max(1.0, std::abs(k.hi));
        const std::string range =
            std::string(k.type == KnobType::Int ? ": must be an integer in [" : ": must be a finite number in [") +
            mrgi::capture::formatNumber(k.lo) + ", " + mrgi::capture::formatNumber(k.hi) + "], not ";
        bad.push_back({literal(k, below), key + range + mrgi::capture::formatNumber(below)});
        bad.push_back({literal(k, above), key + range + mrgi::capture::formatNumber(above)});
        bad.push_back({"\"x\"", key + ": must be"});
        if (k.type == KnobType::Int) bad.push_back({"2.5", key + ": must be an integer"});
      }
      for (const auto& [lit, expected] : bad) {
        const std::string e = errorOf("{\"" + g->key + "\": {\"" + k.name + "\": " + lit + "}}");
        EXPECT_NE(e.find(kScenePath), std::string::npos) << key << " = " << lit << " -> " << e;
        EXPECT_NE(e.find(expected), std::string::npos) << key << " = " << lit << " -> " << e;
        EXPECT_EQ(e.find('\n'), std::string::npos) << e;
      }
    }
}

TEST(Knobs, PresetKnobsByGroupAndOlderFlatOnes) {
  KnobSet knobs;
  completeKnobs(knobs);
  applyKnobsJson(nlohmann::json::parse(R"({"frame": {"rsm_size": 128}, "lpv": {"steps": 4}})"), knobs);
  EXPECT_EQ(knobs["frame"]["rsm_size"], 128);
  EXPECT_EQ(knobs["lpv"]["steps"], 4);
  // Flat, as presets written before the knob groups: each name goes to the one group declaring it.
  applyKnobsJson(nlohmann::json::parse(R"({"rsm_size": 64, "sparse_points": 256, "fusion": false})"), knobs);
  EXPECT_EQ(knobs["frame"]["rsm_size"], 64);
  EXPECT_EQ(knobs["val"]["sparse_points"], 256);
  EXPECT_EQ(knobs["val"]["fusion"], 0.0);
  EXPECT_THROW(applyKnobsJson(nlohmann::json::parse(R"({"warp": 1})"), knobs), std::invalid_argument);
  EXPECT_THROW(applyKnobsJson(nlohmann::json::parse(R"({"lpv": {"resolution": 4096}})"), knobs), std::invalid_argument);
  EXPECT_THROW(applyKnobsJson(nlohmann::json::parse(R"({"nope": {"resolution": 8}})"), knobs), std::invalid_argument);
}

}  // namespace
}  // namespace mrgi::lighting
