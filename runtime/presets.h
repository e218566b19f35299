#pragma once
// Presets: a technique choice and its knobs by name (fast, balanced, accurate), as `mrgi bench --presets`
// writes them from the measured front; replay and live apply them to a scene.
#include <nlohmann/json.hpp>
#include <string>

#include "lighting/scene_file.h"

namespace mrgi::runtime {

/// Applies a preset record's technique and knobs to a scene (knobs by group; older flat knob objects too).
void applyPreset(const nlohmann::json& preset, lighting::SceneDescription& scene);
/// Loads preset `name` from a presets file written by `mrgi bench --presets`; errors name the file.
nlohmann::json loadPreset(const std::string& path, const std::string& name);

}  // namespace mrgi::runtime
