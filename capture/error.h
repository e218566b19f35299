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

/// A flag's (or an option's) value that only the work behind it can judge (two flags together, a value against
/// the input): "<flag>: <problem>"; the command line exits 2 for it, as for a value its parser refused.
class FlagError : public std::runtime_error {
 public:
  FlagError(const std::string& flag, const std::string& problem) : std::runtime_error(flag + ": " + problem) {}
};

}  // namespace mrgi::capture
