#pragma once
/// A replay's composites held against a synthetic session's reference composites (mrgi synth --scene), frame by
/// frame, where a person sees them: the virtual object (its brightness, its relative L1, where its brightest side
/// is) and what it does to the real pixels around it (its shadow's darkening energy). The session's frames, its
/// reference composites and masks (reference/NNNNNN.png, reference/mask_NNNNNN.png) and the replay's frames
/// (frame_NNNN.png with summary.json's per_frame to say which session frame each is) are read; everything in
/// linear light (the 8-bit sRGB decoded). The reference composite is the frame's image with the path tracer's
/// delta added under the same noise, so frame and reference differ by the objects alone.
#include <string>
#include <vector>

namespace mrgi::evaluation {

struct ComposedFrame {
  int frame = 0;               ///< the session's frame index
  int objectPixels = 0;        ///< pixels of the reference's object mask
  double brightness = 0;       ///< the object's summed luminance, ours over the reference's
  double relativeL1 = 0;       ///< sum over its pixels and channels of |ours - reference| over the reference's sum
  double brightestSide = 0;    ///< distance between the two brightest sides (the luminance-weighted centroids of each
                               ///< image's brightest fifth of the object's pixels), in the object's radii on screen
  double shadowEnergy = 0;     ///< the darkening of the real pixels (the frame's luminance less the composite's, where
                               ///< positive), ours over the reference's, outside the object's mask grown by 2 pixels
  double referenceShadow = 0;  ///< the reference's darkening (the denominator above)
};

/// Throws capture::CaptureError naming the file for a missing or unreadable image or summary, or a replay of
/// another size.
std::vector<ComposedFrame> compareComposites(const std::string& session, const std::string& replay);

}  // namespace mrgi::evaluation
