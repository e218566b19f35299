#pragma once
/// JSON from a user's file, parsed with a bounded nesting depth (a deeply nested document would otherwise
/// recurse until the stack runs out, in parsing or in any later copy) and one-line errors naming the file.
#include <istream>
#include <string>

#include <nlohmann/json.hpp>

namespace mrgi::capture {

/// Nesting deeper than this is refused; no mrgi file nests beyond 6 levels.
constexpr int kMaxJsonDepth = 64;

/// Parses `text`; throws InputError("<file>: not valid JSON: ..." or "...: nested deeper than 64 levels").
nlohmann::json parseJson(const std::string& text, const std::string& fileForErrors);
nlohmann::json parseJson(std::istream& in, const std::string& fileForErrors);

}  // namespace mrgi::capture
