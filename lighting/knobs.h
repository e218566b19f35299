#pragma once
/// Knobs, declared once: each technique (and the shared frame resources) lists its knobs in one table —
/// scene-file key, type, range, default, description, bench sweep values, and the member of its typed
/// struct. Scene-file parsing and its errors, summary.json, the bench sweep, presets and the live window's
/// sliders all read that table; nothing else spells a knob's range or default.
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <variant>
#include <vector>

namespace mrgi::lighting {

enum class KnobType { Int, Real, Bool };

struct KnobInfo {
  std::string name;  ///< scene-file key inside the group ("resolution")
  KnobType type = KnobType::Int;
  double lo = 0, hi = 1;  ///< inclusive range (Bool: 0..1)
  double def = 0;         ///< default
  std::string description;
  std::vector<double> sweep;       ///< values the bench tries one at a time around the defaults
  std::vector<double> quickSweep;  ///< the same for `mrgi bench --quick` (may be empty)
  bool logScale = false;           ///< sliders move logarithmically (sizes, counts)
};

/// Values of one knob group by name; after KnobGroup::complete every declared knob is present.
using KnobValues = std::map<std::string, double>;
/// Knob values of every group of a scene, by group key ("frame", "lpv", "val").
using KnobSet = std::map<std::string, KnobValues>;

/// Reports a bad knob value: (key path, problem). Must not return.
using KnobFail = std::function<void(const std::string& key, const std::string& problem)>;

/// A named section of a scene file ("lpv": {...}) and the knobs it holds.
struct KnobGroup {
  std::string key;
  std::vector<KnobInfo> knobs;

  const KnobInfo* find(const std::string& name) const;
  KnobValues defaults() const;
  /// Adds the default of every knob missing from `values`.
  void complete(KnobValues& values) const;
  /// Checks a value against the knob's type and range; the message names `keyPath` ("lpv.resolution").
  void check(const KnobInfo& k, double value, const std::string& keyPath, const KnobFail& fail) const;
  /// Reads one JSON value of knob `k` (number of the right kind, or true/false), checked.
  double read(const KnobInfo& k, const nlohmann::json& v, const std::string& keyPath, const KnobFail& fail) const;
  /// Every declared knob of `values` as JSON (integers as integers, booleans as booleans), in table order.
  nlohmann::json toJson(const KnobValues& values) const;
};

/// A typed knob struct's table: each knob with the member it sets.
template <class S>
struct KnobBinding {
  KnobInfo info;
  std::variant<int S::*, double S::*, bool S::*> member;
};

template <class S>
KnobGroup groupOf(const std::string& key, const std::vector<KnobBinding<S>>& table) {
  KnobGroup g{key, {}};
  for (const auto& b : table) g.knobs.push_back(b.info);
  return g;
}

/// The typed struct of a group's values (defaults for any that are missing).
template <class S>
S knobsFrom(const std::vector<KnobBinding<S>>& table, const KnobValues& values) {
  S s{};
  for (const auto& b : table) {
    const auto it = values.find(b.info.name);
    const double v = it != values.end() ? it->second : b.info.def;
    std::visit(
        [&](auto m) {
          using T = std::remove_reference_t<decltype(s.*m)>;
          if constexpr (std::is_same_v<T, bool>)
            s.*m = v != 0.0;
          else
            s.*m = static_cast<T>(v);
        },
        b.member);
  }
  return s;
}

/// The values of a typed struct.
template <class S>
KnobValues valuesOf(const std::vector<KnobBinding<S>>& table, const S& s) {
  KnobValues out;
  for (const auto& b : table) std::visit([&](auto m) { out[b.info.name] = static_cast<double>(s.*m); }, b.member);
  return out;
}

}  // namespace mrgi::lighting
