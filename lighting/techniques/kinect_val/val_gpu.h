#pragma once
/// GPU side of Kinect-VAL: gather + renormalisation of receivers over VALs (val_gather.comp, VALs streamed
/// through shared memory in K_cache tiles) and the disc-occluder pass (val_occlude.comp). Receivers are the
/// sparse points (sparse method) or the visible pixels (brute force). Same math as lighting/val.h.
#include <vector>

#include "gl/objects.h"
#include "gl/program.h"
#include "lighting/techniques/kinect_val/val.h"

namespace mrgi::lighting {

class ValGpu {
 public:
  /// kCache: VALs per shared-memory tile, 16..512. Needs a current GL 4.5 context.
  explicit ValGpu(int kCache = 128);
  /// VALs per gather dispatch; larger sets take several, the sums carried between them.
  static constexpr size_t kValsPerDispatch = 16384;
  int kCache() const { return kCache_; }

  void setVals(const std::vector<Val>& vals);
  size_t valCount() const { return valCount_; }
  /// Gathers every receiver over every VAL; VPLs and (E, S) stay on the GPU until downloaded.
  void gather(const std::vector<Receiver>& receivers);
  /// Occludes the last gather's VPLs by the receivers as discs (positions, normals, disc radii).
  void occlude(const std::vector<cv::Vec3f>& positions, const std::vector<cv::Vec3f>& normals,
               const std::vector<float>& discRadius);

  std::vector<SparseVpl> downloadVpls() const;
  /// Per receiver E (W/m²) and S of the last gather.
  void downloadSums(std::vector<cv::Vec3f>& E, std::vector<cv::Vec3f>& S) const;
  const gl::Buffer& vplBuffer() const { return vpls_; }
  size_t receiverCount() const { return receiverCount_; }

 private:
  void ensure(gl::Buffer& b, size_t bytes);
  int kCache_;
  gl::Program gather_, occlude_;
  gl::Buffer vals_, receivers_, vpls_, vplsScratch_, sums_, occluders_, partial_;
  size_t valCount_ = 0, receiverCount_ = 0;
};

}  // namespace mrgi::lighting
