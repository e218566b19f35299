// Saved room models (mrgi room): room.json, room.ply and room_appearance.npy from the input, split at the
// first two NUL bytes, then loaded as replay --room does (our PLY check, then Open3D's PLY reader, every
// index checked, then the appearance array against the mesh).
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string_view>

#include "fuzz/fuzz_common.h"
#include "reconstruction/room_model.h"

namespace fs = std::filesystem;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const fs::path dir = mrgi::fuzz::scratchDir("mrgi_fuzz_room");
  std::string_view rest(reinterpret_cast<const char*>(data), size);
  for (const char* name : {"room.json", "room.ply", "room_appearance.npy"}) {
    const size_t nul = std::string(name) == "room_appearance.npy" ? std::string_view::npos : rest.find('\0');
    const std::string_view part = rest.substr(0, nul);
    std::ofstream(dir / name, std::ios::binary | std::ios::trunc)
        .write(part.data(), static_cast<std::streamsize>(part.size()));
    rest = nul == std::string_view::npos ? std::string_view() : rest.substr(nul + 1);
  }
  mrgi::fuzz::expectInputErrorOnly([&] { mrgi::reconstruction::loadRoom(dir.string()); });
  return 0;
}
