#include "runtime/session_setup.h"

#include "lighting/techniques/registry.h"
#include "runtime/presets.h"

namespace mrgi::runtime {

lighting::SceneDescription loadChosenScene(const SceneChoice& choice) {
  lighting::SceneDescription scene = lighting::loadScene(choice.scene);
  if (!choice.preset.empty()) applyPreset(loadPreset(choice.presets, choice.preset), scene);
  if (!choice.technique.empty()) scene.technique = lighting::parseTechniqueChoice(choice.technique, &scene.knobs);
  return scene;
}

}  // namespace mrgi::runtime
