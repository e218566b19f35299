#include "reconstruction/room_lights.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <set>
#include <stdexcept>

#include "capture/checks.h"
#include "capture/colour.h"
#include "reconstruction/mesh_rays.h"
#include "reconstruction/room_bounce.h"

namespace mrgi::reconstruction {

FisheyeRays latLongRays(int width) {
  if (width < 8 || width % 2) throw std::invalid_argument("latLongRays: width must be even and at least 8");
  const int height = width / 2;
  FisheyeRays r;
  r.directions.create(height, width, CV_32FC3);
  r.solidAngle.create(height, width, CV_64FC1);
  const double dPhi = 2 * CV_PI / width;
  for (int v = 0; v < height; ++v) {
    const double t0 = CV_PI * v / height, t1 = CV_PI * (v + 1) / height, t = 0.5 * (t0 + t1);
    const double omega = dPhi * (std::cos(t0) - std::cos(t1));
    for (int u = 0; u < width; ++u) {
      const double phi = dPhi * (u + 0.5);
      r.directions.at<cv::Vec3f>(v, u) =
          cv::Vec3f(static_cast<float>(std::sin(t) * std::cos(phi)), static_cast<float>(std::sin(t) * std::sin(phi)),
                    static_cast<float>(std::cos(t)));
      r.solidAngle.at<double>(v, u) = omega;
      r.totalSolidAngle += omega;
    }
  }
  return r;
}

namespace {

/// Push-pull fill (Gortler et al. 1996) of the lat-long map's texels no ray covered: each coarser level the
/// solid-angle-weighted mean of the 2x2 texels below it, over the covered unsaturated texels only (a lamp's
/// clipped radiance is a bound, not a colour to spread); an uncovered texel takes the coarser levels' values,
/// interpolated. Nothing covered: black.
void fillUncovered(cv::Mat& L, const cv::Mat& hit, const cv::Mat& saturated, const cv::Mat& solidAngle) {
  std::vector<cv::Mat> sum{cv::Mat(L.size(), CV_64FC3, cv::Scalar::all(0))}, weight{cv::Mat(L.size(), CV_64FC1, 0.0)};
  for (int v = 0; v < L.rows; ++v)
    for (int u = 0; u < L.cols; ++u)
      if (hit.at<uchar>(v, u) && !saturated.at<uchar>(v, u)) {
        const double w = solidAngle.at<double>(v, u);
        sum[0].at<cv::Vec3d>(v, u) = cv::Vec3d(L.at<cv::Vec3f>(v, u)) * w;
        weight[0].at<double>(v, u) = w;
      }
  while (sum.back().rows > 1 && sum.back().cols > 1) {
    const cv::Mat &s = sum.back(), &w = weight.back();
    cv::Mat S((s.rows + 1) / 2, (s.cols + 1) / 2, CV_64FC3, cv::Scalar::all(0)), Wc(S.size(), CV_64FC1, 0.0);
    for (int v = 0; v < s.rows; ++v)
      for (int u = 0; u < s.cols; ++u)
        S.at<cv::Vec3d>(v / 2, u / 2) += s.at<cv::Vec3d>(v, u), Wc.at<double>(v / 2, u / 2) += w.at<double>(v, u);
    sum.push_back(S), weight.push_back(Wc);
  }
  // Pull: each level's texels without weight sample the coarser level's filled values bilinearly (wrapping
  // in longitude), so that a filled region is smooth rather than blocky.
  auto sample = [](const cv::Mat& m, double y, double x) {
    const int y0 = static_cast<int>(std::floor(y)), x0 = static_cast<int>(std::floor(x));
    const double fy = y - y0, fx = x - x0;
    auto at = [&](int yy, int xx) {
      yy = std::clamp(yy, 0, m.rows - 1), xx = ((xx % m.cols) + m.cols) % m.cols;
      return m.at<cv::Vec3d>(yy, xx);
    };
    return (1 - fy) * ((1 - fx) * at(y0, x0) + fx * at(y0, x0 + 1)) +
           fy * ((1 - fx) * at(y0 + 1, x0) + fx * at(y0 + 1, x0 + 1));
  };
  cv::Mat filled(sum.back().size(), CV_64FC3, cv::Scalar::all(0));
  for (int v = 0; v < filled.rows; ++v)
    for (int u = 0; u < filled.cols; ++u) {
      const double w = weight.back().at<double>(v, u);
      if (w > 0) filled.at<cv::Vec3d>(v, u) = sum.back().at<cv::Vec3d>(v, u) / w;
    }
  for (size_t l = sum.size() - 1; l-- > 0;) {
    cv::Mat finer(sum[l].size(), CV_64FC3);
    for (int v = 0; v < finer.rows; ++v)
      for (int u = 0; u < finer.cols; ++u) {
        const double w = weight[l].at<double>(v, u);
        finer.at<cv::Vec3d>(v, u) = w > 0 ? cv::Vec3d(sum[l].at<cv::Vec3d>(v, u) / w)
                                          : cv::Vec3d(sample(filled, (v + 0.5) / 2 - 0.5, (u + 0.5) / 2 - 0.5));
      }
    filled = finer;
  }
  for (int v = 0; v < L.rows; ++v)
    for (int u = 0; u < L.cols; ++u)
      if (!hit.at<uchar>(v, u)) L.at<cv::Vec3f>(v, u) = cv::Vec3f(filled.at<cv::Vec3d>(v, u));
}

}  // namespace

namespace {
/// A distant light already known, its light on each vertex: irradiance at normal incidence, direction, reach.
struct KnownDistant {
  cv::Vec3d irradiance, towards;
  const DistantLightRays* reach;
};
RoomLights lightsSeenFrom(const RoomMesh& room, const cv::Vec3d& centre, const RoomLightOptions& o,
                          const MeshRays& mesh, const KnownDistant* sun = nullptr);
}  // namespace

namespace {

/// Clipped surfaces that a lamp lights, not lamps: a lamp near a ceiling or a wall over-exposes a wide patch of it
/// around the lamp's own clipped body, and the patch, taken as an emitter, would stand in for the lamp (its light
/// from the wrong place, its gain judged on the wrong surfaces). The saturated vertices are grouped into connected
/// pieces (by the mesh's edges); a piece no wider than kLampRadiusM, of kMinBodyVertices or more, is a lamp's body; a
/// wider piece most of whose vertices face such a body within kLampReachM with nothing between is a surface it lights,
/// and is cleared from `saturated` (its radiance stays the lower bound it is). A wide piece no body lights (a
/// clipped window, a panel light) stays an emitter. Returns the vertices cleared.
size_t clearLampLitClipped(const RoomMesh& room, const MeshRays& mesh, std::vector<uint8_t>& saturated) {
  constexpr double kLampRadiusM = 0.15, kLampReachM = 2.5, kLitShare = 0.6;
  constexpr size_t kMinBodyVertices = 12;
  const size_t n = std::min(saturated.size(), room.positions.size());
  // Connected pieces: saturated vertices joined by the mesh's edges (union-find).
  std::vector<uint32_t> parent(n);
  for (size_t i = 0; i < n; ++i) parent[i] = static_cast<uint32_t>(i);
  const auto root = [&](uint32_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (size_t t = 0; t + 2 < room.indices.size(); t += 3)
    for (int e = 0; e < 3; ++e) {
      const uint32_t a = room.indices[t + static_cast<size_t>(e)],
                     b = room.indices[t + static_cast<size_t>((e + 1) % 3)];
      if (a < n && b < n && saturated[a] && saturated[b]) parent[root(a)] = root(b);
    }
  std::map<uint32_t, std::vector<uint32_t>> byRoot;
  for (size_t i = 0; i < n; ++i)
    if (saturated[i]) byRoot[root(static_cast<uint32_t>(i))].push_back(static_cast<uint32_t>(i));
  if (byRoot.empty()) return 0;
  std::vector<std::vector<uint32_t>> pieces;
  for (auto& [r, members] : byRoot) pieces.push_back(std::move(members));
  struct Body {
    cv::Vec3d centre;
    double radius;
  };
  std::vector<Body> bodies;
  std::vector<size_t> wide, specks;
  for (size_t k = 0; k < pieces.size(); ++k) {
    cv::Vec3d c(0, 0, 0);
    for (uint32_t i : pieces[k]) c += cv::Vec3d(room.positions[i]);
    c /= static_cast<double>(pieces[k].size());
    double r = 0;
    for (uint32_t i : pieces[k]) r = std::max(r, cv::norm(cv::Vec3d(room.positions[i]) - c));
    if (r > kLampRadiusM)
      wide.push_back(k);
    else if (pieces[k].size() < kMinBodyVertices)
      specks.push_back(k);
    else
      bodies.push_back({c, r});
  }
  if (bodies.empty()) return 0;
  // Specks (a few clipped vertices: a highlight, a patch's rim) would take the lamp's gain, a thousand times their
  // bound, and shine as lamps of their own beside the object: once a lamp's body is found they are surfaces.
  size_t cleared = 0;
  for (size_t k : specks)
    for (uint32_t i : pieces[k]) saturated[i] = 0, ++cleared;
  for (size_t k : wide) {
    const std::vector<uint32_t>& members = pieces[k];
    const size_t step = std::max<size_t>(1, members.size() / 400);
    size_t tried = 0, lit = 0;
    for (size_t j = 0; j < members.size(); j += step) {
      const cv::Vec3d p(room.positions[members[j]]), nrm(room.normals[members[j]]);
      ++tried;
      for (const Body& b : bodies) {
        cv::Vec3d d = b.centre - p;
        const double r = cv::norm(d);
        if (r > kLampReachM || r < 1e-6) continue;
        d /= r;
        if (nrm.dot(d) <= 0.1) continue;
        // The body's own surface faces the patch: a shadow ray stops short of it by its radius and a voxel.
        if (mesh.occluded(p + 0.01 * nrm, d, std::max(0.0, r - b.radius - 0.04))) continue;
        ++lit;
        break;
      }
    }
    if (static_cast<double>(lit) < kLitShare * static_cast<double>(tried)) continue;
    for (uint32_t i : members) saturated[i] = 0, ++cleared;
  }
  return cleared;
}

/// The clipped pieces joined to a sunlit clipped surface (vertices the light's rays reach) are sunlit too, where
/// they face the light: the rays miss the patch's rim (the fused window frame a voxel thick, a piece of the table's
/// edge), and a rim left clipped would read as a small bright lamp beside the object. `saturated` has the sunlit
/// vertices cleared already (where it differs from `room.saturated`); the rest of each piece they touch is cleared
/// here. Touching is by 5 cm cells, not by the mesh's edges (as clearLampLitClipped groups a lamp's body): a rim
/// is often parted from its patch by a vertex or two the camera did not clip. Returns the vertices cleared.
size_t clearConnectedSunlit(const RoomMesh& room, std::vector<uint8_t>& saturated, const cv::Vec3d& towards) {
  constexpr double kCellM = 0.05;
  const size_t n = std::min({saturated.size(), room.saturated.size(), room.positions.size()});
  const auto cellOf = [&](size_t i) {
    const cv::Vec3f& p = room.positions[i];
    return std::array<int, 3>{static_cast<int>(std::floor(p[0] / kCellM)), static_cast<int>(std::floor(p[1] / kCellM)),
                              static_cast<int>(std::floor(p[2] / kCellM))};
  };
  std::map<std::array<int, 3>, std::vector<uint32_t>> clipped;  // still clipped, by cell
  std::vector<std::array<int, 3>> frontier;
  std::set<std::array<int, 3>> sunlitCells;
  for (size_t i = 0; i < n; ++i) {
    if (!room.saturated[i]) continue;
    const auto c = cellOf(i);
    if (saturated[i]) {
      clipped[c].push_back(static_cast<uint32_t>(i));
    } else if (sunlitCells.insert(c).second) {
      frontier.push_back(c);
    }
  }
  size_t cleared = 0;
  while (!frontier.empty()) {
    const std::array<int, 3> c = frontier.back();
    frontier.pop_back();
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const std::array<int, 3> m{c[0] + dx, c[1] + dy, c[2] + dz};
          const auto it = clipped.find(m);
          if (it == clipped.end()) continue;
          bool any = false;
          for (uint32_t i : it->second)
            if (saturated[i] && cv::Vec3d(room.normals[i]).dot(towards) > 0) saturated[i] = 0, ++cleared, any = true;
          if (any && sunlitCells.insert(m).second) frontier.push_back(m);
        }
  }
  return cleared;
}

}  // namespace

RoomLights estimateRoomLights(const RoomMesh& room, const cv::Vec3d& centre, const RoomLightOptions& o,
                              const MeshRays* given) {
  if (room.positions.empty() || room.indices.size() < 3) throw std::invalid_argument("estimateRoomLights: empty room");
  if (room.radiance.size() != room.positions.size())
    throw std::invalid_argument("estimateRoomLights: no radiance per vertex");
  for (int k = 0; k < 3; ++k)
    capture::checkNumber(centre[k], -1e4, 1e4, "room lights",
                         "the point they are seen from (" + capture::formatNumber(centre[0]) + ", " +
                             capture::formatNumber(centre[1]) + ", " + capture::formatNumber(centre[2]) + ")");
  if (!(o.saturatedGain >= 0) || !(o.whiteAlbedo > 0 && o.whiteAlbedo <= 1) || !(o.maxGain >= 1) ||
      !(o.estimateRadius > 0) || !(o.maxSaturatedFraction >= 0 && o.maxSaturatedFraction <= 1) ||
      !(o.minPointDistance >= 0))
    throw std::invalid_argument("estimateRoomLights: options out of range");
  std::optional<MeshRays> built;
  if (!given) built.emplace(room.positions, room.indices);
  const MeshRays& mesh = given ? *given : *built;
  // A distant light the room shows by its sunlit patches and shadows: its direction from the radiance alone (a
  // mid-grey albedo everywhere: the edges' signs are what the search needs).
  const size_t n = room.positions.size();
  std::optional<DistantLight> found;
  if (o.findDistant) {
    const std::vector<cv::Vec3f> grey(n, cv::Vec3f(0.5f, 0.5f, 0.5f));
    found = findDistantLight(room.positions, room.normals, room.radiance, grey, room.saturated, mesh, o.distant,
                             &room.openings);
  }
  // The room as its lights are judged. Clipped surfaces the distant light lights are sunlit surfaces, not lamps:
  // their radiance stays a lower bound of what they send, and they neither become lights nor judge the lamps' gain.
  // So are the clipped surfaces a lamp's own clipped body lights (clearLampLitClipped).
  RoomMesh lit = room;
  std::optional<DistantLightRays> reach;
  size_t sunlitClipped = 0;
  if (found) {
    reach.emplace(room.positions, mesh, &room.openings);
    for (size_t i = 0; i < n && i < lit.saturated.size(); ++i) {
      if (!lit.saturated[i]) continue;
      if (!(reach->lightOn(cv::Vec3d(room.positions[i]), cv::Vec3d(room.normals[i]), found->towards) > 0)) continue;
      lit.saturated[i] = 0;
      ++sunlitClipped;
    }
    sunlitClipped += clearConnectedSunlit(room, lit.saturated, found->towards);
  }
  const size_t lampLitClipped = clearLampLitClipped(lit, mesh, lit.saturated);
  const auto seen = [&](const RoomLightOptions& opts, const KnownDistant* sun = nullptr) {
    RoomLights out = lightsSeenFrom(lit, centre, opts, mesh, sun);
    out.lampLitClipped = lampLitClipped;
    return out;
  };
  if (!found) return seen(o);
  // Its power from the same edges, measured against the albedo the room's other light gives the shadowed side:
  // the lamps at their clipped bound here (their gain, judged by the light on the room's white surfaces, needs the
  // distant light's share of it first).
  RoomLightOptions bounded = o;
  bounded.saturatedGain = 1;
  const auto measureSun = [&](const RoomLights& others) {
    const RoomAlbedo albedo = albedoUnderRoomLights(lit, others, centre, mesh);
    DistantLightOptions measure = o.distant;
    measure.towards = found->towards;
    return findDistantLight(room.positions, room.normals, room.radiance, albedo.albedo, room.saturated, mesh, measure,
                            &room.openings);
  };
  std::optional<DistantLight> sun = measureSun(seen(bounded));
  if (!sun || !(capture::luminance(sun->irradiance) > 0)) return seen(o);
  KnownDistant known{sun->irradiance, sun->towards, &*reach};
  RoomLights out = seen(o, &known);
  // Once more with the lamps' gain that leaves (the shadowed side's albedo under the lamps as they are).
  if (out.gainEstimated && out.gain > 1) {
    if (std::optional<DistantLight> again = measureSun(out); again && capture::luminance(again->irradiance) > 0) {
      sun = again;
      known.irradiance = sun->irradiance;
      out = seen(o, &known);
    }
  }
  RoomLight l;
  l.point = false;
  l.distant = true;
  l.direction = sun->towards;
  for (int k = 0; k < 3; ++k) l.irradiance[k] = std::max(0.0, sun->irradiance[k]);
  l.angularRadius = o.distantAngularRadius;
  out.lights.push_back(l);
  out.distant = *sun;
  out.distant->consistency = found->consistency;
  out.sunlitClipped = sunlitClipped;
  return out;
}

namespace {

RoomLights lightsSeenFrom(const RoomMesh& room, const cv::Vec3d& centre, const RoomLightOptions& o,
                          const MeshRays& mesh, const KnownDistant* sun) {
  const FisheyeRays rays = latLongRays(o.mapWidth);
  const int W = rays.directions.cols, H = rays.directions.rows;
  cv::Mat L(H, W, CV_32FC3, cv::Scalar::all(0)), hitPos(H, W, CV_32FC3, cv::Scalar::all(0));
  cv::Mat saturated(H, W, CV_8UC1, cv::Scalar(0)), hit(H, W, CV_8UC1, cv::Scalar(0));
  double covered = 0, satOmega = 0;
  // What the cameras saw through the room's openings (the sky through a window) is light from there too.
  const DistantLightRays exits(room.positions, mesh, &room.openings);
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      const cv::Vec3d d(rays.directions.at<cv::Vec3f>(v, u));
      const MeshRays::Hit h = mesh.intersect(centre, d);
      if (!h.hit) {
        const int cell = exits.opening(centre, d);
        if (cell < 0 || static_cast<size_t>(cell) >= room.openings.radiance.size()) continue;
        const cv::Vec3d c =
            (cv::Vec3d(room.openings.cells[static_cast<size_t>(cell)]) + cv::Vec3d::all(0.5)) * room.openings.cellM;
        L.at<cv::Vec3f>(v, u) = room.openings.radiance[static_cast<size_t>(cell)];
        hitPos.at<cv::Vec3f>(v, u) = cv::Vec3f(centre + d * std::max(0.0, (c - centre).dot(d)));
        hit.at<uchar>(v, u) = 255;
        saturated.at<uchar>(v, u) =
            static_cast<size_t>(cell) < room.openings.clipped.size() && room.openings.clipped[static_cast<size_t>(cell)]
                ? 255
                : 0;
        const double omega = rays.solidAngle.at<double>(v, u);
        covered += omega;
        if (saturated.at<uchar>(v, u)) satOmega += omega;
        continue;
      }
      const uint32_t a = room.indices[3 * h.triangle], b = room.indices[3 * h.triangle + 1],
                     c = room.indices[3 * h.triangle + 2];
      const double wa = 1 - h.u - h.v;
      const cv::Vec3d rad =
          wa * cv::Vec3d(room.radiance[a]) + h.u * cv::Vec3d(room.radiance[b]) + h.v * cv::Vec3d(room.radiance[c]);
      auto sat = [&](uint32_t i) { return i < room.saturated.size() && room.saturated[i]; };
      L.at<cv::Vec3f>(v, u) = cv::Vec3f(rad);
      hitPos.at<cv::Vec3f>(v, u) = cv::Vec3f(centre + d * h.t);
      hit.at<uchar>(v, u) = 255;
      saturated.at<uchar>(v, u) = sat(a) || sat(b) || sat(c) ? 255 : 0;
      const double omega = rays.solidAngle.at<double>(v, u);
      covered += omega;
      if (saturated.at<uchar>(v, u)) satOmega += omega;
    }
  RoomLights out;
  out.coverage = covered / (4 * CV_PI);
  // Directions the room does not cover (never scanned: the ceiling straight above a table, seen from a camera
  // that looked up at most so far) continue the unsaturated surfaces around them: unknown, not dark, and more
  // like the ceiling beside them than like the room's mean.
  fillUncovered(L, hit, saturated, rays.solidAngle);
  // Radiance is finite and never negative, whatever the room file held.
  L.forEach<cv::Vec3f>([](cv::Vec3f& v, const int*) {
    for (int c = 0; c < 3; ++c) v[c] = std::isfinite(v[c]) ? std::max(v[c], 0.0f) : 0.0f;
  });

  // The unsaturated environment as SH (what the room's surfaces other than lamps and windows send the centre;
  // E_rest at any normal for the gain below).
  std::array<cv::Vec3d, 9> restSh{};
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      if (saturated.at<uchar>(v, u)) continue;
      const auto b = shBasis2(cv::Vec3d(rays.directions.at<cv::Vec3f>(v, u)));
      const cv::Vec3d Lw = cv::Vec3d(L.at<cv::Vec3f>(v, u)) * rays.solidAngle.at<double>(v, u);
      for (int k = 0; k < 9; ++k) restSh[k] += Lw * b[k];
    }
  out.surfacesSh = restSh;
  out.surfaces = L.clone();
  out.surfaces.setTo(cv::Scalar::all(0), saturated);
  out.saturatedFraction = covered > 0 ? satOmega / covered : 0.0;
  out.overExposed = out.saturatedFraction > o.maxSaturatedFraction;
  out.gain = o.saturatedGain > 0 ? o.saturatedGain : 1.0;
  if (o.saturatedGain <= 0 && satOmega > 0 && !out.overExposed) {
    out.gainEstimated = true;
    // The saturated texels grouped into 5 cm cells of their hit positions: each a small source of
    // intensity (luminance) sum(L dOmega) d_centre^2 at its power-weighted position.
    struct Source {
      cv::Vec3d position{0, 0, 0};
      double intensity = 0, weight = 0;
    };
    std::map<std::array<int, 3>, Source> cells;
    for (int v = 0; v < H; ++v)
      for (int u = 0; u < W; ++u) {
        if (!saturated.at<uchar>(v, u)) continue;
        const cv::Vec3d p(hitPos.at<cv::Vec3f>(v, u));
        const double power = capture::luminance(cv::Vec3d(L.at<cv::Vec3f>(v, u))) * rays.solidAngle.at<double>(v, u);
        const double d2 = (p - centre).dot(p - centre);
        Source& s = cells[{static_cast<int>(std::floor(p[0] / 0.05)), static_cast<int>(std::floor(p[1] / 0.05)),
                           static_cast<int>(std::floor(p[2] / 0.05))}];
        s.position += p * power, s.weight += power, s.intensity += power * d2;
      }
    std::vector<Source> sources;
    for (auto& [key, s] : cells)
      if (s.weight > 0) s.position /= s.weight, sources.push_back(s);
    // Vertices near the centre, at most ~4000 of them.
    std::vector<size_t> near;
    for (size_t i = 0; i < room.positions.size(); ++i)
      if (!(i < room.saturated.size() && room.saturated[i]) &&
          cv::norm(cv::Vec3d(room.positions[i]) - centre) <= o.estimateRadius)
        near.push_back(i);
    const size_t step = std::max<size_t>(1, near.size() / 4000);
    std::vector<double> gains;
    constexpr double kLampReach = 0.1;  // metres short of a cell a shadow ray stops: two cells, a lamp's size
    for (size_t k = 0; k < near.size(); k += step) {
      const size_t i = near[k];
      const cv::Vec3d p(room.positions[i]), n(room.normals[i]);
      double Ebound = 0, Ereach = 0;
      for (const Source& s : sources) {
        cv::Vec3d d = s.position - p;
        const double r = cv::norm(d);
        if (r < 1e-6) continue;
        d /= r;
        Ereach += s.intensity / (r * r);
        const double c = n.dot(d);
        if (c <= 0.2) continue;  // grazing: the estimate would divide by little
        // Shadowed only by what lies between: the saturated cells sit on the lamp's side that faces the centre,
        // and the lamp's own body (solid to the depth sensor) would hide them from every surface above it.
        if (mesh.occluded(p + 0.01 * n, d, r - kLampReach)) continue;
        Ebound += s.intensity * c / (r * r);
      }
      // Vertices the saturated regions do not light (shadowed, facing away) tell nothing about them, nor do
      // ones darker than the rest of the room alone would make a white surface.
      double Erest = capture::luminance(shIrradiance(restSh, n));
      // A distant light's share is not the lamps'.
      if (sun) Erest += capture::luminance(sun->irradiance) * sun->reach->lightOn(p, n, sun->towards);
      const double excess = CV_PI * capture::luminance(cv::Vec3d(room.radiance[i])) / o.whiteAlbedo - Erest;
      // Nor do ones the saturated regions light mostly at grazing angles or from behind (a ceiling around the
      // clipped spot a lamp below it makes): their light comes from elsewhere.
      if (Ebound <= 0 || excess <= 0 || Ebound < 0.2 * Ereach) continue;
      gains.push_back(excess / Ebound);
    }
    out.gainSamples = static_cast<int>(gains.size());
    if (!gains.empty()) {
      const size_t q = std::min(gains.size() - 1, static_cast<size_t>(0.95 * static_cast<double>(gains.size())));
      std::nth_element(gains.begin(), gains.begin() + static_cast<std::ptrdiff_t>(q), gains.end());
      out.gain = std::clamp(gains[q], 1.0, o.maxGain);
    }
  }
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u)
      if (saturated.at<uchar>(v, u)) L.at<cv::Vec3f>(v, u) *= static_cast<float>(out.gain);
  out.environment = L;

  // The split, and each light placed at its region's bright-energy-weighted hit position.
  out.split = splitLights(L, rays, o.split);
  out.ambientSh = out.split.ambientSh;
  out.ambientRadiance = out.ambientSh[0] * 0.28209479177387814;  // Y_00
  const double T = out.split.thresholdLuminance;
  for (const EstimatedLight& e : out.split.lights) {
    RoomLight l;
    l.direction = e.direction;
    l.irradiance = normalIrradiance(e);
    l.angularRadius = e.angularRadius;
    cv::Vec3d pos(0, 0, 0);
    double w = 0, wHit = 0, wSat = 0;
    for (int v = e.region.y; v < e.region.y + e.region.height; ++v)
      for (int u = e.region.x; u < e.region.x + e.region.width; ++u) {
        const double lum = capture::luminance(cv::Vec3d(L.at<cv::Vec3f>(v, u)));
        const double excess = std::max(0.0, lum - T) * rays.solidAngle.at<double>(v, u);
        w += excess;
        if (saturated.at<uchar>(v, u)) wSat += excess;
        if (!hit.at<uchar>(v, u)) continue;
        pos += cv::Vec3d(hitPos.at<cv::Vec3f>(v, u)) * excess, wHit += excess;
      }
    l.saturatedFraction = w > 0 ? wSat / w : 0.0;
    l.point = false;
    if (wHit > 0.5 * w && wHit > 0) {
      const cv::Vec3d p = pos / wHit;
      const double d = cv::norm(p - centre);
      if (d >= o.minPointDistance) {
        l.point = true;
        l.position = p;
        l.intensity = l.irradiance * (d * d);
        l.direction = (p - centre) / d;
      }
    }
    out.lights.push_back(l);
  }
  return out;
}

}  // namespace

RoomAlbedo albedoUnderRoomLights(const RoomMesh& room, const RoomLights& lights, const cv::Vec3d& centre,
                                 const MeshRays& rays) {
  AlbedoLights al;
  for (const RoomLight& l : lights.lights) {
    if (l.point) {
      al.points.push_back({l.position, l.intensity, cv::norm(l.position - centre) * std::sin(l.angularRadius)});
    } else {
      EstimatedLight e;
      e.direction = l.direction;
      e.power = l.irradiance;
      e.angularRadius = l.angularRadius;
      al.distant.push_back(e);
    }
  }
  RoomBounceOptions bo;
  bo.outside = lights.ambientRadiance;
  const std::vector<cv::Vec3f> bounce = roomBounceIrradiance(room, rays, bo);
  return estimateRoomAlbedo(room, al, {}, nullptr, &bounce, &rays);
}

nlohmann::json distantLightFacts(const RoomLights& lights) {
  if (!lights.distant) return nullptr;
  const DistantLight& d = *lights.distant;
  return {{"towards", {d.towards[0], d.towards[1], d.towards[2]}},
          {"irradiance", {d.irradiance[0], d.irradiance[1], d.irradiance[2]}},
          {"irradiance_lower_bound", {d.lowerBound[0], d.lowerBound[1], d.lowerBound[2]}},
          {"consistency", d.consistency},
          {"edges", d.edges},
          {"lit_share", d.litShare},
          {"pieces", d.pieces},
          {"pieces_showing", d.piecesShowing},
          {"sunlit_clipped_vertices", lights.sunlitClipped}};
}

}  // namespace mrgi::reconstruction
