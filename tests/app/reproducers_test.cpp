// Every class of bad input the reliability work reproduced from outside (tests/data/reproducers/cases.json),
// fed through the mrgi binary: exit 1-127 (never a signal), exactly one line on stderr naming the file, and no
// file changed outside --out (nor inside it when it held the user's files), no OpenCV temporary file left.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "made_sessions.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string readWhole(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void spit(const fs::path& p, const std::string& bytes) {
  fs::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary | std::ios::trunc) << bytes;
}

std::string replaceAll(std::string s, const std::string& from, const std::string& to) {
  for (size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size()))
    s.replace(at, from.size(), to);
  return s;
}

const json& cases() {
  static const json all =
      json::parse(readWhole(fs::path(MRGI_SOURCE_DIR) / "tests/data/reproducers/cases.json"))["cases"];
  return all;
}

/// One small synthetic session (2 frames, 160x120, a fisheye EXR on frame 0) that each case copies.
const fs::path& baseSession() {
  static const fs::path dir = [] {
    const fs::path d =
        mrgi::test::madeSession("repro_base", "--frames 2 --width 160 --height 120 --fisheye-every 2 --render raycast");
    EXPECT_FALSE(d.empty()) << "mrgi synth failed";
    return d;
  }();
  return dir;
}

/// Every regular file under root (except `skip`) with its bytes.
std::map<std::string, std::string> snapshot(const fs::path& root, const fs::path& skip) {
  std::map<std::string, std::string> files;
  for (auto it = fs::recursive_directory_iterator(root); it != fs::recursive_directory_iterator(); ++it) {
    if (!skip.empty() && it->path() == skip) {
      it.disable_recursion_pending();
      continue;
    }
    if (it->is_regular_file()) files[it->path().string()] = readWhole(it->path());
  }
  return files;
}

class Reproducer : public ::testing::TestWithParam<int> {};

TEST_P(Reproducer, IsOneLineNamingTheFileAndChangesNothingOutsideOut) {
  const json& c = cases()[GetParam()];
  SCOPED_TRACE(c["name"].get<std::string>());
  const fs::path root =
      fs::temp_directory_path() / ("mrgi_repro_" + std::to_string(::getpid()) + "_" + std::to_string(GetParam()));
  fs::remove_all(root);
  const fs::path session = root / "s", data = root / "data", out = root / "out";
  fs::create_directories(data);
  fs::copy(baseSession(), session, fs::copy_options::recursive);
  for (const char* sub : {"reproducers", "fuzz"})
    fs::copy(fs::path(MRGI_SOURCE_DIR) / "tests/data" / sub, data / sub, fs::copy_options::recursive);
  const std::string models = (fs::path(MRGI_SOURCE_DIR) / "recordings/models").string();
  for (const auto& e : fs::recursive_directory_iterator(data))
    if (e.path().extension() == ".json") spit(e.path(), replaceAll(readWhole(e.path()), "{models}", models));
  auto expand = [&](std::string s) {
    s = replaceAll(s, "{session}", session.string());
    s = replaceAll(s, "{data}", data.string());
    s = replaceAll(s, "{models}", models);
    return replaceAll(s, "{out}", out.string());
  };

  // The damage.
  if (c.contains("patch"))
    for (const auto& [target, patch] : c["patch"].items()) {
      const size_t hash = target.find('#');
      const fs::path file = session / target.substr(0, hash);
      if (hash == std::string::npos) {
        json doc = json::parse(readWhole(file));
        doc.merge_patch(patch);
        spit(file, doc.dump(2) + "\n");
      } else {
        const int line = std::stoi(target.substr(hash + 1));
        std::istringstream lines(readWhole(file));
        std::string text, l;
        for (int i = 0; std::getline(lines, l); ++i) {
          if (i == line) {
            json doc = json::parse(l);
            doc.merge_patch(patch);
            l = doc.dump();
          }
          text += l + "\n";
        }
        spit(file, text);
      }
    }
  if (c.contains("copy"))
    for (const auto& [target, source] : c["copy"].items())
      spit(session / target, readWhole(expand(source.get<std::string>())));
  if (c.contains("write"))
    for (const auto& [target, text] : c["write"].items()) spit(session / target, text.get<std::string>());
  if (c.contains("truncate"))
    for (const auto& [target, keep] : c["truncate"].items()) {
      const std::string bytes = readWhole(session / target);
      spit(session / target, bytes.substr(0, static_cast<size_t>(bytes.size() * keep.get<double>())));
    }
  if (c.contains("xor"))
    for (const auto& [target, at] : c["xor"].items()) {
      std::string bytes = readWhole(session / target);
      bytes[static_cast<size_t>(bytes.size() * at.get<double>())] ^= 0x5A;
      spit(session / target, bytes);
    }
  if (c.contains("make"))
    for (const auto& [target, text] : c["make"].items()) spit(expand(target), expand(text.get<std::string>()));
  if (c.contains("generate"))  // [head, unit, times, tail]: large inputs kept small in cases.json
    for (const auto& [target, g] : c["generate"].items()) {
      std::string text = g[0].get<std::string>();
      for (int i = 0; i < g[2].get<int>(); ++i) text += g[1].get<std::string>();
      spit(expand(target), text + g[3].get<std::string>());
    }

  const bool outIsInput = c.value("out_is_input", false);
  const auto before = snapshot(root, outIsInput ? fs::path() : out);
  // OpenCV's codecs that cannot decode from memory go through a temporary file in OPENCV_TEMP_PATH: a
  // private one here, which must stay empty.
  const fs::path temp = root / "opencv_temp";
  fs::create_directories(temp);
  const std::string cmd = "cd " + out.parent_path().string() + " && OPENCV_TEMP_PATH=" + temp.string() + " " +
                          std::string(MRGI_BINARY) + " " + expand(c["args"]) + " > " + (root / "stdout").string() +
                          " 2> " + (root / "stderr").string();
  const int status = std::system(cmd.c_str());
  const std::string err = readWhole(root / "stderr");
  fs::remove(root / "stdout");
  fs::remove(root / "stderr");
  ASSERT_FALSE(WIFSIGNALED(status)) << err;
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  EXPECT_GE(code, 1) << err;
  EXPECT_LE(code, 127) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_NE(err.find(expand(c["names"])), std::string::npos) << err;
  if (c.contains("says")) {
    EXPECT_NE(err.find(c["says"].get<std::string>()), std::string::npos) << err;
  }
  if (c.contains("exit")) {
    EXPECT_EQ(code, c["exit"].get<int>()) << err;  // 2: a bad flag
  }
  EXPECT_LE(err.size(), expand(c["names"]).size() + 700) << "a short line";
  const auto after = snapshot(root, outIsInput ? fs::path() : out);
  EXPECT_EQ(after.size(), before.size());
  for (const auto& [path, bytes] : before) {
    const auto it = after.find(path);
    EXPECT_TRUE(it != after.end() && it->second == bytes) << path << " changed or vanished";
  }
  EXPECT_TRUE(fs::is_empty(temp)) << "a temporary file of OpenCV's was used";
  fs::remove_all(root);
}

std::string caseName(const ::testing::TestParamInfo<int>& info) {
  std::string name;
  for (char ch : cases()[info.param]["name"].get<std::string>())
    name += std::isalnum(static_cast<unsigned char>(ch)) ? ch : '_';
  return std::to_string(info.param) + "_" + name;
}

INSTANTIATE_TEST_SUITE_P(Cases, Reproducer, ::testing::Range(0, static_cast<int>(cases().size())), caseName);

}  // namespace
