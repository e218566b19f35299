#pragma once
// Force-included into every C++ file (top-level CMakeLists.txt) before nlohmann/json.hpp can be.
//
// nlohmann-json leaves its preconditions to assert(), which release builds compile out: a const json's
// operator[] on a missing key then reads past the end of its map (undefined behaviour that crashes only with
// some heap layouts). Here every such precondition is checked in every build and throws std::logic_error, so
// a missing key is an error that names itself rather than a read of unrelated memory (inside nlohmann's
// noexcept functions, such as destructors, a failed check ends the process at once instead).
#include <stdexcept>

namespace mrgi::detail {
[[noreturn]] inline void jsonPreconditionFailed(const char* condition) {
  throw std::logic_error(std::string("JSON precondition failed: ") + condition);
}
}  // namespace mrgi::detail

#define JSON_ASSERT(x) ((x) ? static_cast<void>(0) : ::mrgi::detail::jsonPreconditionFailed(#x))
