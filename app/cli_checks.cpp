#include "app/cli_checks.h"

#include <cmath>
#include <cstdlib>

#include "capture/checks.h"

namespace mrgi::app {
namespace {

/// Whether the whole of text is a number (strtod's syntax, nan and inf included), read into v.
bool parseNumber(const std::string& text, double& v) {
  if (text.empty()) return false;
  char* end = nullptr;
  v = std::strtod(text.c_str(), &end);
  return end != text.c_str() && *end == '\0';
}

CLI::Validator rangeValidator(double lo, double hi, bool openLo) {
  const std::string range =
      std::string(openLo ? "(" : "[") + capture::formatNumber(lo) + ", " + capture::formatNumber(hi) + "]";
  return CLI::Validator(
      [lo, hi, openLo, range](std::string& value) -> std::string {
        double v = 0;
        if (!parseNumber(value, v)) return "'" + capture::excerpt(value, 40) + "' is not a number";
        std::string problem = capture::numberProblem(v, lo, hi);
        if (problem.empty() && openLo && v <= lo)
          problem = "must be a finite number in " + range + ", not " + capture::formatNumber(v);
        return problem;
      },
      "in " + range, "number");
}

constexpr const char* kAllowEmpty = "allow-empty";

bool emptyAllowed(CLI::Option* option) {
  try {
    option->get_validator(kAllowEmpty);
    return true;
  } catch (const CLI::OptionNotFound&) {
    return false;
  }
}

}  // namespace

void allowEmpty(CLI::Option* option) {
  option->check(CLI::Validator([](std::string&) { return std::string(); }, "", kAllowEmpty));  // a mark, checks nothing
}

CLI::Validator numberIn(double lo, double hi) { return rangeValidator(lo, hi, false); }
CLI::Validator numberAbove(double lo, double hi) { return rangeValidator(lo, hi, true); }

std::vector<double> parseNumbers(const std::string& text) {
  std::vector<double> out;
  size_t at = 0;
  while (true) {
    const size_t comma = text.find(',', at);
    const std::string item = text.substr(at, comma == std::string::npos ? std::string::npos : comma - at);
    double v = 0;
    if (!parseNumber(item, v)) throw FlagError("value", "'" + capture::excerpt(item, 40) + "' is not a number");
    out.push_back(v);
    if (comma == std::string::npos) break;
    at = comma + 1;
  }
  return out;
}

CLI::Validator numberList(int count, double lo, double hi, std::vector<std::string> words) {
  const std::string range = "[" + capture::formatNumber(lo) + ", " + capture::formatNumber(hi) + "]";
  std::string what =
      count == 1 ? "a number in " + range : std::to_string(count) + " comma-separated numbers in " + range;
  for (const std::string& w : words) what += " or " + w;
  return CLI::Validator(
      [count, lo, hi, words, what](std::string& value) -> std::string {
        for (const std::string& w : words)
          if (value == w) return {};
        std::vector<double> v;
        try {
          v = parseNumbers(value);
        } catch (const FlagError& e) {
          const std::string why = e.what();
          return why.substr(why.find(": ") + 2) + " (expected " + what + ")";  // "'x' is not a number (expected ...)"
        }
        if (static_cast<int>(v.size()) != count)
          return "expected " + what + ", not '" + capture::excerpt(value, 60) + "'";
        for (double x : v) {
          const std::string problem = capture::numberProblem(x, lo, hi);
          if (!problem.empty())
            return count == 1 ? problem : "each of the " + std::to_string(count) + " numbers " + problem;
        }
        return {};
      },
      what, "number list");
}

CLI::Validator tagFamily() {
  return CLI::Validator([](std::string& value) -> std::string { return capture::tagProblem(value); }, "FAMILY",
                        "tag family");
}

void checkTagId(const std::string& family, int id, const std::string& idFlag) {
  const std::string problem = capture::tagProblem(family, id);
  if (!problem.empty()) throw FlagError(idFlag, problem);
}

void checkEveryValue(CLI::App& app) {
  static const CLI::Validator finite(
      [](std::string& value) -> std::string {
        double v = 0;
        if (parseNumber(value, v) && !std::isfinite(v))
          return "must be a finite number, not " + capture::excerpt(value, 40);
        return {};
      },
      "", "finite");
  static const CLI::Validator nonEmpty(
      [](std::string& value) -> std::string { return value.empty() ? "must not be empty" : ""; }, "", "non-empty");
  // A newline or other control character in a value (a path above all: `--out $'a\nb'`) names a file no one
  // meant, and breaks every one-line message that quotes it.
  static const CLI::Validator printable(
      [](std::string& value) -> std::string {
        for (const char c : value)
          if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f)
            return "holds a control character (byte " + std::to_string(static_cast<unsigned char>(c)) +
                   "); a value must be printable";
        return {};
      },
      "", "printable");
  for (CLI::Option* opt : app.get_options()) {
    if (opt->get_items_expected_max() == 0) continue;  // flags take no value
    opt->check(printable);
    if (!emptyAllowed(opt)) opt->check(nonEmpty);
    if (opt->get_type_name().find("FLOAT") != std::string::npos) opt->check(finite);
  }
  for (CLI::App* sub : app.get_subcommands({})) checkEveryValue(*sub);
}

}  // namespace mrgi::app
