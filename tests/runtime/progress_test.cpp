// What a long command says of its progress (a bar on a terminal, a line per 10 % elsewhere, both with the time
// spent and, once the rate is known, the time left) and of what it wrote, and where its bundled defaults are.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "runtime/output.h"

using mrgi::runtime::progressText;

TEST(Progress, TheLineAndTheBarSayTheTimeSpentAndLeft) {
  EXPECT_EQ(progressText("room", 0.4, 12.3, 18.0, false), "room: 40 % (12 s, about 18 s left)");
  EXPECT_EQ(progressText("room", 1.0, 30.0, 0.0, false), "room: 100 % (30 s)");
  EXPECT_EQ(progressText("replay", 0.1, 2.0, -1.0, false), "replay: 10 % (2 s)");  // no rate yet
  EXPECT_EQ(progressText("room", 0.5, 10.0, 10.0, true),
            "room [####################....................]  50%  10 s, about 10 s left");
  // Out-of-range and non-finite input stays readable.
  EXPECT_EQ(progressText("x", 7.0, 1.0, 1.0, false), "x: 100 % (1 s)");
  EXPECT_EQ(progressText("x", std::nan(""), 1.0, std::nan(""), false), "x: 0 % (1 s)");
}

namespace mrgi::runtime {
namespace {

TEST(Output, BundledDataIsFoundFromAnyFolderAndAFolderIsDescribed) {
  // From a folder outside the checkout, a default path into recordings/ is found above the executable.
  const std::filesystem::path away =
      std::filesystem::temp_directory_path() / ("mrgi_bundled_" + std::to_string(::getpid()));
  std::filesystem::create_directories(away / "d");
  const std::filesystem::path before = std::filesystem::current_path();
  std::filesystem::current_path(away);
  const std::string scene = bundledPath("recordings/scenes/tabletop.json");
  const std::string missing = bundledPath("recordings/no-such-session");
  std::filesystem::current_path(before);
  EXPECT_TRUE(std::filesystem::path(scene).is_absolute()) << scene;
  EXPECT_TRUE(std::filesystem::exists(scene)) << scene;
  EXPECT_EQ(missing, "recordings/no-such-session");
  // What a folder holds, numbered files grouped.
  for (const char* f : {"frame_0000.png", "frame_0001.png", "frame_0002.png", "summary.json"})
    std::ofstream(away / f) << "x";
  EXPECT_EQ(describeFolder(away.string()), "d/, frame_NNNN.png x 3, summary.json");
  EXPECT_EQ(describeFolder((away / "none").string()), "");
  std::filesystem::remove_all(away);
}

}  // namespace
}  // namespace mrgi::runtime
