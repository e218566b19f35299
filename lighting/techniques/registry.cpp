#include "lighting/techniques/registry.h"

#include <stdexcept>

#include "capture/checks.h"
#include "lighting/frame/frame.h"
#include "lighting/techniques/technique.h"

namespace mrgi::lighting {

// Each technique's folder defines its entry; these lines are the registry.
TechniqueInfo dlpvTechniqueInfo();              // lighting/techniques/dlpv/
TechniqueInfo kinectValTechniqueInfo();         // lighting/techniques/kinect_val/
TechniqueInfo imperfectVolumesTechniqueInfo();  // lighting/techniques/imperfect_volumes/
TechniqueInfo splattingTechniqueInfo();         // lighting/techniques/splatting/
TechniqueInfo picTechniqueInfo();               // lighting/techniques/pic/

const std::vector<TechniqueInfo>& techniques() {
  static const std::vector<TechniqueInfo> all = {
      dlpvTechniqueInfo(),      kinectValTechniqueInfo(), imperfectVolumesTechniqueInfo(),
      splattingTechniqueInfo(), picTechniqueInfo(),
  };
  return all;
}

const TechniqueInfo* findTechnique(const std::string& name) {
  for (const TechniqueInfo& t : techniques())
    if (t.name == name) return &t;
  return nullptr;
}

const std::string& defaultTechniqueName() { return techniques().front().name; }

std::vector<const KnobGroup*> knobGroups() {
  std::vector<const KnobGroup*> out{&frameKnobGroup()};
  for (const TechniqueInfo& t : techniques()) out.push_back(&t.knobs);
  return out;
}

const KnobGroup* findKnobGroup(const std::string& key) {
  for (const KnobGroup* g : knobGroups())
    if (g->key == key) return g;
  return nullptr;
}

void completeKnobs(KnobSet& knobs) {
  for (const KnobGroup* g : knobGroups()) g->complete(knobs[g->key]);
}

std::vector<std::string> techniqueSpellings() {
  std::vector<std::string> out;
  for (const TechniqueInfo& t : techniques()) {
    out.push_back(t.name);
    for (const TechniqueAlias& a : t.aliases) out.push_back(a.name);
  }
  return out;
}

namespace {

std::string spellingList() {
  std::string s;
  for (const std::string& n : techniqueSpellings()) s += (s.empty() ? "" : ", ") + n;
  return s + ", \"REAL+VIRTUAL\" or {\"real\": ..., \"virtual\": ...} (\"none\" for no technique)";
}

/// One technique name or alias: its entry, alias knobs written into `knobs`. "none" gives nullptr.
const TechniqueInfo* resolve(const std::string& name, KnobSet* knobs) {
  if (name == "none") return nullptr;
  for (const TechniqueInfo& t : techniques()) {
    if (t.name == name) return &t;
    for (const TechniqueAlias& a : t.aliases)
      if (a.name == name) {
        if (knobs)
          for (const auto& [k, v] : a.knobs) (*knobs)[t.knobs.key][k] = v;
        return &t;
      }
  }
  throw std::invalid_argument("unknown technique '" + name + "'" + capture::didYouMean(name, techniqueSpellings()) +
                              " (expected " + spellingList() + ")");
}

}  // namespace

TechniqueChoice parseTechniqueRoles(const std::string& real, const std::string& virtualObject, KnobSet* knobs) {
  const TechniqueInfo* r = resolve(real, knobs);
  const TechniqueInfo* v = resolve(virtualObject, knobs);
  if (r && !r->real) throw std::invalid_argument("technique '" + real + "' cannot serve real pixels");
  if (v && !v->virtualObject)
    throw std::invalid_argument("technique '" + virtualObject + "' cannot serve the virtual object");
  TechniqueChoice c;
  c.real = r ? r->name : "none";
  c.virtualObject = v ? v->name : "none";
  c.name = canonicalName(c);
  return c;
}

TechniqueChoice parseTechniqueChoice(const std::string& spelling, KnobSet* knobs) {
  if (const size_t plus = spelling.find('+'); plus != std::string::npos) {
    TechniqueChoice c = parseTechniqueRoles(spelling.substr(0, plus), spelling.substr(plus + 1), knobs);
    c.name = spelling;
    return c;
  }
  const TechniqueInfo* t = resolve(spelling, knobs);
  TechniqueChoice c;
  if (t) {
    c.real = t->real ? t->name : "none";
    c.virtualObject = t->virtualObject ? t->name : "none";
  }
  c.name = spelling;
  return c;
}

std::string canonicalName(const TechniqueChoice& c) {
  const TechniqueInfo* r = findTechnique(c.real);
  const TechniqueInfo* v = findTechnique(c.virtualObject);
  if (r && v && r == v) return r->name;
  if (r && !v && !r->virtualObject) return r->name;
  if (v && !r && !v->real) return v->name;
  if (!r && !v) return "none";
  return c.real + "+" + c.virtualObject;
}

std::vector<RoleAssignment> assignRoles(const TechniqueChoice& c) {
  std::vector<RoleAssignment> out;
  auto add = [&](const std::string& name, bool real) {
    const TechniqueInfo* t = findTechnique(name);
    if (!t) return;
    for (RoleAssignment& a : out)
      if (a.info == t) {
        (real ? a.real : a.virtualObject) = true;
        return;
      }
    out.push_back({t, real, !real});
  };
  add(c.real, true);
  add(c.virtualObject, false);
  return out;
}

nlohmann::json usedKnobsJson(const TechniqueChoice& c, const KnobSet& knobs) {
  nlohmann::json out = nlohmann::json::object();
  auto add = [&](const KnobGroup& g) {
    const auto it = knobs.find(g.key);
    out[g.key] = g.toJson(it != knobs.end() ? it->second : g.defaults());
  };
  add(frameKnobGroup());
  for (const RoleAssignment& a : assignRoles(c)) add(a.info->knobs);
  return out;
}

void applyKnobsJson(const nlohmann::json& j, KnobSet& knobs) {
  if (!j.is_object()) throw std::invalid_argument("knobs must be an object");
  const KnobFail fail = [](const std::string& key, const std::string& problem) {
    throw std::invalid_argument(key + ": " + problem);
  };
  for (const auto& [key, value] : j.items()) {
    if (value.is_object()) {
      const KnobGroup* g = findKnobGroup(key);
      if (!g) throw std::invalid_argument("unknown knob group '" + key + "'");
      for (const auto& [name, v] : value.items()) {
        const KnobInfo* k = g->find(name);
        if (!k) throw std::invalid_argument("unknown knob '" + key + "." + name + "'");
        knobs[g->key][name] = g->read(*k, v, key + "." + name, fail);
      }
      continue;
    }
    const KnobGroup* owner = nullptr;
    for (const KnobGroup* g : knobGroups())
      if (g->find(key)) {
        if (owner) throw std::invalid_argument("knob '" + key + "' is ambiguous; write it inside its group");
        owner = g;
      }
    if (!owner) throw std::invalid_argument("unknown knob '" + key + "'");
    knobs[owner->key][key] = owner->read(*owner->find(key), value, owner->key + "." + key, fail);
  }
}

bool isTechniqueStage(const std::string& n) {
  for (const TechniqueInfo& t : techniques())
    for (const std::string& p : t.stagePrefixes)
      if (n.rfind(p, 0) == 0) return true;
  return false;
}

bool isLightingStage(const std::string& n) {
  return n == "gbuffer" || n == "rsm" || n == "shade" || n == "real_vals" || isTechniqueStage(n);
}

}  // namespace mrgi::lighting
