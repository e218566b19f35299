#pragma once
/// The one rule at the boundary: every number, pose and file a user gives passes these checks before any
/// work, and every problem is one line naming the flag, key or file ("<where>: <problem>", InputError).
/// Flags (app/cli_checks.h), JSON keys (capture/json_io.h), YAML calibrations, manifests, scene files and
/// room folders all use them, so the same value gets the same answer wherever it is given.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "capture/types.h"

namespace mrgi::capture {

/// A number as a person reads it: "%g" with up to 6 significant digits (1.79769e+308, never 309 digits).
std::string formatNumber(double v);

/// Empty when v is finite and in [lo, hi]; otherwise the problem ("must be a finite number in [0, 1], not
/// nan"). Bounds at +-DBL_MAX read as "at least" / "at most" / "a finite number".
std::string numberProblem(double v, double lo, double hi);
/// Throws InputError(where, "<what> " + numberProblem) when there is one; returns v.
double checkNumber(double v, double lo, double hi, const std::string& where, const std::string& what);

/// Empty when T is a rigid transform: every entry finite, the rotation orthonormal with determinant +1 within
/// 1e-3, the last row exactly 0 0 0 1, the translation within 1e6 m. Otherwise what is wrong.
std::string rigidProblem(const Pose& T);
/// Throws InputError(where, "<what> is not a rigid transform (<problem>)") when there is one.
void checkRigid(const Pose& T, const std::string& where, const std::string& what);

/// A depth unit (metres per stored step): from a micrometre (1e-6) to a metre; Kinect-like sensors store
/// millimetres (1e-3), TUM 0.2 mm.
constexpr double kMinDepthUnitsM = 1e-6, kMaxDepthUnitsM = 1.0;
/// A relative exposure (colour_exposure, --exposure): within six orders of magnitude of 1 either way.
constexpr double kMinExposure = 1e-6, kMaxExposure = 1e6;

/// The AprilTag families libapriltag ships, with the number of ids in each (a marker spec in a manifest,
/// --family and --id are checked against them; reconstruction's detector is tested to agree).
struct TagFamily {
  const char* name;
  int codes;
};
inline constexpr TagFamily kTagFamilies[] = {{"tag36h11", 587},
                                             {"tag25h9", 35},
                                             {"tag16h5", 30},
                                             {"tagCircle21h7", 38},
                                             {"tagCircle49h12", 65535},
                                             {"tagCustom48h12", 42211},
                                             {"tagStandard41h12", 2115},
                                             {"tagStandard52h13", 48714}};
/// Empty when family is one of them, else the problem naming the known ones.
std::string tagProblem(const std::string& family);
/// Empty when family is known and id one of its ids, else the problem.
std::string tagProblem(const std::string& family, int id);
/// A marker's black-square edge, metres.
constexpr double kMinTagSizeM = 1e-3, kMaxTagSizeM = 10.0;

/// What every light is held to, wherever it is given (a scene file's lights, a manifest's ground truth):
/// at most kMaxLightCount lights; positions within kMaxLightPositionM of the origin on each axis;
/// intensity (W/sr) and irradiance (W/m^2) per channel in [0, kMaxLightPower]; a direction finite and not
/// zero; a spot's half angle in [kMinSpotHalfAngleDeg, kMaxSpotHalfAngleDeg].
constexpr int kMaxLightCount = 16;
constexpr double kMaxLightPositionM = 1e3;
constexpr double kMaxLightPower = 1e9;
constexpr double kMinSpotHalfAngleDeg = 0.1, kMaxSpotHalfAngleDeg = 89.0;
/// Empty when d can be a light's direction (finite, length above 1e-9), else the problem.
std::string directionProblem(const cv::Vec3d& d);

/// Bounds on the files users give, by kind; a file past its bound is refused before it is read.
constexpr std::uintmax_t kMaxTextFileBytes = 64ull << 20;   ///< JSON, YAML, TUM lists, presets, scenes
constexpr std::uintmax_t kMaxBinaryFileBytes = 2ull << 30;  ///< images, models, arrays, meshes

/// The file's whole content: it must be a regular file (not a folder, FIFO or device: /dev/zero would never
/// end) of at most maxBytes. Errors: "<path>: is missing", "...: is not a regular file",
/// "...: is 80 MiB, more than the 64 MiB a <kind> may be", "...: cannot open for reading".
std::string readFileBounded(const std::string& path, std::uintmax_t maxBytes, const std::string& kind);
/// Throws like readFileBounded (missing, not regular, too large) without reading the file; returns its size.
std::uintmax_t checkFileBounded(const std::string& path, std::uintmax_t maxBytes, const std::string& kind);

/// YAML handed to OpenCV's FileStorage is checked first: its parser recurses once per level of nesting and
/// overflows the stack on a few tens of thousands (a flow sequence "[[[[..." or block maps indented deeper
/// and deeper). The deepest nesting in the text: block levels (indentation and "- " items) plus flow
/// levels ("[", "{" outside quotes and comments). A calibration nests 3 levels.
int yamlNestingDepth(const std::string& text);
constexpr int kMaxYamlDepth = 32;
/// Empty when `text` has the shape of a camera calibration in YAML (ROS camera_calibration's or OpenCV's):
/// an optional "%YAML" directive and "---", then only "key: value" lines (keys of letters, digits and '_';
/// values plain scalars, "!!opencv-matrix", or flow lists of numbers, which may run over lines) and comments;
/// otherwise the first line that is not, and why. OpenCV's YAML parser hangs or crashes on some text of
/// other shapes (block sequences, flow mappings: found by the fisheye_yaml fuzzer), so nothing else reaches it.
std::string calibrationYamlShapeError(const std::string& text);

/// A message from a library (assimp, OpenCV, Open3D) or a user's value cut to one printable line of about
/// maxChars (control characters become spaces; UTF-8 is kept whole) for quoting.
std::string excerpt(const std::string& text, std::size_t maxChars = 160);

/// The candidate a misspelt word most likely meant: the nearest by edit distance (insertions, deletions,
/// substitutions and swaps of neighbours, case ignored) within a third of its length (at least 1, at most 3),
/// the first such on a tie; empty when none is that near (or the word is one of them).
std::string nearestSpelling(const std::string& word, const std::vector<std::string>& candidates);
/// " (did you mean 'X'?)" for nearestSpelling, else "".
std::string didYouMean(const std::string& word, const std::vector<std::string>& candidates);

}  // namespace mrgi::capture
