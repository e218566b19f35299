#include "runtime/threads.h"

#include <unistd.h>

#include <cstdlib>

namespace mrgi::runtime {
namespace {
std::optional<std::string> environmentValue(const char* name) {
  const char* value = std::getenv(name);
  return value ? std::optional<std::string>(value) : std::nullopt;
}
}  // namespace

std::vector<std::pair<std::string, std::string>> processSettings(
    const std::function<std::optional<std::string>(const char*)>& get) {
  std::vector<std::pair<std::string, std::string>> set;
  if (!get("OMP_WAIT_POLICY") && !get("OMP_NUM_THREADS")) set.emplace_back("OMP_WAIT_POLICY", "PASSIVE");
  if (!get("GLIBC_TUNABLES")) set.emplace_back("GLIBC_TUNABLES", kGlibcTunables);
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
  for (const char* name : {"OMP_WAIT_POLICY", "OMP_NUM_THREADS", "GLIBC_TUNABLES"}) {
    const auto value = environmentValue(name);
    in[name] = value ? nlohmann::json(*value) : nlohmann::json(nullptr);
  }
  return in;
}

}  // namespace mrgi::runtime
