#pragma once
/// ViSP's RGB-D sequence folders (visp-images' `rbt/sequence`: a RealSense recording with its depth aligned to its
/// colour): `color_image_NNNN.png` and `depth_image_NNNN.npz` (an uncompressed zip holding `data.npy`, uint16) from
/// 0000 up, the intrinsics in `cam.json` ({"w", "h", "px", "py", "u0", "v0"}, an optional "depthScale" in metres per
/// unit, 0.001 when absent). Frames are taken 1/30 s apart (the folders carry no timestamps).
#include <optional>
#include <string>

#include "capture/frame_source.h"

namespace mrgi::capture {

class VispFolder {
 public:
  /// Reads `directory`/cam.json: throws CaptureError naming it (missing, malformed, intrinsics out of range).
  explicit VispFolder(const std::string& directory);
  const Intrinsics& intrinsics() const { return intrinsics_; }
  double depthScale() const { return depthScale_; }
  /// The tags' black-square edge in metres from `directory`/apriltag_data.json's tag_size: throws CaptureError
  /// naming the file when it is missing, malformed, has no tag_size or one out of range.
  double tagSize() const;
  /// Frame `i` (colour RGB, depth in metres, both on the intrinsics' grid), or nullopt when there is no
  /// color_image_<i>.png. Throws CaptureError naming a depth file that is missing or not a uint16 array of the
  /// intrinsics' size, or a colour image of another size.
  std::optional<Frame> frame(int i, double fps = 30.0) const;

 private:
  std::string directory_;
  Intrinsics intrinsics_;
  double depthScale_ = 0.001;
};

}  // namespace mrgi::capture
