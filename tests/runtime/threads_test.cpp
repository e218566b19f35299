// The settings mrgi starts itself again with (runtime/threads.h): each only where the environment leaves it unset.
#include "runtime/threads.h"

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <string>

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

// The minor page faults of allocating, touching and freeing `blocks` blocks of `mib` MiB, done once to warm the heap
// and then measured the second time.
long faultsOfAFrameAgain(int blocks, size_t mib) {
  const auto frame = [&] {
    std::vector<char*> held;
    for (int i = 0; i < blocks; ++i) {
      held.push_back(static_cast<char*>(std::malloc(mib << 20)));
      std::memset(held.back(), i + 1, mib << 20);
    }
    long sum = 0;
    for (char* p : held) sum += p[(mib << 20) - 1], std::free(p);
    return sum;
  };
  frame();
  rusage before{}, after{};
  getrusage(RUSAGE_SELF, &before);
  const long sum = frame();
  getrusage(RUSAGE_SELF, &after);
  return sum > 0 ? after.ru_minflt - before.ru_minflt : -1;
}

// Run by the test below in a process of its own started with the tunables (glibc reads them once, at start).
TEST(ProcessSettingsChild, AFrameAgain) {
  if (!std::getenv("MRGI_HEAP_CHILD")) GTEST_SKIP() << "run by ProcessSettings.TheHeapKeepsWhatAFrameFreed";
  std::printf("faults %ld\n", faultsOfAFrameAgain(12, 4));
}

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define MRGI_OWN_ALLOCATOR 1
#endif
#endif

// A frame's images (twelve 4 MiB maps) freed and taken again under kGlibcTunables come back from the heap without a
// page fault; under glibc's defaults (or hugetlb and one arena alone) the heap's free top past its trim threshold went
// back to the kernel and every page was faulted and zeroed again (about 24 huge pages or 12,000 small ones).
TEST(ProcessSettings, TheHeapKeepsWhatAFrameFreed) {
#ifdef MRGI_OWN_ALLOCATOR
  GTEST_SKIP() << "the sanitizer's allocator ignores glibc's tunables";
#endif
  char self[4096] = {};
  ASSERT_GT(readlink("/proc/self/exe", self, sizeof self - 1), 0);
  const std::string command = std::string("MRGI_HEAP_CHILD=1 GLIBC_TUNABLES=") + kGlibcTunables + " '" + self +
                              "' --gtest_filter=ProcessSettingsChild.AFrameAgain 2>&1";
  std::unique_ptr<FILE, int (*)(FILE*)> out(popen(command.c_str(), "r"), pclose);
  ASSERT_TRUE(out);
  long faults = -2;
  char line[512];
  while (std::fgets(line, sizeof line, out.get()))
    if (std::sscanf(line, "faults %ld", &faults) == 1) break;
  while (std::fgets(line, sizeof line, out.get())) {
  }
  EXPECT_GE(faults, 0);
  EXPECT_LE(faults, 4);
}

}  // namespace
}  // namespace mrgi::runtime
