// Saved room models (mrgi room): room.json and room.ply from the input, split at the first NUL byte, then
// loaded as replay --room does (our PLY check, then Open3D's PLY reader, then every index checked).
#include <cstring>
#include <filesystem>
#include <fstream>

#include "fuzz/fuzz_common.h"
#include "reconstruction/room_model.h"

namespace fs = std::filesystem;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const fs::path dir = mrgi::fuzz::scratchDir("mrgi_fuzz_room");
  const auto* nul = static_cast<const uint8_t*>(std::memchr(data, 0, size));
  const size_t split = nul ? static_cast<size_t>(nul - data) : size;
  std::ofstream(dir / "room.json", std::ios::binary | std::ios::trunc).write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(split));
  const size_t rest = nul ? size - split - 1 : 0;
  std::ofstream(dir / "room.ply", std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(data) + split + (nul ? 1 : 0), static_cast<std::streamsize>(rest));
  mrgi::fuzz::expectInputErrorOnly([&] { mrgi::reconstruction::loadRoom(dir.string()); });
  return 0;
}
