#include "capture/checks.h"

#include <algorithm>
#include <cctype>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string_view>
#include <vector>

#include "capture/error.h"

namespace fs = std::filesystem;

namespace mrgi::capture {

std::string formatNumber(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

std::string numberProblem(double v, double lo, double hi) {
  if (std::isfinite(v) && v >= lo && v <= hi) return {};
  const bool noLo = lo <= -DBL_MAX, noHi = hi >= DBL_MAX;
  std::string range;
  if (noLo && noHi)
    range = "a finite number";
  else if (noLo)
    range = "a finite number at most " + formatNumber(hi);
  else if (noHi)
    range = "a finite number of at least " + formatNumber(lo);
  else
    range = "a finite number in [" + formatNumber(lo) + ", " + formatNumber(hi) + "]";
  return "must be " + range + ", not " + formatNumber(v);
}

double checkNumber(double v, double lo, double hi, const std::string& where, const std::string& what) {
  const std::string problem = numberProblem(v, lo, hi);
  if (!problem.empty()) throw InputError(where, what.empty() ? problem : what + " " + problem);
  return v;
}

std::string rigidProblem(const Pose& T) {
  for (int i = 0; i < 16; ++i)
    if (!std::isfinite(T.val[i])) return "an entry is not finite";
  if (T(3, 0) != 0 || T(3, 1) != 0 || T(3, 2) != 0 || T(3, 3) != 1) return "its last row must be 0 0 0 1";
  const cv::Matx33d R = rotationOf(T);
  const double off = cv::norm(R.t() * R - cv::Matx33d::eye(), cv::NORM_INF);
  if (off > 1e-3) return "its rotation is not orthonormal (R^T R differs from I by " + formatNumber(off) + ")";
  if (cv::determinant(R) < 0) return "its rotation is a reflection (determinant -1)";
  for (int r = 0; r < 3; ++r)
    if (std::abs(T(r, 3)) > 1e6) return "its translation lies beyond 1e6 m";
  return {};
}

void checkRigid(const Pose& T, const std::string& where, const std::string& what) {
  const std::string problem = rigidProblem(T);
  if (!problem.empty()) throw InputError(where, what + " is not a rigid transform (" + problem + ")");
}

std::string tagProblem(const std::string& family) {
  std::string names;
  for (const TagFamily& f : kTagFamilies) {
    if (family == f.name) return {};
    names += (names.empty() ? "" : ", ") + std::string(f.name);
  }
  return "unknown tag family '" + excerpt(family, 40) + "' (" + names + ")";
}

std::string tagProblem(const std::string& family, int id) {
  for (const TagFamily& f : kTagFamilies)
    if (family == f.name)
      return id >= 0 && id < f.codes ? std::string()
                                     : "id " + std::to_string(id) + " is not one of " + family + "'s ids (0 to " +
                                           std::to_string(f.codes - 1) + ")";
  return tagProblem(family);
}

std::string directionProblem(const cv::Vec3d& d) {
  if (!std::isfinite(d[0]) || !std::isfinite(d[1]) || !std::isfinite(d[2])) return "must hold finite numbers";
  if (cv::norm(d) < 1e-9) return "must not be the zero vector";
  return {};
}

namespace {
std::string sizeText(std::uintmax_t bytes) {
  char buf[32];
  if (bytes >= (1ull << 30))
    std::snprintf(buf, sizeof buf, "%.1f GiB", static_cast<double>(bytes) / (1ull << 30));
  else if (bytes >= (1ull << 20))
    std::snprintf(buf, sizeof buf, "%.1f MiB", static_cast<double>(bytes) / (1ull << 20));
  else
    std::snprintf(buf, sizeof buf, "%ju bytes", bytes);
  return buf;
}
}  // namespace

std::uintmax_t checkFileBounded(const std::string& path, std::uintmax_t maxBytes, const std::string& kind) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec || !fs::exists(st)) throw InputError(path, "is missing");
  if (fs::is_directory(st)) throw InputError(path, "is a folder, not a " + kind);
  if (!fs::is_regular_file(st))
    throw InputError(path, "is not a regular file (a device, pipe or socket), not a " + kind);
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) throw InputError(path, "cannot read its size: " + ec.message());
  if (size > maxBytes)
    throw InputError(path, "is " + sizeText(size) + ", more than the " + sizeText(maxBytes) + " a " + kind + " may be");
  return size;
}

std::string readFileBounded(const std::string& path, std::uintmax_t maxBytes, const std::string& kind) {
  const std::uintmax_t size = checkFileBounded(path, maxBytes, kind);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open for reading");
  std::string bytes;
  bytes.reserve(static_cast<std::size_t>(size));
  char buf[1 << 16];
  // Read no more than the bound even if the file grew after it was checked.
  while (in && bytes.size() <= maxBytes) {
    in.read(buf, sizeof buf);
    bytes.append(buf, static_cast<size_t>(in.gcount()));
  }
  if (bytes.size() > maxBytes)
    throw InputError(path, "grew past the " + sizeText(maxBytes) + " a " + kind + " may be while it was read");
  return bytes;
}

std::string calibrationYamlShapeError(const std::string& text) {
  const auto isNumberChar = [](char c) {
    return (c >= '0' && c <= '9') || c == '.' || c == '-' || c == '+' || c == 'e' || c == 'E' || c == ',' || c == ' ';
  };
  int depth = 0;  // open '[' of a flow list running over lines
  bool started = false;
  std::size_t at = 0, number = 0;
  while (at < text.size()) {
    std::size_t end = text.find('\n', at);
    if (end == std::string::npos) end = text.size();
    std::string_view line(text.data() + at, end - at);
    at = end + 1;
    ++number;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const auto where = [&](const std::string& why) { return "line " + std::to_string(number) + ": " + why; };
    const std::size_t first = line.find_first_not_of(' ');
    if (first == std::string_view::npos || line[first] == '#') continue;
    std::string_view rest = line.substr(first);
    if (!started && depth == 0 && (rest.rfind("%YAML", 0) == 0 || rest == "---")) continue;
    started = true;
    // The value part, or the whole line inside a flow list.
    std::string_view value = rest;
    if (depth == 0) {
      std::size_t k = 0;
      while (k < rest.size() && (std::isalnum(static_cast<unsigned char>(rest[k])) || rest[k] == '_')) ++k;
      if (k == 0 || k >= rest.size() || rest[k] != ':' ||
          !(std::isalpha(static_cast<unsigned char>(rest[0])) || rest[0] == '_'))
        return where("not a 'key: value' line");
      value = rest.substr(k + 1);
      const std::size_t v = value.find_first_not_of(' ');
      value = v == std::string_view::npos ? std::string_view() : value.substr(v);
      if (value.rfind("!!opencv-matrix", 0) == 0) value.remove_prefix(15);
    }
    for (std::size_t k = 0; k < value.size(); ++k) {
      const char c = value[k];
      if (c == '#' && (k == 0 || value[k - 1] == ' ')) break;  // a comment to the end of the line
      if (c == '[') {
        if (++depth > 1) return where("a list inside a list");
      } else if (c == ']') {
        if (--depth < 0) return where("a ']' closes no list");
      } else if (depth > 0) {
        if (!isNumberChar(c)) return where("a list holds something other than numbers");
      } else if (c == '{' || c == '}' || c == '&' || c == '*' || c == '|' || c == '>' || c == '!' || c == '\t' ||
                 (k == 0 && (c == '-' || c == '?') && value.size() > 1 && value[1] == ' ')) {
        return where("'" + std::string(1, c) + "' (only plain values and lists of numbers)");
      } else if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) {
        return where("a character outside printable ASCII");
      }
    }
  }
  if (depth != 0) return "a list is not closed";
  return {};
}

int yamlNestingDepth(const std::string& text) {
  int deepest = 0, flow = 0;
  std::vector<std::size_t> indents;  // the block levels open at the current line
  std::size_t at = 0;
  while (at < text.size()) {
    std::size_t end = text.find('\n', at);
    if (end == std::string::npos) end = text.size();
    const std::string_view line(text.data() + at, end - at);
    at = end + 1;
    std::size_t i = line.find_first_not_of(" \t");
    if (i == std::string_view::npos || line[i] == '#') continue;
    int block = 0;
    if (flow == 0) {
      while (!indents.empty() && indents.back() >= i) indents.pop_back();
      indents.push_back(i);
      block = static_cast<int>(indents.size());
      // Compact nested sequences ("- - - x") open a level each.
      while (i + 1 < line.size() && line[i] == '-' && (line[i + 1] == ' ' || line[i + 1] == '\t')) {
        ++block;
        i = line.find_first_not_of(" \t", i + 1);
        if (i == std::string_view::npos) break;
      }
    }
    char quote = 0;
    for (std::size_t k = i == std::string_view::npos ? line.size() : i; k < line.size(); ++k) {
      const char c = line[k];
      if (quote) {
        if (c == '\\' && quote == '"')
          ++k;
        else if (c == quote)
          quote = 0;
        continue;
      }
      if (c == '"' || c == '\'')
        quote = c;
      else if (c == '#' && (k == 0 || line[k - 1] == ' ' || line[k - 1] == '\t'))
        break;
      else if (c == '[' || c == '{')
        deepest = std::max(deepest, block + ++flow);
      else if ((c == ']' || c == '}') && flow > 0)
        --flow;
    }
    deepest = std::max(deepest, block + flow);
  }
  return deepest;
}

std::string excerpt(const std::string& text, std::size_t maxChars) {
  std::string out;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const auto u = static_cast<unsigned char>(text[i]);
    if (out.size() >= maxChars && (u & 0xC0) != 0x80) {  // cut between characters, not inside one (UTF-8)
      out += "...";
      break;
    }
    out += (u < 0x20 || u == 0x7f) ? ' ' : text[i];
  }
  return out;
}

namespace {
/// Optimal string alignment distance (Damerau-Levenshtein without repeated edits of a substring), case ignored.
size_t editDistance(const std::string& a, const std::string& b) {
  const auto lower = [](char c) { return static_cast<char>(std::tolower(static_cast<unsigned char>(c))); };
  std::vector<std::vector<size_t>> d(a.size() + 1, std::vector<size_t>(b.size() + 1, 0));
  for (size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (size_t i = 1; i <= a.size(); ++i)
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t cost = lower(a[i - 1]) == lower(b[j - 1]) ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && lower(a[i - 1]) == lower(b[j - 2]) && lower(a[i - 2]) == lower(b[j - 1]))
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}
}  // namespace

std::string nearestSpelling(const std::string& word, const std::vector<std::string>& candidates) {
  if (word.empty() || word.size() > 200) return {};
  const size_t limit = std::clamp<size_t>(word.size() / 3, 1, 3);
  std::string best;
  size_t bestDistance = limit + 1;
  for (const std::string& c : candidates) {
    if (c == word) return {};
    if (c.size() > word.size() + limit || word.size() > c.size() + limit) continue;
    const size_t d = editDistance(word, c);
    if (d < bestDistance) bestDistance = d, best = c;
  }
  return best;
}

std::string didYouMean(const std::string& word, const std::vector<std::string>& candidates) {
  const std::string n = nearestSpelling(word, candidates);
  return n.empty() ? std::string() : " (did you mean '" + n + "'?)";
}

}  // namespace mrgi::capture
