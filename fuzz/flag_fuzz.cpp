// Every subcommand's flags: the input is an argv (split at NUL bytes, at most 64 arguments) parsed by the
// mrgi command line exactly as main does, validators included; nothing is run. A parse error is the
// expected outcome of bad flags; anything else (a crash, another exception, a hang) is reported.
#include <cstdint>
#include <string>
#include <vector>

#include "app/commands.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::vector<std::string> args{"mrgi"};
  std::string arg;
  for (size_t i = 0; i < size && args.size() < 64; ++i) {
    if (data[i] == 0) {
      args.push_back(arg);
      arg.clear();
    } else {
      arg += static_cast<char>(data[i]);
    }
  }
  if (!arg.empty() && args.size() < 64) args.push_back(arg);
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  // One command line for every input (building it anew took 10 ms an input), cleared of the last parse
  // first, so that each input is parsed as on its own.
  static CLI::App app{"mrgi"};
  static const auto actions = mrgi::app::addCommands(app);
  app.clear();
  try {
    app.parse(static_cast<int>(argv.size()), argv.data());
  } catch (const CLI::ParseError&) {
  }
  return 0;
}
