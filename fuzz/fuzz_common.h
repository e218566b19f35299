#pragma once
// Shared by the libFuzzer targets: a scratch file per process (tmpfs where there is one) for parsers that
// read files, and the rule every target enforces — bad input is an InputError (or, for OpenCV-decoded
// formats, a cv::Exception that the callers turn into one), never a crash, a hang or another exception.
#include <unistd.h>

#include <cstdint>
#include <fstream>
#include <stdexcept>
#include <string>

#include "capture/error.h"

namespace mrgi::fuzz {

/// Writes the input to a per-process scratch file with this extension and returns its path.
inline std::string scratchFile(const uint8_t* data, size_t size, const std::string& extension) {
  static const std::string dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
  const std::string path = dir + "/mrgi_fuzz_" + std::to_string(getpid()) + extension;
  std::ofstream(path, std::ios::binary | std::ios::trunc).write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
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
