#pragma once
#include <stdexcept>
#include <string>

namespace mrgi::capture {

/// Bad input or a failed device, phrased for the user as one line: "<file or URI>: <problem>" (a path, a
/// device URI, "file: key"). Every library throws this one class for user errors.
class InputError : public std::runtime_error {
 public:
  InputError(const std::string& where, const std::string& problem) : std::runtime_error(where + ": " + problem) {}
};
/// The name the capture code uses.
using CaptureError = InputError;

}  // namespace mrgi::capture
