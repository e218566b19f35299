// The settings mrgi starts itself again with (runtime/threads.h): each only where the environment leaves it unset.
#include "runtime/threads.h"

#include <gtest/gtest.h>

#include <map>

namespace mrgi::runtime {
namespace {

using Settings = std::vector<std::pair<std::string, std::string>>;

Settings settingsUnder(const std::map<std::string, std::string>& environment) {
  return processSettings([&](const char* name) -> std::optional<std::string> {
    const auto it = environment.find(name);
    return it == environment.end() ? std::nullopt : std::optional<std::string>(it->second);
  });
}

TEST(ProcessSettings, EachIsSetOnlyWhereTheEnvironmentLeavesItUnset) {
  const Settings both{{"OMP_WAIT_POLICY", "PASSIVE"}, {"GLIBC_TUNABLES", kGlibcTunables}};
  EXPECT_EQ(settingsUnder({}), both);
  EXPECT_EQ(settingsUnder({{"HOME", "/root"}}), both);
  // OpenMP's: either of its variables is the user's choice of how its threads behave.
  EXPECT_EQ(settingsUnder({{"OMP_WAIT_POLICY", "ACTIVE"}}), Settings({{"GLIBC_TUNABLES", kGlibcTunables}}));
  EXPECT_EQ(settingsUnder({{"OMP_NUM_THREADS", "1"}}), Settings({{"GLIBC_TUNABLES", kGlibcTunables}}));
  // The allocator's: any tunables the user set stand, whatever they tune.
  EXPECT_EQ(settingsUnder({{"GLIBC_TUNABLES", "glibc.malloc.arena_max=2"}}),
            Settings({{"OMP_WAIT_POLICY", "PASSIVE"}}));
  EXPECT_EQ(settingsUnder({{"GLIBC_TUNABLES", ""}}), Settings({{"OMP_WAIT_POLICY", "PASSIVE"}}));
  // Both set: nothing to do, and the program does not start again.
  EXPECT_TRUE(settingsUnder({{"OMP_WAIT_POLICY", "PASSIVE"}, {"GLIBC_TUNABLES", kGlibcTunables}}).empty());
}

}  // namespace
}  // namespace mrgi::runtime
