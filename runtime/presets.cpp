#include "runtime/presets.h"

#include <fstream>

#include "capture/checks.h"
#include "capture/error.h"
#include "capture/json_io.h"
#include "lighting/techniques/registry.h"

using nlohmann::json;

namespace mrgi::runtime {

void applyPreset(const json& preset, lighting::SceneDescription& scene) {
  const json& t = preset.at("technique");
  if (t.is_string())
    scene.technique = lighting::parseTechniqueChoice(t.get<std::string>(), &scene.knobs);
  else
    scene.technique = lighting::parseTechniqueRoles(t.value("real", "none"), t.value("virtual", "none"), &scene.knobs);
  lighting::applyKnobsJson(preset.at("knobs"), scene.knobs);
}

json loadPreset(const std::string& path, const std::string& name) {
  const json doc = capture::parseJson(capture::readFileBounded(path, capture::kMaxTextFileBytes, "presets file"), path);
  const json& presets = doc.contains("presets") ? doc["presets"] : doc;
  if (!presets.is_object() || !presets.contains(name))
    throw capture::CaptureError(path, "has no preset \"" + name + "\" (fast, balanced, accurate)");
  const json& p = presets[name];
  if (!p.contains("technique") || !p.contains("knobs") || !p["knobs"].is_object())
    throw capture::CaptureError(path, "preset \"" + name + "\" lacks technique or knobs");
  try {
    lighting::SceneDescription probe;
    applyPreset(p, probe);
  } catch (const std::exception& e) {
    throw capture::CaptureError(path, "preset \"" + name + "\": " + e.what());
  }
  return p;
}

}  // namespace mrgi::runtime
