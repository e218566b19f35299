// NumPy .npy arrays: a well-formed array parses to its values; malformed shapes and dtypes (found by the npy
// fuzzer) are one-line errors naming the file, before anything is allocated for them.
#include "capture/npz.h"

#include <gtest/gtest.h>

#include "capture/error.h"

namespace mrgi::capture {
namespace {

/// A version-1 .npy: magic, header padded with spaces to a multiple of 16, then `data`.
std::string npy(const std::string& dict, const std::string& data) {
  std::string header = dict;
  while ((10 + header.size() + 1) % 16 != 0) header += ' ';
  header += '\n';
  std::string out("\x93NUMPY\x01\x00", 8);
  out += static_cast<char>(header.size() & 0xff);
  out += static_cast<char>(header.size() >> 8);
  return out + header + data;
}

std::string errorOf(const std::string& bytes) {
  try {
    parseNpy(bytes, "depth.npy");
  } catch (const CaptureError& e) {
    return e.what();
  }
  return "(accepted)";
}

TEST(Npy, ParsesAnUnsigned16BitArray) {
  const uint16_t values[6] = {1, 2, 3, 400, 500, 65535};
  const cv::Mat m = parseNpy(npy("{'descr': '<u2', 'fortran_order': False, 'shape': (2, 3), }",
                                 std::string(reinterpret_cast<const char*>(values), sizeof values)),
                             "depth.npy");
  ASSERT_EQ(m.type(), CV_16UC1);
  ASSERT_EQ(m.size(), cv::Size(3, 2));
  EXPECT_EQ(m.at<uint16_t>(1, 0), 400);
  EXPECT_EQ(m.at<uint16_t>(1, 2), 65535);
}

TEST(Npy, MalformedShapesAndDtypesAreOneLineErrors) {
  const std::pair<std::string, const char*> cases[] = {
      {npy("{'descr': '<u2', 'fortran_order': False, 'shape': (0, 3), }", ""), "dimension 0 out of range"},
      {npy("{'descr': '<u2', 'fortran_order': False, 'shape': (99999999999999999999, 3), }", ""), "out of range"},
      {npy("{'descr': '<u2', 'fortran_order': False, 'shape': (16777216, 16777216), }", "ab"), "truncated .npy data"},
      {npy("{'descr': '<u99999999999', 'fortran_order': False, 'shape': (2, 3), }", ""), "unsupported .npy dtype"},
      {npy("{'descr': '<\nu2', 'shape': (2, 3), }", ""), "unsupported .npy dtype in its header"},
  };
  for (const auto& [bytes, expected] : cases) {
    const std::string e = errorOf(bytes);
    EXPECT_EQ(e.rfind("depth.npy: ", 0), 0u) << e;
    EXPECT_NE(e.find(expected), std::string::npos) << e;
    EXPECT_EQ(e.find('\n'), std::string::npos) << e;
  }
}

}  // namespace
}  // namespace mrgi::capture
