#include "reconstruction/marker_image.h"

#include <cstdlib>
#include <stdexcept>

#include "reconstruction/apriltag_family.h"

extern "C" {
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagCircle21h7.h>
#include <apriltag/tagCircle49h12.h>
#include <apriltag/tagCustom48h12.h>
#include <apriltag/tagStandard41h12.h>
#include <apriltag/tagStandard52h13.h>
}

namespace mrgi::reconstruction {

detail::FamilyHandle detail::createFamily(const std::string& name) {
  FamilyHandle h;
  if (name == "tag36h11")
    h.family = tag36h11_create(), h.destroy = tag36h11_destroy;
  else if (name == "tag25h9")
    h.family = tag25h9_create(), h.destroy = tag25h9_destroy;
  else if (name == "tag16h5")
    h.family = tag16h5_create(), h.destroy = tag16h5_destroy;
  else if (name == "tagCircle21h7")
    h.family = tagCircle21h7_create(), h.destroy = tagCircle21h7_destroy;
  else if (name == "tagCircle49h12")
    h.family = tagCircle49h12_create(), h.destroy = tagCircle49h12_destroy;
  else if (name == "tagCustom48h12")
    h.family = tagCustom48h12_create(), h.destroy = tagCustom48h12_destroy;
  else if (name == "tagStandard41h12")
    h.family = tagStandard41h12_create(), h.destroy = tagStandard41h12_destroy;
  else if (name == "tagStandard52h13")
    h.family = tagStandard52h13_create(), h.destroy = tagStandard52h13_destroy;
  else
    throw std::invalid_argument("unknown tag family '" + name +
                                "' (tag36h11, tag25h9, tag16h5, tagCircle21h7, tagCircle49h12, tagCustom48h12, "
                                "tagStandard41h12, tagStandard52h13)");
  return h;
}

cv::Mat renderTag(const std::string& family, int id, TagLayout* layout) {
  const detail::FamilyHandle handle = detail::createFamily(family);
  apriltag_family_t* tf = handle.family;
  if (id < 0 || static_cast<uint32_t>(id) >= tf->ncodes) {
    const uint32_t n = tf->ncodes;
    throw std::invalid_argument("tag id " + std::to_string(id) + " outside " + family + " (0.." +
                                std::to_string(n - 1) + ")");
  }
  image_u8_t* im = apriltag_to_image(tf, id);
  cv::Mat out(im->height, im->width, CV_8UC1);
  for (int y = 0; y < im->height; ++y)
    for (int x = 0; x < im->width; ++x) out.at<uchar>(y, x) = im->buf[y * im->stride + x];
  if (layout) *layout = {static_cast<int>(tf->total_width), static_cast<int>(tf->width_at_border)};
  // image_u8_destroy is not exported by the shared library; the image and its buffer come from calloc.
  free(im->buf);
  free(im);
  return out;
}

}  // namespace mrgi::reconstruction
