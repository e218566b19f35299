#include "lighting/techniques/kinect_val/val.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "capture/colour.h"
#include "reconstruction/point_index.h"

namespace mrgi::lighting {
namespace {

cv::Vec3f reflectView(const Receiver& r) { return 2.f * r.normal.dot(r.view) * r.normal - r.view; }

}  // namespace

float discFormFactor(const Val& val, const cv::Vec3f& x) {
  const cv::Vec3f d = x - val.position;
  const float dist2 = d.dot(d);
  if (!(dist2 > 0.f)) return 0.f;  // the receiver at the disc centre: no defined direction
  const float cosJ = std::clamp(val.normal.dot(d) / std::sqrt(dist2), 0.f, 1.f);  // rounding can exceed 1
  const float denom = std::numbers::pi_v<float> * dist2 + val.area;
  return denom > 0.f ? val.area * cosJ / denom : 0.f;
}

ValGather gatherReference(const Receiver& r, const std::vector<Val>& vals) {
  ValGather g;
  const cv::Vec3f refl = reflectView(r);
  for (const Val& v : vals) {
    const cv::Vec3f dir = v.position - r.position;
    const float dist2 = dir.dot(dir);
    const cv::Vec3f w = dist2 > 0.f ? dir / std::sqrt(dist2) : cv::Vec3f(0, 0, 0);
    const float cosI = std::max(r.normal.dot(w), 0.f);
    const float cosJ = std::max(-v.normal.dot(w), 0.f);
    const float denom = std::numbers::pi_v<float> * dist2 + v.area;
    const float geo = denom > 0.f ? cosJ / denom : 0.f;  // E_j = φ_j · geo · cos ϑ_i ≤ φ_j / a_j
    const float lobe = cosI > 0.f ? phongLobe(refl.dot(w), r.exponent) : 0.f;
    g.E += v.flux * (geo * cosI);
    g.S += v.flux * (geo * lobe);
    const float wd = kValEpsilon + v.weight * geo * cosI;
    const float ws = kValEpsilon + v.weight * geo * lobe;
    g.ld += wd * v.position;
    g.wd += wd;
    g.ldSq += wd * v.position.mul(v.position);
    g.ls += ws * v.position;
    g.ws += ws;
    g.lsSq += ws * v.position.mul(v.position);
  }
  return g;
}

namespace {
float spread(const cv::Vec3f& mean, const cv::Vec3f& sq, float w) {
  float s = 0.f;
  for (int i = 0; i < 3; ++i) s = std::max(s, sq[i] / w - mean[i] * mean[i]);
  return std::sqrt(std::max(s, 0.f));
}
}  // namespace

SparseVpl normalizeReference(const ValGather& g, const Receiver& r) {
  SparseVpl v;
  // No VAL at all: a defined position above the point, zero light.
  v.ld = g.wd > 0.f ? g.ld / g.wd : r.position + r.normal;
  v.ls = g.ws > 0.f ? g.ls / g.ws : r.position + r.normal;
  v.radiusD = g.wd > 0.f ? spread(v.ld, g.ldSq, g.wd) : 0.f;
  v.radiusS = g.ws > 0.f ? spread(v.ls, g.lsSq, g.ws) : 0.f;
  const cv::Vec3f dd = v.ld - r.position, ds = v.ls - r.position;
  const float d2 = std::max(dd.dot(dd), kValMinDist2), s2 = std::max(ds.dot(ds), kValMinDist2);
  const float lenD = std::sqrt(std::max(dd.dot(dd), 1e-30f)), lenS = std::sqrt(std::max(ds.dot(ds), 1e-30f));
  const float cosD = std::max(r.normal.dot(dd) / lenD, kValMinCos);
  const float lobeS = std::max(phongLobe(reflectView(r).dot(ds) / lenS, r.exponent), kValMinLobe);
  v.Ld = g.E * (d2 / cosD);
  v.Ls = g.S * (s2 / lobeS);
  return v;
}

void evaluateVpl(const SparseVpl& v, const Receiver& r, cv::Vec3f& E, cv::Vec3f& S) {
  const cv::Vec3f dd = v.ld - r.position, ds = v.ls - r.position;
  const float d2 = std::max(dd.dot(dd), kValMinDist2), s2 = std::max(ds.dot(ds), kValMinDist2);
  const float lenD = std::sqrt(std::max(dd.dot(dd), 1e-30f)), lenS = std::sqrt(std::max(ds.dot(ds), 1e-30f));
  const float cosD = std::max(r.normal.dot(dd) / lenD, 0.f);
  const float cosS = r.normal.dot(ds) / lenS;
  const float lobe = cosS > 0.f ? phongLobe(reflectView(r).dot(ds) / lenS, r.exponent) : 0.f;
  E = v.Ld * (cosD / d2);
  S = v.Ls * (lobe / s2);
}

cv::Vec3f valRadiance(const cv::Vec3f& E, const cv::Vec3f& S, const cv::Vec3f& albedo, const cv::Vec3f& specular,
                      float exponent) {
  return albedo.mul(E) * (1.f / std::numbers::pi_v<float>)+specular.mul(S) * phongNorm(exponent);
}

SparsePoints sampleSparsePoints(const Mesh& mesh, int count) {
  SparsePoints out;
  const size_t tris = mesh.triangleCount();
  if (tris == 0 || count <= 0) return out;
  std::vector<double> cdf(tris);
  double total = 0;
  for (size_t t = 0; t < tris; ++t) {
    const cv::Vec3f &a = mesh.positions[mesh.indices[3 * t]], &b = mesh.positions[mesh.indices[3 * t + 1]],
                    &c = mesh.positions[mesh.indices[3 * t + 2]];
    total += 0.5 * cv::norm((b - a).cross(c - a));
    cdf[t] = total;
  }
  if (!(total > 0)) return out;
  // R2 low-discrepancy sequence (generalised golden ratio) for the point inside its triangle.
  const double a1 = 0.7548776662466927, a2 = 0.5698402909980532;
  for (int i = 0; i < count; ++i) {
    const double u = (i + 0.5) / count * total;
    const size_t t = std::min<size_t>(std::lower_bound(cdf.begin(), cdf.end(), u) - cdf.begin(), tris - 1);
    double r1 = std::fmod(0.5 + a1 * (i + 1), 1.0), r2 = std::fmod(0.5 + a2 * (i + 1), 1.0);
    const double s = std::sqrt(r1);
    const float b0 = static_cast<float>(1 - s), b1 = static_cast<float>(s * (1 - r2)), b2 = static_cast<float>(s * r2);
    const uint32_t i0 = mesh.indices[3 * t], i1 = mesh.indices[3 * t + 1], i2 = mesh.indices[3 * t + 2];
    out.positions.push_back(b0 * mesh.positions[i0] + b1 * mesh.positions[i1] + b2 * mesh.positions[i2]);
    cv::Vec3f n = b0 * mesh.normals[i0] + b1 * mesh.normals[i1] + b2 * mesh.normals[i2];
    const float len = static_cast<float>(cv::norm(n));
    if (!(len > 1e-12f)) {
      n = (mesh.positions[i1] - mesh.positions[i0]).cross(mesh.positions[i2] - mesh.positions[i0]);
      n *= 1.f / std::max(static_cast<float>(cv::norm(n)), 1e-30f);
    } else {
      n *= 1.f / len;
    }
    out.normals.push_back(n);
  }
  // Occluder disc radius floor: the radius of an equal share of the surface.
  out.discRadius.assign(out.positions.size(), static_cast<float>(std::sqrt(total / count / CV_PI)));
  return out;
}

VertexWeights vertexWeights(const Mesh& mesh, SparsePoints& points) {
  constexpr int K = VertexWeights::kNeighbours;
  VertexWeights w;
  const size_t nv = mesh.positions.size();
  w.index.assign(nv * K, -1);
  w.weight.assign(nv * K, 0.f);
  if (points.positions.empty()) return w;
  const reconstruction::PointCloudAdaptor cloud{points.positions};
  const reconstruction::PointKdTree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  const int k = static_cast<int>(std::min<size_t>(K, points.positions.size()));
  const float diag = static_cast<float>(cv::norm(mesh.boundsMax - mesh.boundsMin));
  const float coincide = 1e-6f * std::max(diag, 1e-6f);
  uint32_t idx[K];
  float d2[K];
  for (size_t v = 0; v < nv; ++v) {
    const size_t found = tree.knnSearch(&mesh.positions[v][0], k, idx, d2);
    if (found == 0) continue;
    int32_t* oi = &w.index[v * K];
    float* ow = &w.weight[v * K];
    const float d0 = std::sqrt(d2[0]);
    points.discRadius[idx[0]] = std::max(points.discRadius[idx[0]], d0);  // Voronoi cell of idx[0]
    if (d0 <= coincide) {                                                 // the vertex is a sparse point: exact there
      oi[0] = static_cast<int32_t>(idx[0]);
      ow[0] = 1.f;
      continue;
    }
    const float dmax = std::sqrt(d2[found - 1]);
    float sum = 0.f;
    for (size_t j = 0; j < found; ++j) {
      oi[j] = static_cast<int32_t>(idx[j]);
      const float dist = std::sqrt(d2[j]);
      ow[j] = (dmax > 0.f ? 1.f - dist / dmax : 1.f) * std::max(mesh.normals[v].dot(points.normals[idx[j]]), 0.f);
      sum += ow[j];
    }
    for (size_t j = 0; j < found; ++j) ow[j] = sum > 0.f ? ow[j] / sum : 1.f / static_cast<float>(found);
  }
  return w;
}

SparseVpl interpolateVpl(const VertexWeights& w, size_t vertex, const std::vector<SparseVpl>& sparse) {
  constexpr int K = VertexWeights::kNeighbours;
  SparseVpl out;
  out.occlusionD = out.occlusionS = 0.f;
  for (int j = 0; j < K; ++j) {
    const int32_t i = w.index[vertex * K + j];
    if (i < 0) continue;
    const float a = w.weight[vertex * K + j];
    const SparseVpl& s = sparse[static_cast<size_t>(i)];
    out.Ld += a * s.Ld;
    out.ld += a * s.ld;
    out.Ls += a * s.Ls;
    out.ls += a * s.ls;
    out.radiusD += a * s.radiusD;
    out.radiusS += a * s.radiusS;
    out.occlusionD += a * s.occlusionD;
    out.occlusionS += a * s.occlusionS;
  }
  return out;
}

namespace {
/// Occlusion o of the light sphere (centre c, radius R) seen from point i by the other points' discs.
float occlusion(size_t i, const cv::Vec3f& c, float R, const std::vector<cv::Vec3f>& pos,
                const std::vector<cv::Vec3f>& nrm, const std::vector<float>& radius) {
  const cv::Vec3f x = pos[i], n = nrm[i];
  const cv::Vec3f toL = c - x;
  const float dl = std::sqrt(toL.dot(toL));
  if (!(dl > 0.f)) return 0.f;
  const cv::Vec3f wl = toL / dl;
  const float cosL = n.dot(wl);
  if (cosL <= 0.f) return 0.f;
  // Tangent frame of the unit circle (Nusselt projection).
  const cv::Vec3f t =
      std::abs(n[0]) < 0.9f ? cv::normalize(n.cross(cv::Vec3f(1, 0, 0))) : cv::normalize(n.cross(cv::Vec3f(0, 1, 0)));
  const cv::Vec3f b = n.cross(t);
  const float Rs = std::max(R, 1e-6f);
  const float areaL = std::numbers::pi_v<float> * Rs * Rs * cosL / (dl * dl + Rs * Rs);  // π F of a sphere
  const float hl = 0.5f * std::sqrt(areaL);
  const float lx = wl.dot(t), ly = wl.dot(b);
  float covered = 0.f;
  for (size_t k = 0; k < pos.size(); ++k) {
    if (k == i) continue;
    const cv::Vec3f toO = pos[k] - x;
    const float d2 = toO.dot(toO);
    if (!(d2 > 0.f)) continue;
    const float dk = std::sqrt(d2);
    const cv::Vec3f wo = toO / dk;
    const float cosX = n.dot(wo);
    if (cosX <= 0.f || dk >= dl) continue;  // behind the point or beyond the light centre
    const float fade = std::min((dl - dk) / Rs, 1.f);
    const float a = std::numbers::pi_v<float> * radius[k] * radius[k];
    const float areaO = std::numbers::pi_v<float> * a * std::abs(nrm[k].dot(wo)) * cosX /
                        (std::numbers::pi_v<float> * d2 + a);  // π F of a two-sided disc
    const float ho = 0.5f * std::sqrt(areaO);
    const float ox = wo.dot(t), oy = wo.dot(b);
    const float w = std::max(0.f, std::min(lx + hl, ox + ho) - std::max(lx - hl, ox - ho));
    const float h = std::max(0.f, std::min(ly + hl, oy + ho) - std::max(ly - hl, oy - ho));
    covered += w * h * fade;
  }
  return areaL > 0.f ? std::min(covered / areaL, 1.f) : 0.f;
}
}  // namespace

void occludeReference(const std::vector<cv::Vec3f>& positions, const std::vector<cv::Vec3f>& normals,
                      const std::vector<float>& discRadius, std::vector<SparseVpl>& vpls) {
  std::vector<float> od(vpls.size()), os(vpls.size());
  for (size_t i = 0; i < vpls.size(); ++i) {
    od[i] = 1.f - occlusion(i, vpls[i].ld, vpls[i].radiusD, positions, normals, discRadius);
    os[i] = 1.f - occlusion(i, vpls[i].ls, vpls[i].radiusS, positions, normals, discRadius);
  }
  for (size_t i = 0; i < vpls.size(); ++i) {
    vpls[i].Ld *= od[i];
    vpls[i].Ls *= os[i];
    vpls[i].occlusionD = od[i];
    vpls[i].occlusionS = os[i];
  }
}

std::vector<Val> valsFromRsm(const RsmTexels& rsm, const SceneLight& light, int stride) {
  std::vector<Val> out;
  stride = std::max(stride, 1);
  const float block = static_cast<float>(stride * stride);  // texels one sample stands for
  for (int y = stride / 2; y < rsm.position.rows; y += stride)
    for (int x = stride / 2; x < rsm.position.cols; x += stride) {
      const cv::Vec4f n4 = rsm.normal.at<cv::Vec4f>(y, x);
      if (n4[3] < 0.5f) continue;  // real texel (or empty)
      const cv::Vec4f p4 = rsm.position.at<cv::Vec4f>(y, x), f4 = rsm.flux.at<cv::Vec4f>(y, x),
                      d4 = rsm.direct.at<cv::Vec4f>(y, x);
      const cv::Vec3f p(p4[0], p4[1], p4[2]), n(n4[0], n4[1], n4[2]);
      cv::Vec3f toLight;
      cv::Vec3d beam;  // irradiance across the beam at the texel
      if (light.type == LightType::Directional) {
        toLight = -cv::Vec3f(light.direction);
        beam = light.irradiance;
      } else {
        const cv::Vec3f d = cv::Vec3f(light.position) - p;
        const float d2 = std::max(d.dot(d), 1e-12f);
        toLight = d / std::sqrt(d2);
        beam = light.intensity / static_cast<double>(d2);
      }
      const int c = beam[0] >= beam[1] && beam[0] >= beam[2] ? 0 : (beam[1] >= beam[2] ? 1 : 2);
      if (!(beam[c] > 0) || !(d4[c] > 0.f)) continue;
      const float across = static_cast<float>(d4[c] / beam[c]);
      Val v;
      v.position = p;
      v.normal = n;
      v.area = block * across / std::max(n.dot(toLight), 0.1f);
      v.flux = block * cv::Vec3f(f4[0], f4[1], f4[2]);
      out.push_back(v);
    }
  setValWeights(out);
  return out;
}

size_t dimShadowedVals(std::vector<Val>& vals, const std::vector<LightShadowMaps>& lights,
                       const cv::Vec3d& ambientRadiance) {
  size_t dimmed = 0;
  for (Val& v : vals) {
    cv::Vec3d with = CV_PI * ambientRadiance, without = with;
    for (const LightShadowMaps& m : lights) {
      const cv::Vec3d x(v.position), n(v.normal);
      const cv::Vec3d e = unshadowedIrradiance(m.light, x, n);
      if (e == cv::Vec3d(0, 0, 0)) continue;
      without += e * lightVisibility(m.maps, m.light, m.view, false, x, n, false);
      with += e * lightVisibility(m.maps, m.light, m.view, true, x, n, false);
    }
    if (with == without) continue;
    for (int c = 0; c < 3; ++c)
      if (without[c] > 0) v.flux[c] *= static_cast<float>(std::clamp(with[c] / without[c], 0.0, 1.0));
    ++dimmed;
  }
  return dimmed;
}

}  // namespace mrgi::lighting
