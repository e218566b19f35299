#pragma once
/// JSON from a user's file, parsed with a bounded nesting depth (a deeply nested document would otherwise
/// recurse until the stack runs out, in parsing or in any later copy) and one-line errors naming the file.
#include <istream>
#include <nlohmann/json.hpp>
#include <string>

namespace mrgi::capture {

/// Nesting deeper than this is refused; no mrgi file nests beyond 6 levels.
constexpr int kMaxJsonDepth = 64;

/// Parses `text`; throws InputError("<file>: not valid JSON: ..." or "...: nested deeper than 64 levels").
nlohmann::json parseJson(const std::string& text, const std::string& fileForErrors);
nlohmann::json parseJson(std::istream& in, const std::string& fileForErrors);
/// The JSON file at `path` (at most kMaxTextFileBytes; `kind` names it in errors, as readFileBounded's), parsed.
nlohmann::json readJsonFile(const std::string& path, const std::string& kind = "JSON file");

/// Typed access to one key of an object, every error naming the file and the key's path:
/// "<file>: missing key 'colour.fx'", "...: key 'colour.fx' must be a finite number",
/// "...: key 'frames' must be an integer", "...: key 'frames' is out of range (1e30)".
/// `path` is the prefix of the key in messages ("colour."). Never converts a number that does not fit
/// (nlohmann's get<int>() of 1e30 is undefined behaviour).
const nlohmann::json& jsonKey(const nlohmann::json& j, const std::string& key, const std::string& file,
                              const std::string& path = "");
double jsonNumber(const nlohmann::json& j, const std::string& key, const std::string& file,
                  const std::string& path = "");
int jsonInt(const nlohmann::json& j, const std::string& key, const std::string& file, const std::string& path = "");
std::string jsonString(const nlohmann::json& j, const std::string& key, const std::string& file,
                       const std::string& path = "");
/// The same, with `fallback` when the key is absent (a key present with the wrong type is still an error).
double jsonNumberOr(const nlohmann::json& j, const std::string& key, double fallback, const std::string& file,
                    const std::string& path = "");
int jsonIntOr(const nlohmann::json& j, const std::string& key, int fallback, const std::string& file,
              const std::string& path = "");
std::string jsonStringOr(const nlohmann::json& j, const std::string& key, const std::string& fallback,
                         const std::string& file, const std::string& path = "");

/// Outputs are checked too: a JSON document about to be printed or written must hold only finite numbers
/// (nlohmann writes nan as null). Throws InputError(where, "<problem> gives a non-finite <key path>") naming
/// the first one; `where` names the input the numbers came from.
void requireFiniteJson(const nlohmann::json& j, const std::string& where, const std::string& problem = "the input");

}  // namespace mrgi::capture
