// Model files through our loader (assimp with its validation and our index checks before post-processing).
// The first byte picks the format the rest is read as.
#include "fuzz/fuzz_common.h"
#include "lighting/scene_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static const char* kExtensions[] = {".ply", ".obj", ".gltf", ".glb"};
  const std::string path = mrgi::fuzz::scratchFile(data + 1, size - 1, kExtensions[data[0] % 4]);
  mrgi::fuzz::expectInputErrorOnly([&] { mrgi::lighting::loadMesh(path); });
  return 0;
}
