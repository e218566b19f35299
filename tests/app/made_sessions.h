#pragma once
// Small synthetic sessions the app tests read (never write), made once per build of mrgi. ctest runs each test in a
// process of its own, and making a session in each took a run of mrgi synth per test (93 reproducer cases and some
// 40 Cli tests; 1-2 s each, twice that under ASan).
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace mrgi::test {

/// `mrgi synth <args> --out DIR` for the binary the tests run (MRGI_BINARY): DIR beside that binary, named `name` and
/// after the binary's size and time, so a rebuilt mrgi makes it again. The first process to need it makes it under a
/// temporary name and renames it into place; the others find it there. Returns DIR, empty when synth failed.
inline std::filesystem::path madeSession(const std::string& name, const std::string& args) {
  namespace fs = std::filesystem;
  const fs::path binary(MRGI_BINARY);
  const std::string prefix = name + "_";
  const std::string stamp = std::to_string(fs::file_size(binary)) + "_" +
                            std::to_string(fs::last_write_time(binary).time_since_epoch().count());
  const fs::path dir = binary.parent_path() / (prefix + stamp);
  if (fs::exists(dir / "frames.jsonl")) return dir;
  const fs::path made = dir.string() + ".making" + std::to_string(::getpid());
  std::error_code ec;
  fs::remove_all(made, ec);
  const std::string cmd = std::string(MRGI_BINARY) + " synth " + args + " --out " + made.string() + " > /dev/null 2>&1";
  if (std::system(cmd.c_str()) != 0) {
    fs::remove_all(made, ec);
    return {};
  }
  fs::rename(made, dir, ec);  // another process may have put its own there first: the same bytes
  if (ec) fs::remove_all(made, ec);
  // Those a former binary made go.
  for (const auto& e : fs::directory_iterator(binary.parent_path(), ec)) {
    const std::string file = e.path().filename().string();
    if (file.rfind(prefix, 0) == 0 && file.find(".making") == std::string::npos && e.path() != dir)
      fs::remove_all(e.path(), ec);
  }
  return dir;
}

}  // namespace mrgi::test
