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

}  // namespace mrgi::app
