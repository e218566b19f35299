// Session manifests (manifest.json): JSON with bounded depth, then every key checked, ground truth included.
#include "capture/json_io.h"
#include "capture/session.h"
#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  mrgi::fuzz::expectInputErrorOnly([&] {
    const nlohmann::json j = mrgi::capture::parseJson(text, "manifest.json");
    mrgi::capture::SessionManifest::fromJson(j, "manifest.json");
  });
  return 0;
}
