#include "reconstruction/marker_image.h"

#include <gtest/gtest.h>

#include "capture/checks.h"
#include "reconstruction/apriltag_family.h"

TEST(MarkerImage, Tag36h11HasBordersFromTheLibrary) {
  mrgi::reconstruction::TagLayout layout{};
  const cv::Mat tag = mrgi::reconstruction::renderTag("tag36h11", 0, &layout);
  EXPECT_EQ(layout.totalCells, 10);
  EXPECT_EQ(layout.borderCells, 8);
  ASSERT_EQ(tag.rows, 10);
  for (int i = 0; i < 10; ++i) {
    EXPECT_EQ(tag.at<uchar>(0, i), 255);  // white outer border
    if (i >= 1 && i <= 8) {
      EXPECT_EQ(tag.at<uchar>(1, i), 0);  // black border
    }
  }
  EXPECT_NE(cv::norm(tag, mrgi::reconstruction::renderTag("tag36h11", 1), cv::NORM_L1), 0.0);
  EXPECT_THROW(mrgi::reconstruction::renderTag("tag36h11", 587), std::invalid_argument);
  EXPECT_THROW(mrgi::reconstruction::renderTag("tagNope", 0), std::invalid_argument);
}

TEST(TagFamilies, TheFamiliesFlagsAndManifestsAcceptAreLibapriltagsWithItsIdCounts) {
  // capture::kTagFamilies checks --family / --id and manifests before any work; it must agree with the
  // detector's library, family by family.
  for (const mrgi::capture::TagFamily& f : mrgi::capture::kTagFamilies) {
    const auto handle = mrgi::reconstruction::detail::createFamily(f.name);
    ASSERT_NE(handle.family, nullptr) << f.name;
    EXPECT_EQ(static_cast<int>(handle.family->ncodes), f.codes) << f.name;
    EXPECT_EQ(mrgi::capture::tagProblem(f.name, f.codes - 1), "") << f.name;
    EXPECT_NE(mrgi::capture::tagProblem(f.name, f.codes), "") << f.name;
    EXPECT_NE(mrgi::capture::tagProblem(f.name, -1), "") << f.name;
  }
  EXPECT_NE(mrgi::capture::tagProblem("tag36h10"), "");
  EXPECT_THROW(mrgi::reconstruction::detail::createFamily("tag36h10"), std::invalid_argument);
}
