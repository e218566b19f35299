#include "reconstruction/marker_image.h"

#include <cstdlib>
#include <stdexcept>

extern "C" {
#include <apriltag/apriltag.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h11.h>
}

namespace mrgi::reconstruction {

cv::Mat renderTag(const std::string& family, int id, TagLayout* layout) {
  apriltag_family_t* tf = nullptr;
  void (*destroy)(apriltag_family_t*) = nullptr;
  if (family == "tag36h11") tf = tag36h11_create(), destroy = tag36h11_destroy;
  else if (family == "tag25h9") tf = tag25h9_create(), destroy = tag25h9_destroy;
  else if (family == "tag16h5") tf = tag16h5_create(), destroy = tag16h5_destroy;
  else throw std::invalid_argument("unknown tag family '" + family + "' (tag36h11, tag25h9, tag16h5)");
  if (id < 0 || static_cast<uint32_t>(id) >= tf->ncodes) {
    const uint32_t n = tf->ncodes;
    destroy(tf);
    throw std::invalid_argument("tag id " + std::to_string(id) + " outside " + family + " (0.." + std::to_string(n - 1) + ")");
  }
  image_u8_t* im = apriltag_to_image(tf, id);
  cv::Mat out(im->height, im->width, CV_8UC1);
  for (int y = 0; y < im->height; ++y)
    for (int x = 0; x < im->width; ++x) out.at<uchar>(y, x) = im->buf[y * im->stride + x];
  if (layout) *layout = {static_cast<int>(tf->total_width), static_cast<int>(tf->width_at_border)};
  // image_u8_destroy is not exported by the shared library; the image and its buffer come from calloc.
  free(im->buf);
  free(im);
  destroy(tf);
  return out;
}

}  // namespace mrgi::reconstruction
