#pragma once
/// Open3D's RGB-D folders (what its reconstruction system reads and writes): `color/` (or `image/`) and
/// `depth/` holding one image per frame, paired in file-name order; the intrinsics in `camera_intrinsic.json`
/// or `camera.json` beside them ({"width", "height", "intrinsic_matrix": 9 numbers, column-major}); the
/// camera's poses, when there are any, in `trajectory.log` (per frame "id id n" and the 4x4 camera-to-world
/// matrix, Open3D's PinholeCameraTrajectory log) as ground truth. Depth PNGs are 16-bit, 1000 units per metre
/// unless OpenOptions says otherwise; frames are taken 1/30 s apart (the folders carry no timestamps).
#include <string>
#include <vector>

#include "capture/frame_source.h"

namespace mrgi::capture {

inline constexpr double kOpen3dDepthUnitsPerMetre = 1000.0;
inline constexpr double kOpen3dFrameRate = 30.0;

/// True when `directory` looks like an Open3D RGB-D folder: a depth/ folder beside color/ or image/.
bool isOpen3dFolder(const std::string& directory);

/// Reads an Open3D camera intrinsic JSON file (throws CaptureError naming the file and the key).
Intrinsics readOpen3dIntrinsics(const std::string& path);

/// The same for a calibration beside frames of `width` x `height`: throws CaptureError when it is for another size.
Intrinsics readFolderIntrinsics(const std::string& path, int width, int height);

/// One frame of a folder of colour and depth images (TUM, Open3D), registered, with intrinsics `k`: throws
/// CaptureError naming the image whose size differs from `k`'s (`first`: what the colour is compared with).
RgbdFrame readFolderFrame(const std::string& colour, const std::string& depth, double unitsPerMetre,
                          const Intrinsics& k, const std::string& first);

/// Reads trajectory.log: one camera-to-world pose per block, keyed by the block's first id. Throws
/// CaptureError("<file>:<line>: ...") for a malformed block.
std::vector<std::pair<int64_t, Pose>> readOpen3dTrajectory(const std::string& path);

class Open3dFolderSource final : public FrameSource {
 public:
  explicit Open3dFolderSource(const std::string& directory, const OpenOptions& options = {});
  const SourceInfo& info() const override { return info_; }
  std::optional<Frame> next() override;

 private:
  struct Item {
    std::string colour, depth;
    std::optional<Pose> pose;
  };
  std::vector<Item> items_;
  SourceInfo info_;
  double unitsPerMetre_ = kOpen3dDepthUnitsPerMetre;
  size_t cursor_ = 0;
};

}  // namespace mrgi::capture
