#include "lighting/techniques/pic/pic_technique.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "gl/error.h"
#include "lighting/sh.h"
#include "lighting/techniques/registry.h"
#include "reconstruction/mesh_rays.h"

namespace mrgi::lighting {

const std::vector<KnobBinding<PicKnobs>>& picKnobTable() {
  static const std::vector<KnobBinding<PicKnobs>> table = {
      {{"surfels",
        KnobType::Int,
        16,
        65536,
        4096,
        "surfels over the static real mesh (precomputed)",
        {1024, 16384},
        {1024},
        true},
       &PicKnobs::surfels},
      {{"bands", KnobType::Int, 1, 8, 4, "SH bands of the caches' radiance", {2, 3, 6, 8}, {2}, false},
       &PicKnobs::bands},
      {{"chroma_bands",
        KnobType::Int,
        0,
        8,
        0,
        "SH bands kept for the caches' chroma (Co, Cg); 0: as many as bands",
        {1, 2},
        {},
        false},
       &PicKnobs::chromaBands},
      {{"links",
        KnobType::Int,
        4,
        2048,
        128,
        "hierarchy nodes linked to each cache (precomputed)",
        {32, 512},
        {32},
        true},
       &PicKnobs::links},
      {{"grid",
        KnobType::Int,
        1,
        16,
        6,
        "caches per axis of the grid over the region (precomputed)",
        {4, 10},
        {},
        false},
       &PicKnobs::grid},
      {{"receivers",
        KnobType::Int,
        0,
        4096,
        256,
        "bounce receivers on a cut of the hierarchy (0: no bounce)",
        {0, 1024},
        {0},
        true},
       &PicKnobs::receivers},
      {{"bounces",
        KnobType::Int,
        0,
        4,
        1,
        "bounces per run (with progressive: added to the last run's)",
        {0, 2},
        {},
        false},
       &PicKnobs::bounces},
      {{"progressive",
        KnobType::Bool,
        0,
        1,
        0,
        "the bounce light carries over between runs (each run adds `bounces`)",
        {1},
        {},
        false},
       &PicKnobs::progressive},
      {{"rgb9e5", KnobType::Bool, 0, 1, 1, "surfel and node flux stored as RGB9E5 (else RGBA32F)", {0}, {}, false},
       &PicKnobs::rgb9e5},
  };
  return table;
}

namespace {

int chromaOf(const PicKnobs& k) { return k.chromaBands > 0 ? std::min(k.chromaBands, k.bands) : k.bands; }
size_t cacheFloats(const PicKnobs& k) {
  const auto b = static_cast<size_t>(k.bands), c = static_cast<size_t>(chromaOf(k));
  return b * b + 2 * c * c;
}

gl::Defines definesOf(const PicKnobs& k) {
  return {{"SH_BANDS", std::to_string(k.bands)}, {"PIC_CHROMA_BANDS", std::to_string(chromaOf(k))}};
}

uint64_t hashBytes(const void* data, size_t bytes, uint64_t h = 1469598103934665603ull) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}

double msSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

template <class T>
gl::Buffer bufferOf(const std::vector<T>& v) {
  return gl::Buffer::storage(std::max<size_t>(v.size() * sizeof(T), 16), v.empty() ? nullptr : v.data());
}

bool sameShadows(const std::vector<SceneLight>& a, const std::vector<SceneLight>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (a[i].type != b[i].type || a[i].position != b[i].position || a[i].direction != b[i].direction) return false;
  return true;
}

}  // namespace

TechniqueInfo picTechniqueInfo() {
  TechniqueInfo t;
  t.name = "pic";
  t.description =
      "Precomputed illuminance composition: the static room's surfels, hierarchy and SH caches precomputed, relit per "
      "run (virtual object only)";
  t.real = false;
  t.virtualObject = true;
  t.stagePrefixes = {"pic."};
  t.knobs = groupOf("pic", picKnobTable());
  t.create = [](const TechniqueSetup& s) { return std::make_unique<PicTechnique>(s); };
  t.estimateBytes = [](const KnobValues& values, const KnobValues&, bool, bool, int w, int h, size_t) {
    const PicKnobs k = knobsFrom(picKnobTable(), values);
    const auto s = static_cast<size_t>(k.surfels), nodes = 2 * s;
    const auto b2 = static_cast<size_t>(k.bands * k.bands);
    const auto g = static_cast<size_t>(k.grid), caches = g * g * g, r = static_cast<size_t>(k.receivers);
    const size_t perCache = static_cast<size_t>(k.links) * (4 + 4 * b2) + 4 * b2 * 9 + 4 * cacheFloats(k) + 4;
    return s * (48 + 4) + nodes * (16 + 8 + 4) + (caches + r) * perCache +
           2 * 16 * static_cast<size_t>(w) * static_cast<size_t>(h);
  };
  return t;
}

PicTechnique::PicTechnique(const TechniqueSetup& setup)
    : knobs_(knobsFrom(picKnobTable(), setup.knobs)),
      progress_(setup.progress),
      cacheDir_(setup.cacheDir),
      lightProgram_(gl::Program::compute("lighting/techniques/pic/pic_light.comp", definesOf(knobs_))),
      pullProgram_(gl::Program::compute("lighting/techniques/pic/pic_pull.comp", definesOf(knobs_))),
      gatherProgram_(gl::Program::compute("lighting/techniques/pic/pic_gather.comp", definesOf(knobs_))),
      readoutProgram_(gl::Program::graphics("lighting/gl/fullscreen.vert", "lighting/techniques/pic/pic_readout.frag",
                                            definesOf(knobs_))),
      irradiance_(GL_TEXTURE_2D, GL_RGBA32F, setup.frame->techniqueView().width, setup.frame->techniqueView().height),
      radiance_(GL_TEXTURE_2D, GL_RGBA32F, setup.frame->techniqueView().width, setup.frame->techniqueView().height) {
  irradiance_.setFilter(GL_NEAREST, GL_NEAREST);
  radiance_.setFilter(GL_NEAREST, GL_NEAREST);
  fb_.attachColour(0, irradiance_);
  fb_.attachColour(1, radiance_);
  fb_.finalise(2);
}

PicTechnique::~PicTechnique() = default;

int PicTechnique::chromaBands() const { return chromaOf(knobs_); }

TechniqueOutputs PicTechnique::outputs() const {
  TechniqueOutputs o;
  o.virtualIrradiance = &irradiance_;
  o.virtualRadiance = &radiance_;
  return o;
}

std::string PicTechnique::cacheFile(const char* part, uint64_t key) const {
  if (cacheDir_.empty()) return {};
  char name[64];
  std::snprintf(name, sizeof name, "pic_%s_%016llx.bin", part, static_cast<unsigned long long>(key));
  return cacheDir_ + "/" + name;
}

void PicTechnique::precomputeMesh(const FrameResources& frame) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto& v = frame.realVertices();
  mesh_ = {};
  mesh_.positions.reserve(v.size());
  for (const MeshVertex& x : v) {
    mesh_.positions.push_back(x.position);
    mesh_.normals.push_back(x.normal);
    mesh_.albedo.push_back(x.albedo);
  }
  mesh_.indices = frame.realIndices();
  rays_ = std::make_unique<reconstruction::MeshRays>(mesh_.positions, mesh_.indices);
  // The saved precompute's key: the geometry (positions, normals, triangles: the surfels' albedo is read
  // again from the mesh) and the knobs it depends on.
  uint64_t key = hashBytes(mesh_.indices.data(), mesh_.indices.size() * sizeof(uint32_t));
  key = hashBytes(mesh_.positions.data(), mesh_.positions.size() * sizeof(cv::Vec3f), key);
  key = hashBytes(mesh_.normals.data(), mesh_.normals.size() * sizeof(cv::Vec3f), key);
  for (int k : {knobs_.surfels, knobs_.bands, knobs_.links, knobs_.receivers, 1 /* format */})
    key = hashBytes(&k, sizeof k, key);
  geometryKey_ = key;
  const std::string file = cacheFile("mesh", key);
  pic::MeshPrecompute saved;
  if (!file.empty() && pic::loadMeshPrecompute(file, key, saved)) {
    surfels_ = std::move(saved.surfels);
    hierarchy_ = std::move(saved.hierarchy);
    receivers_ = std::move(saved.receivers);
    receiverLinks_ = std::move(saved.receiverLinks);
    pic::updateAlbedo(surfels_, mesh_);
    ++cacheLoads_;
    stats_["precompute_loaded_ms"] = msSince(t0);
  } else {
    const auto report = [this](double f) {
      if (progress_) progress_("pic precompute", f);
    };
    report(0.0);
    surfels_ = pic::placeSurfels(mesh_, {knobs_.surfels, 3}, rays_.get());
    const double msSurfels = msSince(t0);
    report(0.05);
    const auto t1 = std::chrono::steady_clock::now();
    hierarchy_ = pic::buildHierarchy(surfels_);
    const double msHierarchy = msSince(t1);
    report(0.1);
    const auto t2 = std::chrono::steady_clock::now();
    receivers_ = knobs_.receivers > 0 ? pic::bounceReceivers(hierarchy_, knobs_.receivers) : pic::Receivers{};
    receiverLinks_ = pic::linkCaches(hierarchy_, surfels_, *rays_, receivers_.positions,
                                     {knobs_.bands, knobs_.links, 1}, [&](double f) { report(0.1 + 0.9 * f); });
    report(1.0);
    stats_["precompute_ms_surfels"] = msSurfels;
    stats_["precompute_ms_hierarchy"] = msHierarchy;
    stats_["precompute_ms_receivers"] = msSince(t2);
    ++precomputes_;
    if (!file.empty()) pic::saveMeshPrecompute(file, key, {surfels_, hierarchy_, receivers_, receiverLinks_});
  }

  // GPU: surfels, children and the inner nodes by level.
  uploadSurfels();
  std::vector<cv::Vec2i> children(hierarchy_.nodes.size(), cv::Vec2i(-1, -1));
  for (size_t k = 0; k < hierarchy_.nodes.size(); ++k)
    children[k] = {hierarchy_.nodes[k].child[0], hierarchy_.nodes[k].child[1]};
  children_ = bufferOf(children);
  levelsCount_ = hierarchy_.levels();
  levelFirst_.assign(static_cast<size_t>(std::max(levelsCount_, 1)), 0);
  levelCount_.assign(static_cast<size_t>(std::max(levelsCount_, 1)), 0);
  std::vector<int> ordered;
  for (int level = 1; level < levelsCount_; ++level) {
    levelFirst_[static_cast<size_t>(level)] = static_cast<int>(ordered.size());
    for (size_t k = hierarchy_.leaves; k < hierarchy_.nodes.size(); ++k)
      if (hierarchy_.nodes[k].level == level) ordered.push_back(static_cast<int>(k));
    levelCount_[static_cast<size_t>(level)] =
        static_cast<int>(ordered.size()) - levelFirst_[static_cast<size_t>(level)];
  }
  levelNodes_ = bufferOf(ordered);
  const size_t nodes = std::max<size_t>(hierarchy_.nodes.size(), 1);
  fluxF_ = gl::Buffer::storage(nodes * 16);
  fluxP_ = gl::Buffer::storage(nodes * 4);
  uploadLinks(receiverLinks_, receiverNodes_, receiverFactors_, receiverTransfer_);
  receiverSh_ = gl::Buffer::storage(std::max<size_t>(receivers_.positions.size(), 1) * cacheFloats(knobs_) * 4);
  receiversLit_ = false;
  visibilityLights_.clear();
  visibility_ = {};
  gridValid_ = false;
}

void PicTechnique::uploadSurfels() {
  // pic.glsl PicSurfel: position and area, normal and the receiver's index (-1: none), albedo.
  std::vector<cv::Vec4f> s;
  s.reserve(3 * surfels_.size());
  for (size_t i = 0; i < surfels_.size(); ++i) {
    const pic::Surfel& x = surfels_[i];
    const float r = i < receivers_.ofSurfel.size() ? static_cast<float>(receivers_.ofSurfel[i]) : -1.0f;
    s.push_back({x.position[0], x.position[1], x.position[2], x.area});
    s.push_back({x.normal[0], x.normal[1], x.normal[2], r});
    s.push_back({x.albedo[0], x.albedo[1], x.albedo[2], 0.0f});
  }
  surfelBuffer_ = bufferOf(s);
}

void PicTechnique::uploadLinks(const pic::CacheLinks& links, gl::Buffer& nodes, gl::Buffer& factors,
                               gl::Buffer& transfer) {
  nodes = bufferOf(links.node);
  factors = bufferOf(links.factor);
  transfer = bufferOf(links.transfer);
}

void PicTechnique::placeGrid(const cv::Vec3f& centre, float side) {
  const auto t0 = std::chrono::steady_clock::now();
  gridCentre_ = centre;
  gridSide_ = side;
  uint64_t key = hashBytes(&geometryKey_, sizeof geometryKey_);
  key = hashBytes(&centre, sizeof centre, key);
  key = hashBytes(&side, sizeof side, key);
  key = hashBytes(&knobs_.grid, sizeof knobs_.grid, key);
  const std::string file = cacheFile("grid", key);
  const auto nodes = static_cast<int32_t>(hierarchy_.nodes.size());
  const auto valid = [&](const pic::CacheLinks& l) {
    if (l.caches() != static_cast<size_t>(knobs_.grid * knobs_.grid * knobs_.grid) || l.bands != knobs_.bands)
      return false;
    return std::all_of(l.node.begin(), l.node.end(), [&](int32_t k) { return k >= -1 && k < nodes; });
  };
  if (!file.empty() && pic::loadCacheLinks(file, key, caches_) && valid(caches_)) {
    ++cacheLoads_;
  } else {
    caches_ = pic::linkCaches(hierarchy_, surfels_, *rays_, pic::gridCaches(gridCentre_, gridSide_, knobs_.grid),
                              {knobs_.bands, knobs_.links, 1}, [this](double f) {
                                if (progress_) progress_("pic caches", f);
                              });
    if (!file.empty()) pic::saveCacheLinks(file, key, caches_);
  }
  uploadLinks(caches_, cacheNodes_, cacheFactors_, cacheTransfer_);
  cacheBack_ = bufferOf(caches_.backFraction);
  cacheSh_ = gl::Buffer::storage(std::max<size_t>(caches_.caches(), 1) * cacheFloats(knobs_) * 4);
  gridValid_ = true;
  stats_["precompute_ms_caches"] = msSince(t0);
}

void PicTechnique::lightAndPull(const FrameResources& frame, bool bounce) {
  const gl::Program& p = lightProgram_;
  p.use();
  const auto n = static_cast<int>(surfels_.size());
  p.set("uCount", n);
  p.set("uPacked", knobs_.rgb9e5 ? 1 : 0);
  p.set("uBounce", bounce && receiversLit_ ? 1 : 0);
  setLightUniforms(p, frame.lights(), {});  // the visibility bits stand for the shadow maps
  setAmbientUniforms(p, frame);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, surfelBuffer_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, visibility_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, fluxF_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, fluxP_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, receiverSh_.id());
  glDispatchCompute(static_cast<GLuint>((n + 63) / 64), 1, 1);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  const gl::Program& q = pullProgram_;
  q.use();
  q.set("uPacked", knobs_.rgb9e5 ? 1 : 0);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, children_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 6, levelNodes_.id());
  for (int level = 1; level < levelsCount_; ++level) {
    const int count = levelCount_[static_cast<size_t>(level)];
    if (count == 0) continue;
    q.set("uFirst", levelFirst_[static_cast<size_t>(level)]);
    q.set("uCount", count);
    glDispatchCompute(static_cast<GLuint>((count + 63) / 64), 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  }
}

void PicTechnique::gather(const FrameResources& frame, bool receivers) {
  const pic::CacheLinks& links = receivers ? receiverLinks_ : caches_;
  if (links.caches() == 0) return;
  const gl::Program& p = gatherProgram_;
  p.use();
  // The ambient's 9 coefficients (pic.h Ambient::coefficients) as YCoCg: the gather subtracts T a.
  pic::Ambient a;
  a.uniform = cv::Vec3f(frame.ambient());
  for (size_t k = 0; k < 9; ++k) a.sh[k] = cv::Vec3f(frame.ambientSh()[k]);
  const auto coefficients = a.coefficients();
  for (size_t k = 0; k < 9; ++k)
    setVec3(p, std::string("uAmbientCoefficients[") + std::to_string(k) + "]",
            cv::Vec3d(pic::toYCoCg(coefficients[k])));
  p.set("uCount", static_cast<int>(links.caches()));
  p.set("uLinks", links.links);
  p.set("uPacked", knobs_.rgb9e5 ? 1 : 0);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, fluxF_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, fluxP_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 7, (receivers ? receiverNodes_ : cacheNodes_).id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 8, (receivers ? receiverFactors_ : cacheFactors_).id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 9, (receivers ? receiverTransfer_ : cacheTransfer_).id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 10, (receivers ? receiverSh_ : cacheSh_).id());
  glDispatchCompute(static_cast<GLuint>((links.caches() + 63) / 64), 1, 1);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  if (receivers) receiversLit_ = true;
}

void PicTechnique::update(const FrameResources& frame, gl::Profiler* profiler) {
  fb_.bind();
  glViewport(0, 0, frame.techniqueView().width, frame.techniqueView().height);
  const float zero[4] = {0, 0, 0, 0};
  glClearNamedFramebufferfv(fb_.id(), GL_COLOR, 0, zero);
  glClearNamedFramebufferfv(fb_.id(), GL_COLOR, 1, zero);
  if (!frame.region()) return;
  {
    auto s = timed(profiler, "pic.precompute", false);
    const auto& v = frame.realVertices();
    const auto& idx = frame.realIndices();
    // The geometry's key: positions and triangles (the albedo is read again without a precompute).
    uint64_t key = hashBytes(idx.data(), idx.size() * sizeof(uint32_t));
    uint64_t albedo = 1469598103934665603ull;
    for (const MeshVertex& x : v) {
      key = hashBytes(&x.position, sizeof(x.position), key);
      albedo = hashBytes(&x.albedo, sizeof(x.albedo), albedo);
    }
    if (key != meshKey_ || !rays_) {
      precomputeMesh(frame);
      meshKey_ = key;
      albedoKey_ = albedo;
    } else if (albedo != albedoKey_) {
      for (size_t i = 0; i < v.size() && i < mesh_.albedo.size(); ++i) mesh_.albedo[i] = v[i].albedo;
      pic::updateAlbedo(surfels_, mesh_);
      uploadSurfels();
      albedoKey_ = albedo;
    }
    // The grid covers the region with a cache spacing's margin, its centre on a lattice of that spacing: it
    // is re-linked only when the objects move by a spacing, and is the same for the same region whatever came
    // before (a fresh pipeline gets the same caches).
    const Region& r = *frame.region();
    const double h = r.side / std::max(knobs_.grid, 1);
    cv::Vec3f centre;
    for (int a = 0; a < 3; ++a) centre[a] = static_cast<float>(std::round(r.centre()[a] / h) * h);
    const auto side = static_cast<float>(r.side + h);
    if (!gridValid_ || centre != gridCentre_ || side != gridSide_) placeGrid(centre, side);
  }
  if (surfels_.empty() || hierarchy_.root < 0) return;
  {
    auto s = timed(profiler, "pic.visibility", false);
    if (!visibility_.id() || !sameShadows(frame.lights(), visibilityLights_)) {
      std::vector<SceneLight> lights(
          frame.lights().begin(),
          frame.lights().begin() + static_cast<std::ptrdiff_t>(std::min<size_t>(frame.lights().size(), kMaxLights)));
      const std::vector<uint8_t> vis = pic::surfelVisibility(surfels_, lights, *rays_);
      std::vector<uint32_t> bits(surfels_.size(), 0);
      for (size_t i = 0; i < surfels_.size(); ++i)
        for (size_t l = 0; l < lights.size(); ++l)
          if (vis[i * lights.size() + l]) bits[i] |= 1u << l;
      visibility_ = bufferOf(bits);
      visibilityLights_ = frame.lights();
    }
  }
  {
    auto s = timed(profiler, "pic.light");
    // Not progressive: every run starts from the direct light and adds `bounces` (the same result for the same
    // inputs); progressive: the receivers keep the last run's light, so each run adds bounces to it.
    if (!knobs_.progressive) receiversLit_ = false;
    for (int b = 0; b < knobs_.bounces && !receivers_.positions.empty(); ++b) {
      lightAndPull(frame, true);
      gather(frame, true);
    }
    lightAndPull(frame, !receivers_.positions.empty());
  }
  {
    auto s = timed(profiler, "pic.gather");
    gather(frame, false);
  }
  auto s = timed(profiler, "pic.readout");
  fb_.bind();
  glViewport(0, 0, frame.techniqueView().width, frame.techniqueView().height);
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_BLEND);
  const gl::Program& p = readoutProgram_;
  p.use();
  frame.techniqueView().bind();
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 10, cacheSh_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 11, cacheBack_.id());
  setVec3(p, "uGridCentre", cv::Vec3d(gridCentre_));
  p.set("uGridSide", gridSide_);
  p.set("uGridResolution", knobs_.grid);
  const capture::Pose& T = frame.camera().T_world_camera;
  setVec3(p, "uCameraPosition", cv::Vec3d(T(0, 3), T(1, 3), T(2, 3)));
  setObjectLobes(p, frame);
  emptyVao_.bind();
  glDrawArrays(GL_TRIANGLES, 0, 3);
  gl::checkGlError("PicTechnique::update()");
  stats_["surfels"] = surfels_.size();
  stats_["nodes"] = hierarchy_.nodes.size();
  stats_["levels"] = levelsCount_;
  stats_["caches"] = caches_.caches();
  stats_["receivers"] = receivers_.positions.size();
  stats_["precomputes"] = precomputes_;
}

std::vector<cv::Vec3f> PicTechnique::downloadFlux() const {
  const size_t n = hierarchy_.nodes.size();
  std::vector<cv::Vec3f> out(n);
  if (n == 0) return out;
  if (knobs_.rgb9e5) {
    std::vector<uint32_t> p(n);
    fluxP_.download(0, static_cast<GLsizeiptr>(n * 4), p.data());
    for (size_t i = 0; i < n; ++i) out[i] = pic::unpackRgb9e5(p[i]);
  } else {
    std::vector<cv::Vec4f> f(n);
    fluxF_.download(0, static_cast<GLsizeiptr>(n * 16), f.data());
    for (size_t i = 0; i < n; ++i) out[i] = {f[i][0], f[i][1], f[i][2]};
  }
  return out;
}

std::vector<float> PicTechnique::downloadCaches(bool receivers) const {
  const size_t n = (receivers ? receiverLinks_ : caches_).caches() * cacheFloats(knobs_);
  std::vector<float> out(n);
  if (n > 0) (receivers ? receiverSh_ : cacheSh_).download(0, static_cast<GLsizeiptr>(n * 4), out.data());
  return out;
}

std::vector<cv::Vec3f> PicTechnique::decodeCache(const std::vector<float>& stored, size_t cache) const {
  const auto b2 = static_cast<size_t>(knobs_.bands * knobs_.bands),
             c2 = static_cast<size_t>(chromaBands() * chromaBands());
  const float* x = &stored[cache * cacheFloats(knobs_)];
  std::vector<cv::Vec3f> out(b2);
  for (size_t i = 0; i < b2; ++i)
    out[i] = pic::fromYCoCg({x[i], i < c2 ? x[b2 + i] : 0.0f, i < c2 ? x[b2 + c2 + i] : 0.0f});
  return out;
}

cv::Mat PicTechnique::debugImage(const std::string& view, const DebugContext& context, nlohmann::json& info) const {
  if (view != "pic_surfels" && view != "pic_caches" && view != "pic_cut") return {};
  if (!context.T_world_camera || context.composite.empty()) return {};
  cv::Mat img = context.composite.clone();
  const capture::Pose T_camera_world = capture::inversePose(*context.T_world_camera);
  const auto project = [&](const cv::Vec3f& p, cv::Point& px) {
    const cv::Vec4d c = T_camera_world * cv::Vec4d(p[0], p[1], p[2], 1.0);
    if (c[2] <= 1e-3) return false;
    px = {static_cast<int>(context.intrinsics.fx * c[0] / c[2] + context.intrinsics.cx),
          static_cast<int>(context.intrinsics.fy * c[1] / c[2] + context.intrinsics.cy)};
    return px.x >= 0 && px.y >= 0 && px.x < img.cols && px.y < img.rows;
  };
  int drawn = 0;
  if (view == "pic_cut") {
    // The hierarchy cut linked to the cache nearest the grid's centre (white ring): each linked node's surfels
    // in one colour of its own; surfels it does not see (no linked node holds them) are left out.
    if (caches_.caches() == 0) return img;
    size_t centre = 0;
    for (size_t c = 1; c < caches_.caches(); ++c)
      if (cv::norm(caches_.positions[c] - gridCentre_) < cv::norm(caches_.positions[centre] - gridCentre_)) centre = c;
    const auto L = static_cast<size_t>(caches_.links);
    int linked = 0;
    for (size_t l = 0; l < L; ++l) {
      const int32_t node = caches_.node[centre * L + l];
      if (node < 0) continue;
      ++linked;
      const uint32_t h = static_cast<uint32_t>(node) * 2654435761u;
      const cv::Scalar colour(64 + (h & 127), 64 + ((h >> 8) & 127), 64 + ((h >> 16) & 127));
      std::vector<int32_t> stack{node};
      while (!stack.empty()) {
        const int32_t k = stack.back();
        stack.pop_back();
        const pic::Node& n = hierarchy_.nodes[static_cast<size_t>(k)];
        if (n.child[0] >= 0) {
          stack.push_back(n.child[0]);
          stack.push_back(n.child[1]);
          continue;
        }
        cv::Point px;
        if (!project(surfels_[static_cast<size_t>(k)].position, px)) continue;
        cv::circle(img, px, 2, colour, cv::FILLED);
        ++drawn;
      }
    }
    cv::Point px;
    if (project(caches_.positions[centre], px)) cv::circle(img, px, 5, cv::Scalar(255, 255, 255), 2);
    info["cache"] = centre;
    info["linked_nodes"] = linked;
    info["surfels_drawn"] = drawn;
    return img;
  }
  if (view == "pic_surfels") {
    // Each surfel a dot coloured by its radiosity (flux / area), white at the 95th percentile of their
    // brightest channel.
    const std::vector<cv::Vec3f> flux = downloadFlux();
    std::vector<float> level;
    for (size_t i = 0; i < surfels_.size() && i < flux.size(); ++i)
      level.push_back(std::max({flux[i][0], flux[i][1], flux[i][2]}) / surfels_[i].area);
    float peak = 1e-12f;
    if (!level.empty()) {
      std::vector<float> sorted = level;
      const size_t at = sorted.size() * 95 / 100;
      std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(at), sorted.end());
      peak = std::max(peak, sorted[at]);
    }
    for (size_t i = 0; i < level.size(); ++i) {
      cv::Point px;
      if (!project(surfels_[i].position, px)) continue;
      const cv::Vec3f c = flux[i] / (surfels_[i].area * peak) * 255.0f;
      cv::circle(img, px, 2, cv::Scalar(c[0], c[1], c[2]), cv::FILLED);
      ++drawn;
    }
    info["radiosity_peak"] = peak;
    info["surfels_drawn"] = drawn;
  } else {
    // Each cache a dot: its mean incident radiance (band 0: the room's light minus the ambient it hides),
    // white at the largest magnitude, outlined red where negative (the room hides more ambient than it
    // sends) and grey where the cache lies behind geometry.
    const std::vector<float> stored = downloadCaches(false);
    std::vector<cv::Vec3f> mean(caches_.caches());
    float peak = 1e-12f;
    for (size_t c = 0; c < caches_.caches(); ++c) {
      mean[c] = decodeCache(stored, c)[0] * static_cast<float>(sh::kY00);
      peak = std::max(peak, std::max({std::abs(mean[c][0]), std::abs(mean[c][1]), std::abs(mean[c][2])}));
    }
    for (size_t c = 0; c < caches_.caches(); ++c) {
      cv::Point px;
      if (!project(caches_.positions[c], px)) continue;
      const cv::Vec3f m = mean[c];
      const bool behind = caches_.backFraction[c] > 0.5f, negative = m[0] + m[1] + m[2] < 0;
      const cv::Scalar fill = behind ? cv::Scalar(128, 128, 128)
                                     : cv::Scalar(std::abs(m[0]) / peak * 255.0f, std::abs(m[1]) / peak * 255.0f,
                                                  std::abs(m[2]) / peak * 255.0f);
      cv::circle(img, px, 3, fill, cv::FILLED);
      cv::circle(img, px, 4, negative ? cv::Scalar(255, 0, 0) : cv::Scalar(255, 255, 255), 1);
      ++drawn;
    }
    info["mean_radiance_peak"] = peak;
    info["caches_drawn"] = drawn;
  }
  return img;
}

size_t PicTechnique::gpuBytes() const {
  size_t sum = irradiance_.bytes() + radiance_.bytes();
  for (const gl::Buffer* b :
       {&surfelBuffer_, &visibility_, &children_, &levelNodes_, &cacheNodes_, &cacheFactors_, &cacheTransfer_,
        &cacheBack_, &cacheSh_, &receiverNodes_, &receiverFactors_, &receiverTransfer_, &receiverSh_})
    sum += static_cast<size_t>(b->id() ? b->size() : 0);
  sum += static_cast<size_t>(knobs_.rgb9e5 ? (fluxP_.id() ? fluxP_.size() : 0) : (fluxF_.id() ? fluxF_.size() : 0));
  return sum;
}

}  // namespace mrgi::lighting
