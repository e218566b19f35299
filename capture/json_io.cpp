#include "capture/json_io.h"

#include <cmath>
#include <limits>
#include <sstream>

#include "capture/checks.h"
#include "capture/error.h"

namespace mrgi::capture {

nlohmann::json readJsonFile(const std::string& path, const std::string& kind) {
  return parseJson(readFileBounded(path, kMaxTextFileBytes, kind), path);
}

nlohmann::json parseJson(const std::string& text, const std::string& file) {
  // The callback sees every value with its depth; refusing at the first one past the limit keeps both the
  // parser's own recursion and the document shallow.
  const nlohmann::json::parser_callback_t limit = [&file](int depth, nlohmann::json::parse_event_t, nlohmann::json&) {
    if (depth > kMaxJsonDepth)
      throw InputError(file, "not valid JSON: nested deeper than " + std::to_string(kMaxJsonDepth) + " levels");
    return true;
  };
  try {
    return nlohmann::json::parse(text, limit);
  } catch (const nlohmann::json::exception& e) {
    // In our words: the library's "[json.exception.parse_error.101] parse error at ..." without its tag; a
    // number past a double's range ("number overflow parsing '1e999'") said as such.
    std::string what = e.what();
    if (what.rfind("[json.exception.", 0) == 0 && what.find("] ") != std::string::npos)
      what = what.substr(what.find("] ") + 2);
    if (what.rfind("parse error ", 0) == 0) what = what.substr(12);  // "at line 1, column 5: ..."
    const size_t overflow = what.find("number overflow parsing '");
    if (overflow != std::string::npos) {
      const size_t start = overflow + 25, end = what.find('\'', start);
      what = "the number " + what.substr(start, end == std::string::npos ? std::string::npos : end - start) +
             " is too large (a double's range is about 1.8e308)";
    }
    for (char& c : what)
      if (c == '\n' || c == '\r') c = ' ';
    throw InputError(file, "not valid JSON: " + what);
  }
}

nlohmann::json parseJson(std::istream& in, const std::string& file) {
  std::stringstream ss;
  ss << in.rdbuf();
  return parseJson(ss.str(), file);
}

const nlohmann::json& jsonKey(const nlohmann::json& j, const std::string& key, const std::string& file,
                              const std::string& path) {
  if (!j.is_object() || !j.contains(key)) throw InputError(file, "missing key '" + path + key + "'");
  return j.at(key);
}

double jsonNumber(const nlohmann::json& j, const std::string& key, const std::string& file, const std::string& path) {
  const nlohmann::json& v = jsonKey(j, key, file, path);
  if (!v.is_number() || !std::isfinite(v.get<double>()))
    throw InputError(file, "key '" + path + key + "' must be a finite number");
  return v.get<double>();
}

int jsonInt(const nlohmann::json& j, const std::string& key, const std::string& file, const std::string& path) {
  const nlohmann::json& v = jsonKey(j, key, file, path);
  if (!v.is_number_integer()) throw InputError(file, "key '" + path + key + "' must be an integer");
  // Read as 64 bits and range-checked: 4294967297 must not wrap to 1.
  const bool fits = v.is_number_unsigned() ? v.get<uint64_t>() <= static_cast<uint64_t>(std::numeric_limits<int>::max())
                                           : v.get<int64_t>() >= std::numeric_limits<int>::min() &&
                                                 v.get<int64_t>() <= std::numeric_limits<int>::max();
  if (!fits) throw InputError(file, "key '" + path + key + "' is out of range (" + v.dump() + ")");
  return static_cast<int>(v.get<int64_t>());
}

std::string jsonString(const nlohmann::json& j, const std::string& key, const std::string& file,
                       const std::string& path) {
  const nlohmann::json& v = jsonKey(j, key, file, path);
  if (!v.is_string()) throw InputError(file, "key '" + path + key + "' must be a string");
  return v.get<std::string>();
}

double jsonNumberOr(const nlohmann::json& j, const std::string& key, double fallback, const std::string& file,
                    const std::string& path) {
  return j.is_object() && j.contains(key) ? jsonNumber(j, key, file, path) : fallback;
}

int jsonIntOr(const nlohmann::json& j, const std::string& key, int fallback, const std::string& file,
              const std::string& path) {
  return j.is_object() && j.contains(key) ? jsonInt(j, key, file, path) : fallback;
}

std::string jsonStringOr(const nlohmann::json& j, const std::string& key, const std::string& fallback,
                         const std::string& file, const std::string& path) {
  return j.is_object() && j.contains(key) ? jsonString(j, key, file, path) : fallback;
}

namespace {
bool firstNonFinite(const nlohmann::json& j, std::string& path) {
  if (j.is_number_float()) return !std::isfinite(j.get<double>());
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end(); ++it)
      if (firstNonFinite(it.value(), path)) {
        path = "." + it.key() + path;
        return true;
      }
  } else if (j.is_array()) {
    for (size_t i = 0; i < j.size(); ++i)
      if (firstNonFinite(j[i], path)) {
        path = "[" + std::to_string(i) + "]" + path;
        return true;
      }
  }
  return false;
}
}  // namespace

void requireFiniteJson(const nlohmann::json& j, const std::string& where, const std::string& problem) {
  std::string path;
  if (firstNonFinite(j, path))
    throw InputError(where,
                     problem + " gives a non-finite " + (path.empty() ? "value" : path.substr(path[0] == '.' ? 1 : 0)));
}

}  // namespace mrgi::capture
