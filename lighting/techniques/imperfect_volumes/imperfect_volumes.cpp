#include "lighting/techniques/imperfect_volumes/imperfect_volumes.h"

#include <algorithm>
#include <cmath>

#include "capture/colour.h"
#include "gl/error.h"
#include "lighting/debug_views.h"
#include "lighting/sh.h"
#include "lighting/techniques/registry.h"

namespace mrgi::lighting {

const std::vector<KnobBinding<ImperfectVolumesKnobs>>& imperfectVolumesKnobTable() {
  static const std::vector<KnobBinding<ImperfectVolumesKnobs>> table = {
      {{"resolution", KnobType::Int, 1, 128, 32, "voxels per axis of the grid over the region", {16, 48}, {16}, true},
       &ImperfectVolumesKnobs::resolution},
      {{"points",
        KnobType::Int,
        3,
        19,
        8,
        "points per triangle (virtual objects and the real mesh)",
        {3, 19},
        {},
        false},
       &ImperfectVolumesKnobs::points},
      {{"rays", KnobType::Int, 16, 256, 64, "rays per voxel", {16, 256}, {16}, true}, &ImperfectVolumesKnobs::rays},
      {{"bands", KnobType::Int, 1, 8, 3, "SH bands of the incident radiance", {2, 4}, {}, false},
       &ImperfectVolumesKnobs::bands},
      {{"range",
        KnobType::Real,
        0.001,
        10.0,
        0.5,
        "metres: a surface farther along a ray than this leaves the ambient",
        {0.25, 1.0},
        {},
        true},
       &ImperfectVolumesKnobs::range},
      {{"bounces",
        KnobType::Int,
        0,
        3,
        2,
        "light bounces off the volume's surfaces (0: ambient occlusion only)",
        {0, 1},
        {1},
        false},
       &ImperfectVolumesKnobs::bounces},
      {{"object_rays",
        KnobType::Int,
        0,
        1024,
        64,
        "rays per virtual-object pixel, marched from its surface point through the real-only volume (0: the "
        "object reads the voxels' SH like real pixels)",
        {0, 256},
        {0},
        true},
       &ImperfectVolumesKnobs::objectRays},
      {{"outer_resolution",
        KnobType::Int,
        0,
        128,
        32,
        "voxels per axis of the coarser volume the object's rays go on through past the grid (side: the grid's + 2 "
        "range; real surfaces only; 0: past the grid is the ambient)",
        {0, 16},
        {0},
        true},
       &ImperfectVolumesKnobs::outerResolution},
  };
  return table;
}

namespace {

/// vec4 records per voxel (iv.glsl IvVoxel).
constexpr size_t kVoxelRecords = 8;

/// The per-voxel buffers: records and occupancy words, incident SH and occlusion per scene version (mu only for real
/// pixels), the bounce and reflected scratch (more than one bounce), computed flags and point offsets, for the object's
/// own rays the ambient hidden per voxel and the sum of the reflected bounces; the ray directions; the
/// points, which depend on the scene: budgeted as three surfaces across the grid at 4 points (48 bytes each)
/// per voxel; for the object's rays the outer volume's records, offsets and points; the rays' hits.
size_t voxelBytes(const ImperfectVolumesKnobs& k, bool real, bool virtualObject) {
  const size_t r = static_cast<size_t>(k.resolution), n = r * r * r;
  const size_t c = static_cast<size_t>(k.bands) * k.bands;
  const size_t versions = real ? 2 : 1;
  const bool own = virtualObject && k.objectRays > 0;
  const size_t perVoxel = kVoxelRecords * 16 + 4 + versions * (3 * c * 4 + 4) + (k.bounces > 1 ? 3 * c * 4 + 16 : 0) +
                          4 + 4 + (own ? 16 : 0) + (own && k.bounces > 1 ? 16 : 0);
  const size_t directions = 16 * static_cast<size_t>(k.rays + (own ? k.objectRays : 0));
  // The outer volume: records, occupancy and offsets, its points budgeted as the grid's.
  const size_t ro = own ? static_cast<size_t>(k.outerResolution) : 0, no = ro * ro * ro;
  const size_t outer = no * (kVoxelRecords * 16 + 4 + 4) + ro * ro * 3 * 4 * 48;
  // The rays' hits (iv_hits.comp): the voxels within one of those three surfaces, 8 bytes a ray, at most the
  // default budget.
  const size_t hits =
      std::min(ImperfectVolumesTechnique::kDefaultHitsBudget, 9 * r * r * static_cast<size_t>(k.rays) * 8);
  return n * perVoxel + directions + 3 * r * r * 4 * 48 + outer + hits;
}

}  // namespace

TechniqueInfo imperfectVolumesTechniqueInfo() {
  TechniqueInfo t;
  t.name = "imperfect-volumes";
  t.description =
      "Imperfect volumes: ambient occlusion and bounce light ray-marched through a voxelised point cloud, on real "
      "pixels and the object";
  t.real = true;
  t.virtualObject = true;
  t.stagePrefixes = {"iv."};
  t.knobs = groupOf("iv", imperfectVolumesKnobTable());
  t.create = [](const TechniqueSetup& s) { return std::make_unique<ImperfectVolumesTechnique>(s); };
  t.estimateBytes = [](const KnobValues& values, const KnobValues&, bool real, bool virtualObject, int w, int h,
                       size_t) {
    const ImperfectVolumesKnobs k = knobsFrom(imperfectVolumesKnobTable(), values);
    return voxelBytes(k, real, virtualObject) + 2 * 16 * static_cast<size_t>(w) * static_cast<size_t>(h);
  };
  return t;
}

IvPoints ivScenePoints(const FrameResources& frame, const iv::Grid& grid, int perTriangle, const iv::Grid* without) {
  perTriangle = std::clamp(perTriangle, 1, 64);
  const cv::Vec3f lo(grid.origin), hi = lo + cv::Vec3f::all(static_cast<float>(grid.voxel * grid.resolution));
  struct P {
    cv::Vec4f position, normal, albedo;
    uint32_t voxel;
  };
  std::vector<P> pts;
  IvPoints out;
  uint32_t triangleId = 0;
  const auto addTriangle = [&](const cv::Vec3f* x, const cv::Vec3f* n, const cv::Vec3f* albedo, bool isVirtual) {
    const uint32_t id = triangleId++;
    cv::Vec3f tlo = x[0], thi = x[0];
    for (int k = 1; k < 3; ++k)
      for (int a = 0; a < 3; ++a) tlo[a] = std::min(tlo[a], x[k][a]), thi[a] = std::max(thi[a], x[k][a]);
    for (int a = 0; a < 3; ++a)
      if (!(thi[a] >= lo[a] && tlo[a] < hi[a])) return false;  // outside the grid (or NaN)
    // N points, and on a triangle larger than a voxel at least 4 per voxel of its area, so that it leaves
    // no hole (a depth mesh's triangles are far smaller than a voxel; a cube's faces are not).
    const double area = 0.5 * cv::norm((x[1] - x[0]).cross(x[2] - x[0]));
    const int count = static_cast<int>(
        std::min(65536.0, std::max<double>(perTriangle, std::ceil(4.0 * area / (grid.voxel * grid.voxel)))));
    for (int j = 0; j < count; ++j) {
      const cv::Vec2f r = iv::sampleOf(id, j);
      const float s = std::sqrt(r[0]);
      const float wa = 1.0f - s, wb = (1.0f - r[1]) * s, wc = r[1] * s;
      const cv::Vec3f p = wa * x[0] + wb * x[1] + wc * x[2];
      cv::Vec3i v, inner;
      if (!grid.voxelOf(cv::Vec3d(p), v) || (without && without->voxelOf(cv::Vec3d(p), inner))) continue;
      cv::Vec3f nn = wa * n[0] + wb * n[1] + wc * n[2];
      const float len = static_cast<float>(cv::norm(nn));
      nn = len > 1e-12f ? nn / len : cv::Vec3f(0, 0, 0);
      const cv::Vec3f al = wa * albedo[0] + wb * albedo[1] + wc * albedo[2];
      pts.push_back({cv::Vec4f(p[0], p[1], p[2], isVirtual ? 1.0f : 0.0f), cv::Vec4f(nn[0], nn[1], nn[2], 0.0f),
                     cv::Vec4f(al[0], al[1], al[2], 1.0f), static_cast<uint32_t>(grid.index(v[0], v[1], v[2]))});
    }
    return true;
  };
  for (const FrameObject& o : frame.objects()) {
    if (without) break;  // the outer volume holds the real scene only
    const Mesh& m = o.source.mesh;
    const cv::Matx33f N = normalMatrix(o.T_world_object);
    const cv::Matx44d& T = o.T_world_object;
    for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
      cv::Vec3f x[3], n[3], al[3];
      for (int k = 0; k < 3; ++k) {
        const uint32_t i = m.indices[t + static_cast<size_t>(k)];
        const cv::Vec4d w = T * cv::Vec4d(m.positions[i][0], m.positions[i][1], m.positions[i][2], 1.0);
        x[k] = cv::Vec3f(static_cast<float>(w[0]), static_cast<float>(w[1]), static_cast<float>(w[2]));
        n[k] = N * m.normals[i];
        al[k] = o.source.material.albedo;
      }
      out.virtualTriangles += addTriangle(x, n, al, true);
    }
  }
  const auto& rv = frame.realVertices();
  const auto& ri = frame.realIndices();
  for (size_t t = 0; t + 2 < ri.size(); t += 3) {
    cv::Vec3f x[3], n[3], al[3];
    for (int k = 0; k < 3; ++k) {
      const MeshVertex& v = rv[ri[t + static_cast<size_t>(k)]];
      x[k] = v.position, n[k] = v.normal, al[k] = v.albedo;
    }
    out.realTriangles += addTriangle(x, n, al, false);
  }
  // Counting sort by voxel: each voxel's points contiguous.
  out.offsets.assign(grid.count() + 1, 0);
  for (const P& p : pts) ++out.offsets[p.voxel + 1];
  for (size_t v = 0; v < grid.count(); ++v) out.offsets[v + 1] += out.offsets[v];
  std::vector<uint32_t> at(out.offsets.begin(), out.offsets.end() - 1);
  out.data.resize(3 * pts.size());
  for (const P& p : pts) {
    const size_t k = 3 * size_t(at[p.voxel]++);
    out.data[k] = p.position, out.data[k + 1] = p.normal, out.data[k + 2] = p.albedo;
  }
  return out;
}

IvPoints ivOuterPoints(const FrameResources& frame, const iv::Grid& inner, const iv::Grid& outer, int perTriangle) {
  const double ratio = inner.voxel / outer.voxel;
  return ivScenePoints(frame, outer, std::max(1, static_cast<int>(std::lround(perTriangle * ratio * ratio))), &inner);
}

ImperfectVolumesTechnique::ImperfectVolumesTechnique(const TechniqueSetup& setup)
    : knobs_(knobsFrom(imperfectVolumesKnobTable(), setup.knobs)),
      real_(setup.real),
      virtual_(setup.virtualObject),
      injectProgram_(gl::Program::compute("lighting/techniques/imperfect_volumes/iv_inject.comp")),
      gatherProgram_(gl::Program::compute("lighting/techniques/imperfect_volumes/iv_gather.comp",
                                          {{"SH_BANDS", std::to_string(knobs_.bands)}})),
      reflectProgram_(gl::Program::compute("lighting/techniques/imperfect_volumes/iv_reflect.comp",
                                           {{"SH_BANDS", std::to_string(knobs_.bands)}})),
      hiddenProgram_(gl::Program::compute("lighting/techniques/imperfect_volumes/iv_hidden.comp")),
      coneProgram_(gl::Program::compute("lighting/techniques/imperfect_volumes/iv_cone.comp",
                                        {{"SH_BANDS", std::to_string(knobs_.bands)}})),
      readoutProgram_(gl::Program::graphics("lighting/gl/fullscreen.vert",
                                            "lighting/techniques/imperfect_volumes/iv_readout.frag",
                                            {{"SH_BANDS", std::to_string(knobs_.bands)}})),
      hitsProgram_(gl::Program::compute("lighting/techniques/imperfect_volumes/iv_hits.comp")),
      out_(setup.frame->techniqueView().width, setup.frame->techniqueView().height) {}

void ImperfectVolumesTechnique::build(const FrameResources& frame, gl::Profiler* profiler) {
  const Region& region = *frame.region();
  iv::Grid g;
  g.resolution = knobs_.resolution;
  g.origin = region.origin;
  g.voxel = region.side / knobs_.resolution;
  const bool regrid = !grid_ || grid_->resolution != g.resolution;
  grid_ = g;
  const size_t count = g.count();
  const int C = knobs_.bands * knobs_.bands;
  IvPoints pts;
  std::vector<uint32_t> needed, computed(count, 0);
  {
    auto s = timed(profiler, "iv.points", false);
    pts = ivScenePoints(frame, g, knobs_.points);
    pointCount_ = pts.count();
    std::vector<uint8_t> occupied(count);
    for (size_t v = 0; v < count; ++v) occupied[v] = pts.offsets[v + 1] > pts.offsets[v];
    const std::vector<uint8_t> near = iv::neededVoxels(g, occupied);
    for (size_t v = 0; v < count; ++v)
      if (near[v]) computed[v] = 1, needed.push_back(static_cast<uint32_t>(v));
    neededCount_ = needed.size();
    points_ = gl::Buffer::storage(pts.data.size() * sizeof(cv::Vec4f), pts.data.data());
    offsets_ = gl::Buffer::storage(pts.offsets.size() * sizeof(uint32_t), pts.offsets.data());
    needed_ = gl::Buffer::storage(needed.size() * sizeof(uint32_t), needed.data());
    computed_ = gl::Buffer::storage(computed.size() * sizeof(uint32_t), computed.data());
    if (regrid || !directions_.id()) {
      std::vector<cv::Vec4f> dirs;
      for (const cv::Vec3f& d : iv::rayDirections(knobs_.rays)) dirs.emplace_back(d[0], d[1], d[2], 0.0f);
      directions_ = gl::Buffer::storage(dirs.size() * sizeof(cv::Vec4f), dirs.data());
      voxels_ = gl::Buffer::storage(count * kVoxelRecords * sizeof(cv::Vec4f));
      occupancy_ = gl::Buffer::storage(count * sizeof(uint32_t));
      incidentRho_ = real_ ? gl::Buffer::storage(count * 3 * static_cast<size_t>(C) * sizeof(float)) : gl::Buffer();
      incidentMu_ = gl::Buffer::storage(count * 3 * static_cast<size_t>(C) * sizeof(float));
      bounce_ = gl::Buffer::storage(knobs_.bounces > 1 ? count * 3 * static_cast<size_t>(C) * sizeof(float) : 0);
      reflected_ = gl::Buffer::storage(knobs_.bounces > 1 ? count * sizeof(cv::Vec4f) : 0);
      occlusionRho_ = real_ ? gl::Buffer::storage(count * sizeof(float)) : gl::Buffer();
      occlusionMu_ = gl::Buffer::storage(count * sizeof(float));
      reflectedSum_ = gl::Buffer::storage(knobs_.bounces > 1 && virtual_ ? count * sizeof(cv::Vec4f) : 0);
      hidden_ = gl::Buffer::storage(virtual_ && knobs_.objectRays > 0 ? count * sizeof(cv::Vec4f) : 0);
    }
    if (virtual_ && knobs_.objectRays > 0 && knobs_.outerResolution > 0) {
      // The outer volume past the grid: the real mesh at the same point density per voxel area.
      const iv::Grid o = iv::outerGrid(g, knobs_.range, knobs_.outerResolution);
      const IvPoints op = ivOuterPoints(frame, g, o, knobs_.points);
      outerPointCount_ = op.count();
      outerPoints_ = gl::Buffer::storage(std::max<size_t>(op.data.size(), 1) * sizeof(cv::Vec4f), op.data.data());
      outerOffsets_ = gl::Buffer::storage(op.offsets.size() * sizeof(uint32_t), op.offsets.data());
      if (!outerVoxels_.id()) {  // the knob is fixed
        outerVoxels_ = gl::Buffer::storage(o.count() * kVoxelRecords * sizeof(cv::Vec4f));
        outerOccupancy_ = gl::Buffer::storage(o.count() * sizeof(uint32_t));
      }
      outerGrid_ = o;
    }
    if (!objectDirections_.id() && virtual_ && knobs_.objectRays > 0) {
      std::vector<cv::Vec4f> dirs;
      for (const cv::Vec3f& d : iv::rayDirections(knobs_.objectRays)) dirs.emplace_back(d[0], d[1], d[2], 0.0f);
      objectDirections_ = gl::Buffer::storage(dirs.size() * sizeof(cv::Vec4f), dirs.data());
    }
  }
  {
    auto s = timed(profiler, "iv.inject");
    const gl::Program& p = injectProgram_;
    p.use();
    setLightUniforms(p, frame.lights(), frame.lightViews());
    setAmbientUniforms(p, frame);
    p.set("uVoxelCount", static_cast<int>(count));
    setVec3(p, "uGridOrigin", g.origin);
    p.set("uVoxel", static_cast<float>(g.voxel));
    p.set("uResolution", g.resolution);
    frame.bindShadowMaps();
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, points_.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, offsets_.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, voxels_.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 14, occupancy_.id());
    glDispatchCompute(static_cast<GLuint>((count + 63) / 64), 1, 1);
    if (outerGrid_) {
      p.set("uVoxelCount", static_cast<int>(outerGrid_->count()));
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, outerPoints_.id());
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, outerOffsets_.id());
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, outerVoxels_.id());
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 14, outerOccupancy_.id());
      glDispatchCompute(static_cast<GLuint>((outerGrid_->count() + 63) / 64), 1, 1);
    }
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  }
  const size_t hitBytes = neededCount_ * static_cast<size_t>(knobs_.rays) * 2 * sizeof(int32_t);
  hitsCached_ = neededCount_ > 0 && hitBytes <= hitsBudget_;
  if (hitsCached_) {
    // Each needed voxel's rays marched once, for every pass below that casts them.
    auto s = timed(profiler, "iv.hits");
    if (static_cast<size_t>(hits_.size()) < hitBytes) hits_ = gl::Buffer::storage(hitBytes);
    useVoxelRays(hitsProgram_, frame, false);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, hits_.id());
    glDispatchCompute(static_cast<GLuint>((neededCount_ + 31) / 32), 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  }
  if (virtual_ && knobs_.objectRays > 0) {
    // The ambient the objects hide from real surfaces (what the object's own rays see on them).
    auto s = timed(profiler, "iv.hidden");
    useVoxelRays(hiddenProgram_, frame);
    hidden_.clear();
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 12, hidden_.id());
    glDispatchCompute(static_cast<GLuint>(std::max<size_t>((neededCount_ + 31) / 32, 1)), 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  }
  {
    auto s = timed(profiler, "iv.gather");
    if (real_) gather(frame, true);
    gather(frame, false);
  }
  coneBound_.reset();
  if (real_) {
    if (const auto b = frame.objectBounds()) {
      // The objects' box, grown by a voxel's half diagonal: their points occupy whole voxels.
      const cv::Vec3d lo = b->first, hi = b->second;
      coneBound_ = iv::Bound{cv::Vec3f(0.5 * (lo + hi)),
                             static_cast<float>(0.5 * cv::norm(hi - lo) + 0.5 * std::sqrt(3.0) * g.voxel)};
      auto s = timed(profiler, "iv.cone");
      const gl::Program& p = coneProgram_;
      useVoxelRays(p, frame);
      p.set("uConeRays", coneRays());
      p.set("uBounceLight", knobs_.bounces > 0 ? 1 : 0);
      p.set("uBound", coneBound_->centre[0], coneBound_->centre[1], coneBound_->centre[2], coneBound_->radius);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, incidentRho_.id());
      glDispatchCompute(static_cast<GLuint>(std::max<size_t>((neededCount_ + 31) / 32, 1)), 1, 1);
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    }
  }
  gl::checkGlError("ImperfectVolumesTechnique::build()");
  stats_ = {{"points", pointCount_},
            {"voxels_gathered", neededCount_},
            {"voxel_m", g.voxel},
            {"real_triangles", pts.realTriangles},
            {"virtual_triangles", pts.virtualTriangles}};
  if (outerGrid_) stats_["outer_points"] = outerPointCount_, stats_["outer_voxel_m"] = outerGrid_->voxel;
}

void ImperfectVolumesTechnique::useVoxelRays(const gl::Program& p, const FrameResources& frame, bool readsHits) const {
  const iv::Grid& g = *grid_;
  p.use();
  setVec3(p, "uGridOrigin", g.origin);
  p.set("uVoxel", static_cast<float>(g.voxel));
  p.set("uResolution", g.resolution);
  p.set("uNeededCount", static_cast<int>(neededCount_));
  p.set("uRays", knobs_.rays);
  p.set("uRange", static_cast<float>(knobs_.range));
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, voxels_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 14, occupancy_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, needed_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, directions_.id());
  if (!readsHits) return;
  setAmbientUniforms(p, frame);
  p.set("uCachedHits", hitsCached_ ? 1 : 0);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, (hitsCached_ ? hits_ : voxels_).id());  // a stand-in when not kept
}

void ImperfectVolumesTechnique::gather(const FrameResources& frame, bool rho) {
  const iv::Grid& g = *grid_;
  const gl::Buffer& incident = rho ? incidentRho_ : incidentMu_;
  const gl::Buffer& occlusion = rho ? occlusionRho_ : occlusionMu_;
  incident.clear();
  occlusion.clear();
  const GLuint groups = static_cast<GLuint>(std::max<size_t>((neededCount_ + 31) / 32, 1));
  const auto common = [&](const gl::Program& p) {
    p.use();
    setVec3(p, "uGridOrigin", g.origin);
    p.set("uVoxel", static_cast<float>(g.voxel));
    p.set("uResolution", g.resolution);
    p.set("uNeededCount", static_cast<int>(neededCount_));
  };
  const bool accumulate = !rho && knobs_.bounces > 1 && virtual_;  // the object's rays read the mu bounces
  if (accumulate) reflectedSum_.clear();
  const gl::Program& p = gatherProgram_;
  useVoxelRays(p, frame);
  p.set("uRho", rho ? 1 : 0);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, incident.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 6, occlusion.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 7, reflected_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 8, bounce_.id());
  // The first gather: ambient where nothing is hit within range, the surfaces' direct light where something is.
  p.set("uAmbientOn", 1);
  p.set("uOcclusionOn", 1);
  p.set("uBounceLight", knobs_.bounces > 0 ? 1 : 0);
  p.set("uExitantFromBuffer", 0);
  p.set("uWriteBounce", knobs_.bounces > 1 ? 1 : 0);
  glDispatchCompute(groups, 1, 1);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  for (int b = 1; b < knobs_.bounces; ++b) {
    const gl::Program& r = reflectProgram_;
    common(r);
    r.set("uAccumulate", accumulate ? 1 : 0);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 11, (accumulate ? reflectedSum_ : voxels_).id());
    glDispatchCompute(groups, 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    p.use();
    p.set("uAmbientOn", 0);
    p.set("uOcclusionOn", 0);
    p.set("uBounceLight", 1);
    p.set("uExitantFromBuffer", 1);
    p.set("uWriteBounce", b + 1 < knobs_.bounces ? 1 : 0);
    glDispatchCompute(groups, 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  }
}

void ImperfectVolumesTechnique::update(const FrameResources& frame, gl::Profiler* profiler) {
  if (!frame.region()) return;
  frame_ = &frame;
  const FrameVersions& v = frame.versions();
  const std::array<uint64_t, 3> from{v.geometry, v.lights, v.ambient};
  if (!builtFrom_ || *builtFrom_ != from) {
    build(frame, profiler);
    builtFrom_ = from;
  }
  auto s = timed(profiler, "iv.readout");
  out_.fb.bind();
  glViewport(0, 0, frame.techniqueView().width, frame.techniqueView().height);
  glDisable(GL_DEPTH_TEST);
  const gl::Program& p = readoutProgram_;
  p.use();
  const iv::Grid& g = *grid_;
  setVec3(p, "uGridOrigin", g.origin);
  p.set("uVoxel", static_cast<float>(g.voxel));
  p.set("uResolution", g.resolution);
  p.set("uReal", real_ ? 1 : 0);
  p.set("uVirtual", virtual_ ? 1 : 0);
  setAmbientUniforms(p, frame);
  frame.techniqueView().bind();
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, voxels_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, (real_ ? incidentRho_ : incidentMu_).id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 9, incidentMu_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 10, computed_.id());
  const bool objectRays = virtual_ && knobs_.objectRays > 0;
  p.set("uObjectRays", objectRays ? knobs_.objectRays : 0);
  p.set("uRange", static_cast<float>(knobs_.range));
  p.set("uBounceLight", knobs_.bounces > 0 ? 1 : 0);
  const bool reflectedOn = objectRays && knobs_.bounces > 1;
  p.set("uReflectedOn", reflectedOn ? 1 : 0);
  // Stand-ins where a buffer is not read (an SSBO binding must still name a buffer).
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, (objectRays ? objectDirections_ : voxels_).id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 11, (reflectedOn ? reflectedSum_ : voxels_).id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 12, (objectRays ? hidden_ : voxels_).id());
  const bool outer = objectRays && outerGrid_;
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 13, (outer ? outerVoxels_ : voxels_).id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 14, occupancy_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 15, (outer ? outerOccupancy_ : occupancy_).id());
  p.set("uOuterResolution", outer ? outerGrid_->resolution : 0);
  if (outer) {
    setVec3(p, "uOuterOrigin", outerGrid_->origin);
    p.set("uOuterVoxel", static_cast<float>(outerGrid_->voxel));
  }
  emptyVao_.bind();
  glDrawArrays(GL_TRIANGLES, 0, 3);
  gl::checkGlError("ImperfectVolumesTechnique::update()");
}

TechniqueOutputs ImperfectVolumesTechnique::outputs() const { return out_.outputs(real_, virtual_); }

namespace {

/// A volume's records as the reference math holds them.
iv::Volume downloadRecords(const iv::Grid& grid, const gl::Buffer& voxels) {
  iv::Volume v(grid);
  const size_t n = grid.count();
  std::vector<cv::Vec4f> rec(n * kVoxelRecords);
  voxels.download(0, static_cast<GLsizeiptr>(rec.size() * sizeof(cv::Vec4f)), rec.data());
  for (size_t i = 0; i < n; ++i) {
    const cv::Vec4f* r = &rec[i * kVoxelRecords];
    v.exitantRho[i] = r[0], v.exitantMu[i] = r[1], v.normalRho[i] = r[2], v.normalMu[i] = r[3];
    v.albedoRho[i] = cv::Vec3f(r[4][0], r[4][1], r[4][2]);
    v.albedoMu[i] = cv::Vec3f(r[5][0], r[5][1], r[5][2]);
    v.exitantMuLit[i] = cv::Vec4f(r[6][0], r[6][1], r[6][2], r[1][3]);
    v.exitantVirtual[i] = r[7];
    v.occupancy[i] = static_cast<uint8_t>((r[1][3] > 0 ? iv::kReal : 0) | (r[7][3] > 0 ? iv::kVirtual : 0));
  }
  return v;
}

}  // namespace

iv::Volume ImperfectVolumesTechnique::downloadVolume() const {
  if (!grid_) return iv::Volume(iv::Grid{cv::Vec3d(0, 0, 0), 1.0, 0});
  return downloadRecords(*grid_, voxels_);
}

iv::Volume ImperfectVolumesTechnique::downloadOuterVolume() const {
  if (!outerGrid_) return iv::Volume(iv::Grid{cv::Vec3d(0, 0, 0), 1.0, 0});
  return downloadRecords(*outerGrid_, outerVoxels_);
}

std::vector<cv::Vec3f> ImperfectVolumesTechnique::downloadHidden() const {
  if (!grid_ || !hidden_.id() || hidden_.size() == 0) return {};
  std::vector<cv::Vec4f> h(grid_->count());
  hidden_.download(0, static_cast<GLsizeiptr>(h.size() * sizeof(cv::Vec4f)), h.data());
  std::vector<cv::Vec3f> out(h.size());
  for (size_t i = 0; i < h.size(); ++i) out[i] = {h[i][0], h[i][1], h[i][2]};
  return out;
}

iv::Incident ImperfectVolumesTechnique::downloadIncident(bool rho) const {
  iv::Incident in;
  if (!grid_ || (rho && !real_)) return in;
  const size_t n = grid_->count();
  in.bands = knobs_.bands;
  in.sh.resize(n * 3 * static_cast<size_t>(knobs_.bands * knobs_.bands));
  (rho ? incidentRho_ : incidentMu_).download(0, static_cast<GLsizeiptr>(in.sh.size() * sizeof(float)), in.sh.data());
  in.occlusion.resize(n);
  (rho ? occlusionRho_ : occlusionMu_).download(0, static_cast<GLsizeiptr>(n * sizeof(float)), in.occlusion.data());
  std::vector<uint32_t> c(n);
  computed_.download(0, static_cast<GLsizeiptr>(n * sizeof(uint32_t)), c.data());
  in.computed.assign(c.begin(), c.end());
  return in;
}

cv::Mat ImperfectVolumesTechnique::debugImage(const std::string& view, const DebugContext&,
                                              nlohmann::json& info) const {
  if (!grid_) return {};
  if (view == "iv_ao" && frame_) {
    // Per pixel: the occlusion of the scene with the objects (the fraction of the sphere's rays blocked
    // within range: an open floor reads 0.5, mid grey), read as the reconstruction reads light
    // (iv::occlusion on the downloaded volume); real surfaces grey, the objects tinted yellow, outside the
    // grid dark blue.
    const iv::Volume v = downloadVolume();
    const iv::Incident in = downloadIncident(real_);
    const cv::Mat pos = frame_->downloadGBuffer(0), nrm = frame_->downloadGBuffer(1), alb = frame_->downloadGBuffer(2);
    cv::Mat out(pos.size(), CV_8UC3, cv::Scalar(30, 30, 70));
    double sum = 0;
    int n = 0;
    for (int i = 0; i < static_cast<int>(pos.total()); ++i) {
      const cv::Vec4f p = pos.at<cv::Vec4f>(i), q = nrm.at<cv::Vec4f>(i);
      if (p[3] < 0.5f) continue;
      const float ao = iv::occlusion(v, in, {p[0], p[1], p[2]}, {q[0], q[1], q[2]});
      if (ao < 0.0f) continue;  // outside the grid
      const auto open = cv::saturate_cast<uchar>(255.0 * (1.0 - ao));
      const bool isVirtual = alb.at<cv::Vec4f>(i)[3] > 0.5f;
      out.at<cv::Vec3b>(i) =
          isVirtual ? cv::Vec3b(open, open, static_cast<uchar>(open * 0.6)) : cv::Vec3b(open, open, open);
      sum += ao, ++n;
    }
    info["debug_iv_mean_occlusion"] = n > 0 ? sum / n : 0.0;
    return out;
  }
  if (view != "iv_slices") return {};
  // Two rows of slices along z (every 4th): occupancy (real grey, virtual yellow, empty dark blue) and the
  // ambient occlusion of the rho scene where rays were cast (white = open, black = enclosed; others dark red).
  const iv::Volume v = downloadVolume();
  const iv::Incident in = downloadIncident(true);
  const int res = grid_->resolution, every = std::max(1, res / 8), cell = std::max(1, 128 / res), gap = 2;
  const int slices = (res + every - 1) / every;
  cv::Mat out(2 * res * cell + gap, slices * (res * cell + gap), CV_8UC3, cv::Scalar(30, 30, 30));
  for (int s = 0; s < slices; ++s) {
    const int k = s * every;
    for (int j = 0; j < res; ++j)
      for (int i = 0; i < res; ++i) {
        const size_t idx = grid_->index(i, j, k);
        const int x = s * (res * cell + gap) + i * cell, y = (res - 1 - j) * cell;
        const uint8_t o = v.occupancy[idx];
        const cv::Scalar occ = (o & iv::kVirtual) ? cv::Scalar(240, 200, 40)
                               : (o & iv::kReal)  ? cv::Scalar(160, 160, 160)
                                                  : cv::Scalar(30, 30, 70);
        out(cv::Rect(x, y, cell, cell)).setTo(occ);
        cv::Scalar ao(70, 10, 10);
        if (!in.computed.empty() && in.computed[idx]) {
          const double open = 255.0 * (1.0 - in.occlusion[idx]);
          ao = cv::Scalar(open, open, open);
        }
        out(cv::Rect(x, y + res * cell + gap, cell, cell)).setTo(ao);
      }
  }
  info["debug_iv_slices_every"] = every;
  return out;
}

nlohmann::json ImperfectVolumesTechnique::stats() const { return stats_; }

size_t ImperfectVolumesTechnique::gpuBytes() const {
  size_t sum = out_.bytes();
  for (const gl::Buffer* b :
       {&points_,       &offsets_,     &voxels_,       &needed_,      &directions_, &incidentRho_,      &incidentMu_,
        &occlusionRho_, &occlusionMu_, &reflected_,    &bounce_,      &computed_,   &objectDirections_, &reflectedSum_,
        &hidden_,       &outerPoints_, &outerOffsets_, &outerVoxels_, &occupancy_,  &outerOccupancy_,   &hits_})
    sum += static_cast<size_t>(b->id() ? b->size() : 0);
  return sum;
}

}  // namespace mrgi::lighting
