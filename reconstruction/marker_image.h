#pragma once
/// AprilTag images from libapriltag's own family tables (for synthetic scenes and printing).
#include <opencv2/core.hpp>
#include <string>

namespace mrgi::reconstruction {

struct TagLayout {
  int totalCells;   ///< cells across the whole image, including the white outer border
  int borderCells;  ///< cells across the black border square (the "tag size" used for pose)
};

/// The tag as a CV_8UC1 image, one pixel per cell (0 black, 255 white), row 0 = top; throws
/// std::invalid_argument for an unknown family ("tag36h11", "tag25h9", "tag16h5") or id.
cv::Mat renderTag(const std::string& family, int id, TagLayout* layout = nullptr);

}  // namespace mrgi::reconstruction
