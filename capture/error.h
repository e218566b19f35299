#pragma once
#include <stdexcept>
#include <string>

namespace mrgi::capture {

/// Bad input or a failed device, phrased for the user as one line: "<file or URI>: <problem>".
class CaptureError : public std::runtime_error {
 public:
  CaptureError(const std::string& where, const std::string& problem)
      : std::runtime_error(where + ": " + problem) {}
};

}  // namespace mrgi::capture
