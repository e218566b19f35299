// NumPy arrays (depth in some public datasets): the first byte picks a bare .npy or an .npz archive (our
// zip reader, stored or deflated entries) from which "data.npy" is read as import-visp does.
#include "capture/npz.h"
#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  if (data[0] & 1) {
    const std::string path = mrgi::fuzz::scratchFile(data + 1, size - 1, ".npz");
    mrgi::fuzz::expectInputErrorOnly([&] { mrgi::capture::readNpzArray(path, "data.npy"); });
  } else {
    const std::string bytes(reinterpret_cast<const char*>(data + 1), size - 1);
    mrgi::fuzz::expectInputErrorOnly([&] { mrgi::capture::parseNpy(bytes, "array.npy"); });
  }
  return 0;
}
