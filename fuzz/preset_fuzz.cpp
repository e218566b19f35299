// Presets files as `--presets` reads them, applied to a scene.
#include "fuzz/fuzz_common.h"
#include "runtime/presets.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = mrgi::fuzz::scratchFile(data, size, ".json");
  mrgi::fuzz::expectInputErrorOnly([&] {
    for (const char* name : {"fast", "balanced", "accurate"}) {
      const nlohmann::json p = mrgi::runtime::loadPreset(path, name);
      mrgi::lighting::SceneDescription scene;
      mrgi::runtime::applyPreset(p, scene);
    }
  });
  return 0;
}
