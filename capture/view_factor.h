#pragma once
/// The view factor from a surface element to a sphere, and the irradiance of a light with extent built on it.
/// Shared by the objects' shadow of the ambient (lighting/object_shadow.h) and lights with an angular extent
/// (reconstruction's split lights, the shading pass's direct light). GLSL twin: lighting/view_factor.glsl.
#include <algorithm>
#include <cmath>

namespace mrgi::capture {

/// The fraction of a surface element's cosine-weighted hemisphere (pi) a sphere covers, the sphere's centre
/// at distance H (in sphere radii, H > 1) and at angle theta (cos theta = cosT) to the element's normal.
/// Whole above the horizon cos theta / H^2, whole below 0; partly below, the closed form of the view factor
/// from a tilted planar element to a sphere (Howell's catalogue of configuration factors), continuous with
/// both at their boundaries. H <= 1 (the element inside the sphere): 1.
inline double sphereViewFactor(double H, double cosT) {
  if (!(H > 1)) return std::isnan(H) ? 0.0 : 1.0;
  cosT = std::clamp(cosT, -1.0, 1.0);
  if (H * cosT >= 1.0) return cosT / (H * H);
  if (H * cosT <= -1.0) return 0.0;
  const double pi = 3.14159265358979323846;
  const double sinT = std::sqrt(std::max(0.0, 1.0 - cosT * cosT)), g = std::sqrt(H * H - 1.0);
  const double a = std::asin(std::clamp(g / (H * sinT), -1.0, 1.0));
  const double b = std::acos(std::clamp(-g * cosT / sinT, -1.0, 1.0));
  const double f = 0.5 - a / pi + (cosT * b - g * std::sqrt(std::max(0.0, 1.0 - H * H * cosT * cosT))) / (pi * H * H);
  return std::clamp(f, 0.0, 1.0);
}

/// A light with extent: a disc of uniform radiance seen under half-angle alpha (sin alpha = sinA) at angle
/// theta to the normal gives E = E_perp * capCosine(cos theta, sin alpha), E_perp its irradiance at normal
/// incidence. Equals max(cos theta, 0) whole above the horizon; near and below it the part still above
/// (a point light's cosine drops to 0 at once). sinA <= 0: a point direction.
inline double capCosine(double cosT, double sinA) {
  if (std::isnan(cosT)) return 0.0;
  if (!(sinA > 1e-4)) return std::clamp(cosT, 0.0, 1.0);
  sinA = std::min(sinA, 0.999);  // a hemisphere or more is not a light
  return std::min(sphereViewFactor(1.0 / sinA, cosT) / (sinA * sinA), 1.0);
}

}  // namespace mrgi::capture
