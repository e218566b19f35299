#include "groundtruth/raycaster.h"

#include <embree3/rtcore.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace mrgi::groundtruth {
namespace {

/// Smallest t > tNear at which the ray meets the sphere, or +inf.
float hitSphere(cv::Vec3f o, cv::Vec3f d, cv::Vec3f c, float r, float tNear) {
  const cv::Vec3f oc = o - c;
  const float b = oc.dot(d), cc = oc.dot(oc) - r * r;
  const float disc = b * b - cc;
  if (disc < 0) return std::numeric_limits<float>::infinity();
  const float s = std::sqrt(disc);
  if (-b - s > tNear) return -b - s;
  if (-b + s > tNear) return -b + s;
  return std::numeric_limits<float>::infinity();
}
}  // namespace

RayCaster::RayCaster(const Scene& scene) : scene_(scene) {
  device_ = rtcNewDevice(nullptr);
  if (!device_) throw std::runtime_error("RayCaster(): cannot create an Embree device");
  rtcScene_ = rtcNewScene(device_);
  // Watertight traversal: a depth mesh has a vertex exactly on every second pixel's centre ray, and the
  // fast mode lets such rays slip through shared edges and vertices (12 % of a frame's rays escaped).
  rtcSetSceneFlags(rtcScene_, RTC_SCENE_FLAG_ROBUST);
  if (!scene.triangles.empty()) {
    RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), scene.vertices.size()));
    for (size_t i = 0; i < scene.vertices.size(); ++i)
      for (int c = 0; c < 3; ++c) v[3 * i + c] = scene.vertices[i][c];
    auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                               3 * sizeof(unsigned), scene.triangles.size()));
    for (size_t i = 0; i < scene.triangles.size(); ++i)
      for (int c = 0; c < 3; ++c) idx[3 * i + c] = static_cast<unsigned>(scene.triangles[i][c]);
    rtcCommitGeometry(g);
    rtcAttachGeometry(rtcScene_, g);
    rtcReleaseGeometry(g);
  }
  rtcCommitScene(rtcScene_);
}

RayCaster::~RayCaster() {
  rtcReleaseScene(rtcScene_);
  rtcReleaseDevice(device_);
}

std::optional<Hit> RayCaster::intersect(cv::Vec3f o, cv::Vec3f d, float tNear, float tFar, bool hitLights) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh{};
  rh.ray.org_x = o[0], rh.ray.org_y = o[1], rh.ray.org_z = o[2];
  rh.ray.dir_x = d[0], rh.ray.dir_y = d[1], rh.ray.dir_z = d[2];
  rh.ray.tnear = tNear;
  rh.ray.tfar = tFar;
  rh.ray.mask = 0xffffffffu;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(rtcScene_, &ctx, &rh);
  if (hitLights && rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
    // A camera ray through a mesh vertex exactly (a depth mesh has one on every vertex pixel's ray) can
    // slip between the triangles that share it even with watertight traversal: nudge it by ~1e-6 rad
    // (a micrometre at a metre, far below a pixel) and look once more.
    const cv::Vec3f nudged = cv::normalize(d + cv::Vec3f(0.93e-6f, 1.71e-6f, -1.29e-6f));
    rh.ray.dir_x = nudged[0], rh.ray.dir_y = nudged[1], rh.ray.dir_z = nudged[2];
    rh.ray.tfar = tFar;
    rtcIntersect1(rtcScene_, &ctx, &rh);
    rh.ray.dir_x = d[0], rh.ray.dir_y = d[1], rh.ray.dir_z = d[2];
  }

  float best = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID ? rh.ray.tfar : std::numeric_limits<float>::infinity();
  int light = -1;
  if (hitLights) {
    for (size_t i = 0; i < scene_.lights.size(); ++i) {
      if (scene_.lights[i].type == LightType::Directional || !(scene_.lights[i].radius > 0)) continue;
      const float t = hitSphere(o, d, scene_.lights[i].position, scene_.lights[i].radius, tNear);
      if (t < best && t < tFar) best = t, light = static_cast<int>(i);
    }
  }
  if (!std::isfinite(best)) return std::nullopt;
  Hit h;
  h.t = best;
  h.position = o + best * d;
  if (light >= 0) {
    h.light = light;
    h.normal = cv::normalize(h.position - scene_.lights[light].position);
    return h;
  }
  h.triangle = static_cast<int>(rh.hit.primID);
  const cv::Vec3i tri = scene_.triangles[h.triangle];
  cv::Vec3f n(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z);
  n = cv::normalize(n);
  if (n.dot(d) > 0) n = -n;
  h.normal = n;
  h.material = scene_.triangleMaterial[h.triangle];
  const Material& m = scene_.materials[h.material];
  const float u = rh.hit.u, v = rh.hit.v, w = 1.f - u - v;
  h.shading = n;
  if (!scene_.normals.empty()) {
    const cv::Vec3f s = w * scene_.normals[tri[0]] + u * scene_.normals[tri[1]] + v * scene_.normals[tri[2]];
    const float len = static_cast<float>(cv::norm(s));
    if (len > 1e-6f) h.shading = (s.dot(n) < 0 ? -s : s) / len;
  }
  h.albedo = m.albedo;
  if (!scene_.vertexAlbedo.empty())
    h.albedo = h.albedo.mul(w * scene_.vertexAlbedo[tri[0]] + u * scene_.vertexAlbedo[tri[1]] +
                            v * scene_.vertexAlbedo[tri[2]]);
  if (m.texture >= 0) {
    const cv::Vec2f uv = w * scene_.uvs[tri[0]] + u * scene_.uvs[tri[1]] + v * scene_.uvs[tri[2]];
    const cv::Mat& tex = scene_.textures[m.texture];
    const int x = std::clamp(static_cast<int>(uv[0] * tex.cols), 0, tex.cols - 1);
    const int y = std::clamp(static_cast<int>(uv[1] * tex.rows), 0, tex.rows - 1);
    h.albedo = h.albedo.mul(tex.at<cv::Vec3f>(y, x));
  }
  return h;
}

bool RayCaster::occluded(cv::Vec3f o, cv::Vec3f d, float tNear, float tFar) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRay ray{};
  ray.org_x = o[0], ray.org_y = o[1], ray.org_z = o[2];
  ray.dir_x = d[0], ray.dir_y = d[1], ray.dir_z = d[2];
  ray.tnear = tNear;
  ray.tfar = tFar;
  ray.mask = 0xffffffffu;
  rtcOccluded1(rtcScene_, &ctx, &ray);
  return ray.tfar < 0;  // Embree sets tfar = -inf on a hit
}

RayCaster::Incident RayCaster::incident(size_t i, cv::Vec3f p, cv::Vec3f g) const {
  const Light& l = scene_.lights[i];
  const cv::Vec3f origin = p + 1e-4f * g;
  if (l.type == LightType::Directional) {
    const cv::Vec3f w = -l.direction;
    if (g.dot(w) <= 0 || occluded(origin, w, 0.f, 1e30f)) return {w, {0, 0, 0}};
    return {w, l.irradiance};
  }
  const cv::Vec3f toLight = l.position - p;
  const float dist2 = toLight.dot(toLight);
  const float dist = std::sqrt(dist2);
  if (!(dist > l.radius) || dist == 0.f) return {{0, 0, 1}, {0, 0, 0}};  // inside the emitter: undefined
  const cv::Vec3f w = toLight / dist;
  if (l.type == LightType::Spot && -w.dot(l.direction) < l.spotCos) return {w, {0, 0, 0}};
  if (g.dot(w) <= 0 || occluded(origin, w, 0.f, dist - l.radius)) return {w, {0, 0, 0}};
  return {w, l.intensity * (1.f / dist2)};
}

cv::Vec3f RayCaster::shadeDirect(const Hit& hit) const {
  if (hit.light >= 0) {
    const Light& l = scene_.lights[hit.light];
    return l.intensity * (1.f / (std::numbers::pi_v<float> * l.radius * l.radius));
  }
  cv::Vec3f e(0, 0, 0);
  for (size_t i = 0; i < scene_.lights.size(); ++i) {
    const Incident in = incident(i, hit.position, hit.normal);
    e += in.irradiance * std::max(hit.shading.dot(in.direction), 0.f);
  }
  return hit.albedo.mul(e * (1.f / std::numbers::pi_v<float>)+scene_.ambient);
}

}  // namespace mrgi::groundtruth
