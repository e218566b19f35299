#include "capture/json_io.h"

#include <sstream>

#include "capture/error.h"

namespace mrgi::capture {

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
    std::string what = e.what();
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

}  // namespace mrgi::capture
