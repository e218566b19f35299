#include <map>
#include <stdexcept>

#include "app/commands.h"
#include "lighting/techniques/registry.h"

namespace mrgi::app {

CLI::Validator techniqueValidator() {
  std::string names;
  for (const std::string& n : lighting::techniqueSpellings()) names += (names.empty() ? "" : "|") + n;
  return CLI::Validator(
      [](std::string& value) -> std::string {
        try {
          lighting::parseTechniqueChoice(value, nullptr);
        } catch (const std::invalid_argument& e) {
          return e.what();
        }
        return {};
      },
      "TECHNIQUE (" + names + " or REAL+VIRTUAL)", "technique");
}

CLI::Option* addPoseOption(CLI::App& app, runtime::PoseMode& mode) {
  std::map<std::string, runtime::PoseMode> modes;
  for (const std::string& name : runtime::poseModeNames()) modes.emplace(name, runtime::poseModeFromName(name));
  return app.add_option("--pose", mode, runtime::poseModeHelp())
      ->transform(CLI::CheckedTransformer(modes))
      ->option_text(std::string("MODE (marker|ground-truth|odometry|tracked; default ") + runtime::toString(mode) +
                    ")");
}

}  // namespace mrgi::app
