#include "runtime/threads.h"

#include <unistd.h>

#include <cstdlib>

namespace mrgi::runtime {
namespace {
std::optional<std::string> environmentValue(const char* name) {
  const char* value = std::getenv(name);
  return value ? std::optional<std::string>(value) : std::nullopt;
}

// The variables processSettings() reads, which processSettingsInEffect() reports.
constexpr const char* kOmpWaitPolicyName = "OMP_WAIT_POLICY";
constexpr const char* kOmpNumThreadsName = "OMP_NUM_THREADS";
constexpr const char* kGlibcTunablesName = "GLIBC_TUNABLES";
}  // namespace

std::vector<std::pair<std::string, std::string>> processSettings(
    const std::function<std::optional<std::string>(const char*)>& get) {
  std::vector<std::pair<std::string, std::string>> set;
  if (!get(kOmpWaitPolicyName) && !get(kOmpNumThreadsName)) set.emplace_back(kOmpWaitPolicyName, kOmpWaitPolicy);
  if (!get(kGlibcTunablesName)) set.emplace_back(kGlibcTunablesName, kGlibcTunables);
  return set;
}

void configureProcess(char** argv) {
  const auto settings = processSettings(environmentValue);
  if (settings.empty()) return;
  for (const auto& [name, value] : settings)
    if (setenv(name.c_str(), value.c_str(), 1) != 0) return;
  execv("/proc/self/exe", argv);  // only returns when it failed
}

nlohmann::json processSettingsInEffect() {
  nlohmann::json in = nlohmann::json::object();
  for (const char* name : {kOmpWaitPolicyName, kOmpNumThreadsName, kGlibcTunablesName}) {
    const auto value = environmentValue(name);
    in[name] = value ? nlohmann::json(*value) : nlohmann::json(nullptr);
  }
  return in;
}

}  // namespace mrgi::runtime
