#include "app/commands.h"

namespace mrgi::app {
Action addSynth(CLI::App& app) {
  return [] { return 0; };
}
}  // namespace mrgi::app
