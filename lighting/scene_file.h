#pragma once
/// Scene files: which virtual objects go where (relative to the marker), their materials, the lights and
/// the lighting technique with its knobs. JSON; every error names the file and the offending key.
///
/// Frames: "marker" = the tag frame (origin at the tag centre, z out of the tag, x along its first edge,
/// metres). The lighting world of `mrgi replay` is the marker frame: the tag is fixed in the room, so the
/// volume stays axis-aligned in a frame that does not move with the camera.
#include <cmath>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "capture/error.h"
#include "lighting/knobs.h"
#include "lighting/scene.h"

namespace mrgi::lighting {

/// Bad scene file or model: "path: key: problem" (the one input-error class, capture/error.h).
using SceneError = capture::InputError;

/// Loads OBJ, PLY, glTF/GLB (anything assimp reads): all meshes of the file in their node transforms,
/// triangulated, smooth normals generated where missing. Throws SceneError naming the file when it cannot
/// be read or holds no triangles.
Mesh loadMesh(const std::string& path);

/// Parses and validates a scene file; model paths are relative to the scene file. Throws SceneError.
SceneDescription loadScene(const std::string& path);
/// Same from a JSON text (path used in messages and to resolve models).
SceneDescription parseScene(const std::string& text, const std::string& path);

// Writing scene files (mrgi insert): the document is edited as JSON, checked by the parser, and written whole.

/// A scene file's document, checked by parseScene (errors name the key). Throws SceneError.
nlohmann::json readSceneDocument(const std::string& path);
/// Rewrites the document's relative model paths, relative to the scene file `from`, relative to `to`'s folder.
void rebaseModelPaths(nlohmann::json& doc, const std::string& from, const std::string& to);
/// Writes the document atomically (indented; the folder must exist).
void writeSceneDocument(const std::string& path, const nlohmann::json& doc);
/// Euler angles in degrees of R = Rz Ry Rx, the inverse of an object's "rotate_deg" (x, then y, then z about the
/// marker's axes); in gimbal lock (y = +-90 degrees) x is 0.
cv::Vec3d eulerDegrees(const cv::Matx33d& R);

}  // namespace mrgi::lighting
