#pragma once
// The scenes the reference path tracer renders for a frame: the same inputs the real-time techniques see
// (the measured real mesh with its estimated albedo, the scene's virtual objects and lights, the ambient as
// the radiance of everything outside the mesh), in the lighting world (the marker frame).
#include "groundtruth/path_tracer.h"
#include "runtime/frame_pipeline.h"

namespace mrgi::evaluation {

struct ReferenceScenes {
  groundtruth::Scene withObjects;  ///< ρ: real mesh + virtual objects
  groundtruth::Scene realOnly;     ///< μ: real mesh alone
  groundtruth::PinholeCamera camera;
};

/// Virtual objects keep their material: albedo, specular and the Phong exponent of their roughness.
ReferenceScenes reconstructedScenes(const runtime::LightingSetup& setup, const runtime::RealSurface& real,
                                    const capture::Intrinsics& intrinsics, const capture::Pose& T_marker_camera);

/// Adds the virtual objects (marker frame) to a path-tracer scene through T_world_marker, each with its
/// material: albedo, specular and the Phong exponent of its roughness, marked virtual.
void addVirtualObjects(const std::vector<lighting::VirtualObject>& objects, const capture::Pose& T_world_marker,
                       groundtruth::Scene& scene);

/// The scene's lights (marker frame) as the path tracer's delta lights (invisible to the camera).
std::vector<groundtruth::Light> referenceLights(const std::vector<lighting::SceneLight>& lights);

}  // namespace mrgi::evaluation
