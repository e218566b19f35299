#pragma once
// Shared by the libFuzzer targets: a scratch file per process (tmpfs where there is one) for parsers that
// read files, and the rule every target enforces — bad input is an InputError (or, for OpenCV-decoded
// formats, a cv::Exception that the callers turn into one), never a crash, a hang or another exception.
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include "capture/error.h"

namespace mrgi::fuzz {

/// Where scratch files go: tmpfs where there is one.
inline const std::string& scratchRoot() {
  static const std::string dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
  return dir;
}

/// A per-process scratch folder of this name (created), for parsers that read a folder of files.
inline std::filesystem::path scratchDir(const std::string& name) {
  const std::filesystem::path d = std::filesystem::path(scratchRoot()) / (name + "_" + std::to_string(getpid()));
  std::filesystem::create_directories(d);
  return d;
}

/// Writes the input to a per-process scratch file with this extension and returns its path.
inline std::string scratchFile(const uint8_t* data, size_t size, const std::string& extension) {
  const std::string path = scratchRoot() + "/mrgi_fuzz_" + std::to_string(getpid()) + extension;
  std::ofstream(path, std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  return path;
}

/// Runs one parse: InputError is the expected outcome of bad input; anything else escapes and libFuzzer
/// reports it.
template <typename Fn>
void expectInputErrorOnly(Fn&& fn) {
  try {
    fn();
  } catch (const capture::InputError&) {
  }
}

}  // namespace mrgi::fuzz
