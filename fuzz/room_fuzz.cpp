// Saved room models (mrgi room): room.json and room.ply from the input, split at its first two NUL bytes; then a
// 4-byte little-endian length, that many bytes of room_appearance.npy and the rest as room_openings.npy; loaded as
// replay --room does (our PLY check, then Open3D's PLY reader, every index checked, the appearance array against
// the mesh, the openings' cells).
#include <algorithm>
#include <cstdint>
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
  const auto write = [&](const char* name, std::string_view part) {
    std::ofstream(dir / name, std::ios::binary | std::ios::trunc)
        .write(part.data(), static_cast<std::streamsize>(part.size()));
  };
  for (const char* name : {"room.json", "room.ply"}) {
    const size_t nul = rest.find('\0');
    write(name, rest.substr(0, nul));
    rest = nul == std::string_view::npos ? std::string_view() : rest.substr(nul + 1);
  }
  uint32_t length = 0;
  if (rest.size() >= 4) {
    std::memcpy(&length, rest.data(), 4);
    rest.remove_prefix(4);
  }
  const size_t appearance = std::min<size_t>(length, rest.size());
  write("room_appearance.npy", rest.substr(0, appearance));
  write("room_openings.npy", rest.substr(appearance));
  mrgi::fuzz::expectInputErrorOnly([&] { mrgi::reconstruction::loadRoom(dir.string()); });
  return 0;
}
