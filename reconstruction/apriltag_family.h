#pragma once
// Internal: libapriltag family tables by name (shared by marker images and the detector).
#include <string>
#include <utility>

extern "C" {
#include <apriltag/apriltag.h>
}

namespace mrgi::reconstruction::detail {

struct FamilyHandle {
  apriltag_family_t* family = nullptr;
  void (*destroy)(apriltag_family_t*) = nullptr;
  FamilyHandle() = default;
  FamilyHandle(const FamilyHandle&) = delete;
  FamilyHandle& operator=(const FamilyHandle&) = delete;
  FamilyHandle(FamilyHandle&& o) noexcept : family(o.family), destroy(o.destroy) { o.family = nullptr; }
  FamilyHandle& operator=(FamilyHandle&& o) noexcept {
    std::swap(family, o.family);
    std::swap(destroy, o.destroy);
    return *this;
  }
  ~FamilyHandle() {
    if (family) destroy(family);
  }
};

/// Throws std::invalid_argument naming the known families for an unknown name.
FamilyHandle createFamily(const std::string& name);

}  // namespace mrgi::reconstruction::detail
