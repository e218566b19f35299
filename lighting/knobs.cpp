#include "lighting/knobs.h"

#include <cmath>
#include <sstream>

#include "capture/checks.h"

namespace mrgi::lighting {

const KnobInfo* KnobGroup::find(const std::string& name) const {
  for (const KnobInfo& k : knobs)
    if (k.name == name) return &k;
  return nullptr;
}

KnobValues KnobGroup::defaults() const {
  KnobValues v;
  for (const KnobInfo& k : knobs) v[k.name] = k.def;
  return v;
}

void KnobGroup::complete(KnobValues& values) const {
  for (const KnobInfo& k : knobs) values.emplace(k.name, k.def);
}

void KnobGroup::check(const KnobInfo& k, double x, const std::string& keyPath, const KnobFail& fail) const {
  if (!std::isfinite(x)) fail(keyPath, "must be a finite number");
  if (k.type == KnobType::Int && x != std::floor(x)) fail(keyPath, "must be an integer");
  if (k.type == KnobType::Bool && x != 0.0 && x != 1.0) fail(keyPath, "must be true or false");
  if (x < k.lo || x > k.hi)
    fail(keyPath, std::string(k.type == KnobType::Int ? "must be an integer" : "must be a finite number") + " in [" +
                      capture::formatNumber(k.lo) + ", " + capture::formatNumber(k.hi) + "], not " +
                      capture::formatNumber(x));
}

double KnobGroup::read(const KnobInfo& k, const nlohmann::json& v, const std::string& keyPath,
                       const KnobFail& fail) const {
  double x = 0;
  switch (k.type) {
    case KnobType::Bool:
      if (!v.is_boolean()) fail(keyPath, "must be true or false");
      x = v.get<bool>() ? 1.0 : 0.0;
      break;
    case KnobType::Int:
      if (!v.is_number_integer()) fail(keyPath, "must be an integer");
      x = static_cast<double>(v.get<long long>());
      break;
    case KnobType::Real:
      if (!v.is_number()) fail(keyPath, "must be a number");
      x = v.get<double>();
      break;
  }
  check(k, x, keyPath, fail);
  return x;
}

nlohmann::json KnobGroup::toJson(const KnobValues& values) const {
  nlohmann::json out = nlohmann::json::object();
  for (const KnobInfo& k : knobs) {
    const auto it = values.find(k.name);
    if (it == values.end()) continue;
    switch (k.type) {
      case KnobType::Bool:
        out[k.name] = it->second != 0.0;
        break;
      case KnobType::Int:
        out[k.name] = static_cast<long long>(std::llround(it->second));
        break;
      case KnobType::Real:
        out[k.name] = it->second;
        break;
    }
  }
  return out;
}

}  // namespace mrgi::lighting
