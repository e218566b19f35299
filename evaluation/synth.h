#pragma once
// Synthetic sessions with ground truth (`mrgi synth`): the tabletop room (evaluation/tabletop.h) rendered
// along the camera's orbit, optionally a look-around, through the session writer, with the sensor's noise, a
// fisheye frame of the ceiling and, for a scene's virtual objects, each frame's path-traced reference
// composite and real-pixel delta.
#include <cstdint>
#include <functional>
#include <optional>
#include <string>

namespace mrgi::evaluation {

struct SynthOptions {
  std::string out;
  int frames = 20;
  int width = 640, height = 480;
  uint64_t seed = 1;
  int tagId = 0;
  double tagSize = 0.16;
  bool staticCamera = false;         ///< every frame from the orbit's first pose (only the sensor noise changes)
  int fisheyeEvery = 30;             ///< a fisheye frame every N frames (the room is static), 0 = none
  std::string render = "pathtrace";  ///< pathtrace (global illumination) | raycast (direct light + constant ambient)
  int spp = 64, bounces = 3;
  /// The reference delta's samples per pixel around the objects (groundtruth::virtualFocus); 0: the delta is
  /// the composite's render minus the frame's own (spp, one seed, the camera's noise in both).
  int referenceFocusSpp = 0;
  /// How far around the objects the focus reaches: the box of their bounding sphere grown by this many radii
  /// on every side (the objects' shadow and bounce of the room reach about ten).
  double referenceFocusRadii = 3.0;
  std::string scene;            ///< virtual objects whose path-traced reference composite each frame gets
  std::string environment;      ///< HDR equirect EXR: outdoors under it instead of the room
  double environmentScale = 0;  ///< 0: a white upward surface in the open reads 0.6
  int scan = 0;                 ///< look-around frames after the orbit (walls, ceiling, the lamp)
  int scanJpegQuality = 0;      ///< the look-around's colour as JPEG at this quality (0: PNG, as the orbit's)
  /// Relative exposure; none: "auto", the exposure at which at most 1 % of the pixels clip (per frame).
  std::optional<double> exposure = 1.0;
  bool moveBox = false;    ///< the box moves to the front of the table a third of the way through (carving)
  bool moveLight = false;  ///< the lamp moves a third of the way round the table over the orbit
  bool windowSun = false;  ///< a window in the right wall and the sun through it onto the table (beside the lamp)
  /// Called with the fraction done (0..1) as frames are rendered.
  std::function<void(double)> progress;
};

/// Writes the session into `o.out` (a new or empty folder) and returns the number of frames written. Throws
/// std::invalid_argument for options that do not go together (naming the flag) and capture errors for inputs.
int writeSynthSession(const SynthOptions& o);
}  // namespace mrgi::evaluation
