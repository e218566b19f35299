// mrgi: inserts virtual objects into live or recorded RGB-D footage with consistent lighting.
#include <csignal>
#include <cstdio>
#include <exception>
#include <map>
#include <opencv2/core.hpp>
#include <string>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "capture/checks.h"
#include "capture/image_io.h"
#include "capture/memory.h"
#include "runtime/threads.h"

namespace {
/// Every message ends as one printable line of bounded length: a library may quote a whole file.
std::string oneLine(const std::string& message) { return mrgi::capture::excerpt(message, 600); }
}  // namespace

int main(int argc, char** argv) {
  mrgi::runtime::shareCoresWithGl(argv);
  mrgi::capture::keepFrameMemory();
  CLI::App app{
      "mrgi: a mixed-reality compositor for RGB-D footage (differential rendering with real-time global illumination)"};
  const std::map<CLI::App*, mrgi::app::Action> actions = mrgi::app::addCommands(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);  // --help / --version
    if (argc > 1 && argv[1][0] != '-') {
      bool known = false;
      for (const auto* sub : app.get_subcommands({})) known |= sub->get_name() == argv[1];
      if (!known) {
        std::fprintf(stderr, "mrgi: unknown subcommand '%s' (see mrgi --help)\n", oneLine(argv[1]).c_str());
        return 2;
      }
    }
    // One line on stderr naming the problem.
    std::fprintf(stderr, "mrgi: %s (see mrgi --help)\n", oneLine(e.what()).c_str());
    return 2;
  }
  mrgi::capture::quietOpenCv();
  try {
    for (const auto& [sub, action] : actions)
      if (sub->parsed()) return action();
  } catch (const mrgi::app::FlagError& e) {
    std::fprintf(stderr, "mrgi: %s (see mrgi --help)\n", oneLine(e.what()).c_str());
    return 2;
  } catch (const cv::Exception& e) {
    std::fprintf(stderr, "mrgi: OpenCV: %s\n", oneLine(e.err).c_str());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mrgi: %s\n", oneLine(e.what()).c_str());
    return 1;
  }
  return 1;
}
