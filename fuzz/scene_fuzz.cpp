// Scene files: objects, lights, techniques by role, every knob group (models resolve to missing files).
#include "fuzz/fuzz_common.h"
#include "lighting/scene_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  mrgi::fuzz::expectInputErrorOnly([&] { mrgi::lighting::parseScene(text, "/nonexistent/fuzz/scene.json"); });
  return 0;
}
