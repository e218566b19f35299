#include "capture/ground_truth.h"

#include <cmath>

#include "capture/checks.h"
#include "capture/error.h"
#include "capture/session.h"

using nlohmann::json;

namespace mrgi::capture {
namespace {

cv::Vec3d vec3(const json& j, const std::string& file, const std::string& key) {
  if (!j.is_array() || j.size() != 3) throw CaptureError(file, key + " must be an array of 3 numbers");
  cv::Vec3d v;
  for (int i = 0; i < 3; ++i) {
    if (!j[i].is_number() || !std::isfinite(j[i].get<double>()))
      throw CaptureError(file, key + " must hold finite numbers");
    v[i] = j[i].get<double>();
  }
  return v;
}

const json& need(const json& j, const char* k, const std::string& file, const std::string& key) {
  if (!j.contains(k)) throw CaptureError(file, key + "." + k + " is missing");
  return j[k];
}

double finiteNumber(const json& j, const std::string& file, const std::string& key) {
  if (!j.is_number() || !std::isfinite(j.get<double>())) throw CaptureError(file, key + " must be a finite number");
  return j.get<double>();
}

}  // namespace

std::string GroundTruthReference::pathFor(const std::string& sessionDir, const std::string& pattern, int64_t index) {
  std::string p = pattern;
  const size_t at = p.find("NNNNNN");
  if (at != std::string::npos) {
    char idx[24];
    std::snprintf(idx, sizeof idx, "%06lld", static_cast<long long>(index));
    p.replace(at, 6, idx);
  }
  return sessionDir + "/" + p;
}

std::vector<GroundTruthLight> lightsFromJson(const json& array, const std::string& file, const std::string& prefix) {
  if (!array.is_array()) throw CaptureError(file, prefix + " must be an array");
  if (array.size() > static_cast<size_t>(kMaxLightCount))
    throw CaptureError(file, prefix + ": " + std::to_string(array.size()) + " lights, at most " +
                                 std::to_string(kMaxLightCount) + " are supported");
  // The same ranges as a scene file's lights (capture/checks.h).
  auto inRange = [&](const cv::Vec3d& v, double lo, double hi, const std::string& key) {
    for (int k = 0; k < 3; ++k) checkNumber(v[k], lo, hi, file, key + "[" + std::to_string(k) + "]");
    return v;
  };
  auto direction = [&](const cv::Vec3d& v, const std::string& key) {
    const std::string problem = directionProblem(v);
    if (!problem.empty()) throw CaptureError(file, key + " " + problem);
    return cv::normalize(v);
  };
  std::vector<GroundTruthLight> out;
  for (size_t i = 0; i < array.size(); ++i) {
    const json& l = array[i];
    const std::string key = prefix + "[" + std::to_string(i) + "]";
    if (!l.is_object()) throw CaptureError(file, key + " must be an object");
    GroundTruthLight light;
    const std::string type = l.contains("type") && l["type"].is_string() ? l["type"].get<std::string>() : "";
    if (type == "point" || type == "spot") {
      light.type = type == "point" ? GroundTruthLight::Type::Point : GroundTruthLight::Type::Spot;
      light.position = inRange(vec3(need(l, "position", file, key), file, key + ".position"), -kMaxLightPositionM,
                               kMaxLightPositionM, key + ".position");
      light.intensity = inRange(vec3(need(l, "intensity_w_sr", file, key), file, key + ".intensity_w_sr"), 0,
                                kMaxLightPower, key + ".intensity_w_sr");
      if (light.type == GroundTruthLight::Type::Spot) {
        light.direction =
            direction(vec3(need(l, "direction", file, key), file, key + ".direction"), key + ".direction");
        if (l.contains("spot_half_angle_deg"))
          light.spotHalfAngleDeg =
              checkNumber(finiteNumber(l["spot_half_angle_deg"], file, key + ".spot_half_angle_deg"),
                          kMinSpotHalfAngleDeg, kMaxSpotHalfAngleDeg, file, key + ".spot_half_angle_deg");
      }
    } else if (type == "directional") {
      light.type = GroundTruthLight::Type::Directional;
      light.direction = direction(vec3(need(l, "direction", file, key), file, key + ".direction"), key + ".direction");
      light.irradiance = inRange(vec3(need(l, "irradiance_w_m2", file, key), file, key + ".irradiance_w_m2"), 0,
                                 kMaxLightPower, key + ".irradiance_w_m2");
    } else {
      throw CaptureError(file, key + ".type '" + type + "' is not point, spot or directional");
    }
    if (l.contains("radius_m"))
      light.radius = checkNumber(finiteNumber(l["radius_m"], file, key + ".radius_m"), 0, 10, file, key + ".radius_m");
    out.push_back(light);
  }
  return out;
}

json lightsToJson(const std::vector<GroundTruthLight>& lights) {
  json out = json::array();
  const auto v = [](const cv::Vec3d& x) { return json::array({x[0], x[1], x[2]}); };
  for (const GroundTruthLight& l : lights) {
    json j;
    if (l.type == GroundTruthLight::Type::Directional) {
      j = {{"type", "directional"}, {"direction", v(l.direction)}, {"irradiance_w_m2", v(l.irradiance)}};
    } else {
      j = {{"type", l.type == GroundTruthLight::Type::Spot ? "spot" : "point"},
           {"position", v(l.position)},
           {"intensity_w_sr", v(l.intensity)}};
      if (l.type == GroundTruthLight::Type::Spot) {
        j["direction"] = v(l.direction);
        j["spot_half_angle_deg"] = l.spotHalfAngleDeg;
      }
    }
    if (l.radius > 0) j["radius_m"] = l.radius;
    out.push_back(j);
  }
  return out;
}

GroundTruth GroundTruth::fromJson(const json& j, const std::string& file) {
  GroundTruth g;
  if (j.is_null()) return g;
  if (!j.is_object()) throw CaptureError(file, "ground_truth must be an object");
  if (j.contains("T_world_marker"))
    g.T_world_marker = poseFromJson(j["T_world_marker"], file, "ground_truth.T_world_marker");
  if (j.contains("lights")) {
    g.listsLights = true;
    g.lights = lightsFromJson(j["lights"], file, "ground_truth.lights");
  }
  if (j.contains("scene") && j["scene"].is_object() && j["scene"].contains("ambient_radiance"))
    g.ambientRadiance = vec3(j["scene"]["ambient_radiance"], file, "ground_truth.scene.ambient_radiance");
  if (j.contains("reference")) {
    const json& r = j["reference"];
    if (!r.is_object()) throw CaptureError(file, "ground_truth.reference must be an object");
    GroundTruthReference ref;
    for (auto [k, out] :
         {std::pair{"scene", &ref.scene}, {"composite", &ref.composite}, {"delta", &ref.delta}, {"mask", &ref.mask}}) {
      if (!r.contains(k) || !r[k].is_string())
        throw CaptureError(file, std::string("ground_truth.reference.") + k + " must be a string");
      *out = r[k].get<std::string>();
    }
    for (const std::string* p : {&ref.composite, &ref.delta, &ref.mask})
      if (p->find("NNNNNN") == std::string::npos)
        throw CaptureError(file, "ground_truth.reference: '" + *p + "' has no NNNNNN frame placeholder");
    g.reference = ref;
  }
  if (j.contains("environment")) g.environment = j["environment"];
  return g;
}

}  // namespace mrgi::capture
