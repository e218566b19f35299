#pragma once
/// GPU side of Kinect-VAL: gather + renormalisation of receivers over VALs (val_gather.comp, VALs streamed
/// through shared memory in K_cache tiles) and the disc-occluder pass (val_occlude.comp). Receivers are the
/// sparse points (sparse method) or the visible pixels (brute force). Same math as lighting/val.h.
/// The VAL set itself is either uploaded (setVals) or built on the GPU from the frame, nothing read back
/// (beginVirtual / appendRsmVals per light / assemble: val_rsm.comp, val_dim.comp, val_weights.comp).
#include <cstdint>
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
  /// Slots of the VAL set the gather runs over (its size when uploaded, its capacity when built on the GPU).
  size_t valCount() const { return valCount_; }

  /// The VAL set built on the GPU. beginVirtual() empties the virtual VALs and makes room for `capacity`;
  /// appendRsmVals() adds one light's from its RSM (valsFromRsm's VALs, in its order); assemble() makes the
  /// set: the real VALs, those the objects now shadow dimmed (dimShadowedVals, through the frame's shadow
  /// maps, lights and ambient), then the virtual ones, all weighed (setValWeights). Sizes stay on the GPU.
  void beginVirtual(size_t capacity);
  void appendRsmVals(const Rsm& rsm, const SceneLight& light, int stride);
  void assemble(const std::vector<Val>& real, const FrameResources& frame);
  /// Virtual VALs one light's RSM can give: its grid of every stride-th texel.
  static size_t rsmValCapacity(int rsmSize, int stride);
  /// The sizes of the set (reading them back is a synchronous readback).
  struct Counts {
    uint32_t all = 0, real = 0, virtualVals = 0, dimmed = 0;
  };
  Counts downloadCounts() const;
  /// The set as the gather sees it (a synchronous readback).
  std::vector<Val> downloadVals() const;
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
  gl::Program gather_, occlude_, rsmVals_, dim_, weights_;
  gl::Buffer vals_, receivers_, vpls_, vplsScratch_, sums_, occluders_, partial_, virtual_, counts_;
  size_t valCount_ = 0, receiverCount_ = 0, virtualCapacity_ = 0;
};

}  // namespace mrgi::lighting
