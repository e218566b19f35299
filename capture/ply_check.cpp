#include "capture/ply_check.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "capture/error.h"

namespace fs = std::filesystem;

namespace mrgi::capture {

/// PLY files are checked before assimp sees them: its reader loops forever on some malformed headers (an
/// element line without a count, found by the model fuzzer), and it accepts a body shorter than the header
/// promises (a truncated file) by reading what is there. Accepts the header grammar only: "ply", one format
/// line, comment/obj_info lines, "element NAME COUNT", "property TYPE NAME" or "property list TYPE TYPE
/// NAME", "end_header"; then the body must hold every element the header declares (ASCII: one line each;
/// binary: walked property by property, list lengths included).
void checkPlyFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  auto bad = [&](std::string why) {
    for (char& c : why)
      if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) c = '?';  // one printable line
    throw InputError(path, "malformed PLY header: " + why);
  };
  // A PLY file is one named .ply or one starting with "ply" (assimp recognises it by either): its first line
  // must then be exactly "ply" (a damaged one sent assimp's PLY reader into an endless loop of seeks; found
  // by the model fuzzer). Anything else is left to assimp.
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  char magic[3] = {};
  in.read(magic, 3);
  std::string first(magic, static_cast<size_t>(in.gcount()));
  for (char& c : first) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  const bool ply = ext == ".ply" || first == "ply";  // assimp matches the token in any case
  if (!ply) return;
  in.clear();
  in.seekg(0);
  if (!std::getline(in, line) || (line != "ply" && line != "ply\r")) bad("the first line is not 'ply'");
  static const std::map<std::string, int> kTypes{{"char", 1},  {"uchar", 1},  {"short", 2},   {"ushort", 2},
                                                 {"int", 4},   {"uint", 4},   {"float", 4},   {"double", 8},
                                                 {"int8", 1},  {"uint8", 1},  {"int16", 2},   {"uint16", 2},
                                                 {"int32", 4}, {"uint32", 4}, {"float32", 4}, {"float64", 8}};
  struct Property {
    int countBytes = 0, itemBytes = 0;  // countBytes > 0: a list
    bool indices = false;               // a face's vertex index list: every index must name a vertex
    bool signedItem = false;
  };
  struct Element {
    std::string name;
    uint64_t count = 0;
    std::vector<Property> properties;
    std::vector<std::string> names;
  };
  std::vector<Element> elements;
  std::string format;
  bool header = false;
  for (int n = 0; n < 10000 && std::getline(in, line); ++n) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream words(line);
    std::string word;
    words >> word;
    if (word == "end_header") {
      if (format.empty()) bad("no format line");
      header = true;
      break;
    }
    if (word == "comment" || word == "obj_info") continue;
    std::vector<std::string> rest;
    for (std::string w; words >> w;) rest.push_back(w);
    if (word == "format") {
      if (rest.size() != 2 ||
          (rest[0] != "ascii" && rest[0] != "binary_little_endian" && rest[0] != "binary_big_endian"))
        bad("format line '" + line + "'");
      format = rest[0];
    } else if (word == "element") {
      if (rest.size() != 2 || rest[1].empty() || rest[1].find_first_not_of("0123456789") != std::string::npos ||
          rest[1].size() > 10)
        bad("element line '" + line + "' needs a name and a count");
      // A name twice: readers bind to the first, this check would count the last (found by the room fuzzer:
      // a second, larger "vertex" element let face indices past Open3D's vertices through).
      for (const Element& e : elements)
        if (e.name == rest[0]) bad("element '" + rest[0].substr(0, 40) + "' declared twice");
      elements.push_back({rest[0], std::stoull(rest[1]), {}, {}});
    } else if (word == "property") {
      if (elements.empty()) bad("a property before any element");
      const bool list = !rest.empty() && rest[0] == "list";
      if (list ? (rest.size() != 4 || !kTypes.count(rest[1]) || !kTypes.count(rest[2]))
               : (rest.size() != 2 || !kTypes.count(rest[0])))
        bad("property line '" + line + "'");
      const std::string& name = rest.back();
      for (const std::string& other : elements.back().names)
        if (other == name) bad("property '" + name.substr(0, 40) + "' declared twice");
      elements.back().names.push_back(name);
      if (list && elements.back().name == "vertex" && (name == "x" || name == "y" || name == "z"))
        bad("vertex coordinate '" + name + "' declared as a list");
      Property prop = list ? Property{kTypes.at(rest[1]), kTypes.at(rest[2])} : Property{0, kTypes.at(rest[0])};
      if (list && elements.back().name == "face" && (rest[3] == "vertex_indices" || rest[3] == "vertex_index")) {
        if (rest[2] == "float" || rest[2] == "double" || rest[2] == "float32" || rest[2] == "float64")
          bad("face indices of type " + rest[2]);
        prop.indices = true;
        prop.signedItem = rest[2] == "char" || rest[2] == "short" || rest[2] == "int" || rest[2] == "int8" ||
                          rest[2] == "int16" || rest[2] == "int32";
      }
      elements.back().properties.push_back(prop);
    } else {
      bad("unexpected line '" + line.substr(0, 40) + "'");
    }
  }
  if (!header) bad("no end_header");
  // Readers index the vertex callbacks by coordinate: a vertex element without one of x, y, z (or with some
  // of a normal's or a colour's components and not the others) crashed Open3D's reader (found by the room
  // fuzzer: "property float x", "property float z").
  for (const Element& e : elements) {
    if (e.name != "vertex") continue;
    auto has = [&](const char* n) { return std::find(e.names.begin(), e.names.end(), n) != e.names.end(); };
    if (!has("x") || !has("y") || !has("z")) bad("a vertex element needs the properties x, y and z");
    for (const auto& group :
         {std::array<const char*, 3>{"nx", "ny", "nz"}, std::array<const char*, 3>{"red", "green", "blue"}}) {
      const int n = has(group[0]) + has(group[1]) + has(group[2]);
      if (n != 0 && n != 3)
        bad(std::string("a vertex element with some of ") + group[0] + ", " + group[1] + ", " + group[2] +
            " needs all three");
    }
  }
  uint64_t vertices = 0;
  for (const Element& e : elements)
    if (e.name == "vertex") vertices = e.count;
  // Readers index their vertex arrays with these before checking them (Open3D's ear clipping, found by the
  // room fuzzer; assimp's post-processing): every face has at least 3 indices, each naming a vertex.
  auto badFace = [&](uint64_t i, const std::string& why) {
    throw InputError(path, "malformed PLY: face " + std::to_string(i) + " " + why);
  };
  auto checkIndex = [&](uint64_t face, double v) {
    if (v >= 0 && v < static_cast<double>(vertices) && v == std::floor(v)) return;
    // Named as written: a value past long long (7.8e27, found by the room fuzzer) cannot be converted to one.
    char named[32] = "?";
    if (std::isfinite(v)) std::snprintf(named, sizeof named, "%.15g", v);
    badFace(face, "names vertex " + std::string(named) + " of " + std::to_string(vertices));
  };

  auto truncated = [&](const Element& e, uint64_t have) {
    throw InputError(path, "PLY file is truncated: the header declares " + std::to_string(e.count) + " " + e.name +
                               " elements, the file holds " + std::to_string(have));
  };
  if (format == "ascii") {
    for (const Element& e : elements) {
      if (e.properties.empty()) continue;
      for (uint64_t i = 0; i < e.count; ++i) {
        do {
          if (!std::getline(in, line)) truncated(e, i);
        } while (line.find_first_not_of(" \t\r") == std::string::npos);
        // The line must hold every property: one number each, a list its length and then that many.
        std::istringstream words(line);
        auto number = [&]() {
          std::string word;
          if (!(words >> word)) {
            if (in.peek() == EOF) truncated(e, i);  // the last line, cut short
            throw InputError(path,
                             "malformed PLY: " + e.name + " element " + std::to_string(i) + " has too few values");
          }
          char* end = nullptr;
          const double value = std::strtod(word.c_str(), &end);
          if (end == word.c_str() || *end != '\0' || !std::isfinite(value))
            throw InputError(path, "malformed PLY: " + e.name + " element " + std::to_string(i) + " holds '" +
                                       word.substr(0, 20) + "', not a number");
          return value;
        };
        for (const Property& p : e.properties) {
          const double first = number();
          if (p.countBytes > 0) {
            if (!(first >= 0 && first <= 1e6 && first == std::floor(first)))
              throw InputError(path, "malformed PLY: " + e.name + " element " + std::to_string(i) +
                                         " has a list length of " + std::to_string(first));
            if (p.indices && first < 3)
              badFace(i, "has " + std::to_string(static_cast<int>(first)) + " vertex indices (at least 3)");
            for (int k = 0; k < static_cast<int>(first); ++k) {
              const double v = number();
              if (p.indices) checkIndex(i, v);
            }
          }
        }
        // Readers take an ASCII body as one stream of numbers: a value too many on a line shifts every
        // element after it (found by the room fuzzer: a fifth vertex line of four numbers made the faces
        // after it two- and one-sided, and Open3D's normals read past its vertices).
        std::string extra;
        if (words >> extra)
          throw InputError(path, "malformed PLY: " + e.name + " element " + std::to_string(i) +
                                     " has more values than its properties");
      }
    }
    return;
  }
  const bool swap = format == "binary_big_endian";
  const std::string body{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  uint64_t at = 0;
  for (const Element& e : elements) {
    if (e.properties.empty()) continue;
    for (uint64_t i = 0; i < e.count; ++i)
      for (const Property& p : e.properties) {
        uint64_t items = 1;
        if (p.countBytes > 0) {
          if (at + static_cast<uint64_t>(p.countBytes) > body.size()) truncated(e, i);
          items = 0;
          for (int k = 0; k < p.countBytes; ++k)
            items |=
                uint64_t(static_cast<unsigned char>(body[at + static_cast<uint64_t>(swap ? p.countBytes - 1 - k : k)]))
                << (8 * k);
          at += static_cast<uint64_t>(p.countBytes);
        }
        if (items > body.size() || at + items * static_cast<uint64_t>(p.itemBytes) > body.size()) truncated(e, i);
        if (p.indices) {
          if (items < 3) badFace(i, "has " + std::to_string(items) + " vertex indices (at least 3)");
          for (uint64_t k = 0; k < items; ++k) {
            uint64_t raw = 0;
            for (int b = 0; b < p.itemBytes; ++b)
              raw |= uint64_t(static_cast<unsigned char>(body[at + k * static_cast<uint64_t>(p.itemBytes) +
                                                              static_cast<uint64_t>(swap ? p.itemBytes - 1 - b : b)]))
                     << (8 * b);
            double v = static_cast<double>(raw);
            if (p.signedItem && (raw >> (8 * p.itemBytes - 1)) & 1) v -= std::ldexp(1.0, 8 * p.itemBytes);
            checkIndex(i, v);
          }
        }
        at += items * static_cast<uint64_t>(p.itemBytes);
      }
  }
}

}  // namespace mrgi::capture
