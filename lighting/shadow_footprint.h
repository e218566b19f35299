#pragma once
/// Where in the camera's image the objects can change more than the terms that reach every real pixel: their
/// own pixels and the real surfaces their direct shadow may fall on. The shading pass draws its whole program
/// only there and a program without the objects' pixels and direct shadow elsewhere (lighting/shade.frag,
/// SHADE_REAL_ONLY): llvmpipe runs every branch of a fragment program under masks, so a pixel's cost follows
/// the program, not the branch it takes.
#include <opencv2/core.hpp>
#include <vector>

#include "lighting/frame/mesh.h"
#include "lighting/scene.h"

namespace mrgi::lighting {

/// Whether the segment of light `light` towards the point x (the light's centre to x; for a directional light,
/// the ray from x against its direction) may pass within `radius` + `margin` of `centre` for some point of the
/// light (its extent: a sphere's radius or a sky disc's half-angle) — whether the sphere (centre, radius) may
/// shadow x from that light at all. Conservative: true wherever any part of the light is hidden.
bool mayShadow(const SceneLight& light, const cv::Vec3d& centre, double radius, const cv::Vec3d& x, double margin);

/// The image rectangle (pixels, clipped to the image) holding the sphere (centre, radius) bounding the objects
/// and every vertex of a triangle of the camera's mesh that the sphere may shadow from one of `lights`
/// (mayShadow with `margin` plus the triangle's own size), grown by 2 pixels; the whole image when such a point
/// lies at or behind the camera's near plane. Empty when the sphere is entirely behind the camera and shadows
/// nothing in view.
cv::Rect objectsFootprint(const CameraView& camera, const cv::Vec3d& centre, double radius,
                          const std::vector<SceneLight>& lights, double margin, const std::vector<MeshVertex>& vertices,
                          const std::vector<uint32_t>& indices);

/// The image less `inner` as at most four disjoint rectangles (the rows above and below it, then the columns
/// left and right of it beside it), none empty: each pixel of `image` outside `inner` lies in exactly one. The
/// whole image when `inner` misses it.
std::vector<cv::Rect> bandsAround(const cv::Rect& image, const cv::Rect& inner);

}  // namespace mrgi::lighting
