// NumPy .npy arrays (depth in some public datasets).
#include "capture/npz.h"
#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  mrgi::fuzz::expectInputErrorOnly([&] { mrgi::capture::parseNpy(bytes, "array.npy"); });
  return 0;
}
