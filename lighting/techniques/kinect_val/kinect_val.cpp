#include "lighting/techniques/kinect_val/kinect_val.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "capture/colour.h"
#include "gl/error.h"
#include "lighting/debug_views.h"
#include "lighting/techniques/registry.h"

namespace mrgi::lighting {

const std::vector<KnobBinding<KinectValKnobs>>& kinectValKnobTable() {
  static const std::vector<KnobBinding<KinectValKnobs>> table = {
      {{"sparse_points", KnobType::Int, 16, 16384, 1024, "sparse shading points per object", {256, 4096}, {64}, true},
       &KinectValKnobs::sparsePoints},
      {{"k_cache", KnobType::Int, 16, 512, 128, "VALs per shared-memory tile of the gather", {32, 512}, {}, true},
       &KinectValKnobs::kCache},
      {{"occlusion",
        KnobType::Bool,
        0,
        1,
        1,
        "disc-occluder approximation of the object's self-occlusion",
        {0, 1},
        {0, 1}},
       &KinectValKnobs::occlusion},
      {{"stride", KnobType::Int, 1, 64, 4, "RGB-D pixel stride of the real-surface VALs", {2, 8}, {}, false},
       &KinectValKnobs::stride},
      {{"rsm_stride", KnobType::Int, 1, 64, 2, "RSM texel stride of the object's own VALs", {}, {}, false},
       &KinectValKnobs::rsmStride},
      {{"fusion", KnobType::Bool, 0, 1, 1, "fuse real VALs over frames in a world-space surfel map", {0, 1}, {}},
       &KinectValKnobs::fusion},
      {{"voxel", KnobType::Real, 1e-3, 1.0, 0.02, "surfel voxel of the fusion, metres", {}, {}, true},
       &KinectValKnobs::voxel},
      {{"decay",
        KnobType::Real,
        0.0,
        1.0,
        0.0,
        "confidence a surfel keeps per frame that should have seen it but did not (above 0 the same surface "
        "quantised into neighbouring voxels counts twice)",
        {},
        {},
        false},
       &KinectValKnobs::decay},
      {{"brute_force", KnobType::Bool, 0, 1, 0, "reference: every VAL gathered at every visible virtual pixel", {}, {}},
       &KinectValKnobs::bruteForce},
  };
  return table;
}

TechniqueInfo kinectValTechniqueInfo() {
  TechniqueInfo t;
  t.name = "kinect-val";
  t.description =
      "Kinect-VAL: real RGB-D surfaces and the object's lit texels as area lights on the object (diffuse + glossy)";
  t.real = false;
  t.virtualObject = true;
  t.stagePrefixes = {"val."};
  t.knobs = groupOf("val", kinectValKnobTable());
  t.create = [](const TechniqueSetup& s) { return std::make_unique<KinectValTechnique>(s); };
  t.estimateBytes = [](const KnobValues& k, const KnobValues& frame, bool, bool, int w, int h, size_t lights) {
    // Radiance and irradiance targets, and the slots of the virtual VALs (twice: built, then in the set).
    const size_t slots = std::max<size_t>(lights, 1) * ValGpu::rsmValCapacity(static_cast<int>(frame.at("rsm_size")),
                                                                              static_cast<int>(k.at("rsm_stride")));
    return 2 * 16 * static_cast<size_t>(w) * static_cast<size_t>(h) + 2 * slots * sizeof(Val);
  };
  return t;
}

namespace {
/// A receiver at (p, n) seen from `eye`.
Receiver seenFrom(const cv::Vec3f& p, const cv::Vec3f& n, const cv::Vec3f& eye, float exponent) {
  const cv::Vec3f toEye = eye - p;
  return {p, n, cv::norm(toEye) > 0 ? cv::normalize(toEye) : n, exponent};
}

}  // namespace

KinectValTechnique::KinectValTechnique(const TechniqueSetup& setup)
    : knobs_(knobsFrom(kinectValKnobTable(), setup.knobs)),
      gpu_(knobs_.kCache),
      meshProgram_(gl::Program::graphics("lighting/techniques/kinect_val/val_mesh.vert",
                                         "lighting/techniques/kinect_val/val_mesh.frag")) {
  const FrameResources& frame = *setup.frame;
  // Sparse points and per-vertex weights depend on the mesh only (model space): computed once.
  for (const FrameObject& fo : frame.objects()) {
    const VirtualObject& o = fo.source;
    Object vo;
    vo.material = o.material;
    vo.points = sampleSparsePoints(o.mesh, knobs_.sparsePoints);
    const VertexWeights w = vertexWeights(o.mesh, vo.points);
    constexpr int K = VertexWeights::kNeighbours;
    static_assert(K == 8);
    struct Packed {
      int32_t index[8];
      float weight[8];
    };
    std::vector<Packed> packed(o.mesh.positions.size());
    for (size_t v = 0; v < packed.size(); ++v)
      for (int k = 0; k < K; ++k) {
        packed[v].index[k] = w.index[v * K + k];
        packed[v].weight[k] = w.weight[v * K + k];
      }
    vo.weights = gl::Buffer(static_cast<GLsizeiptr>(std::max<size_t>(packed.size(), 1) * sizeof(Packed)),
                            packed.empty() ? nullptr : packed.data());
    objects_.push_back(std::move(vo));
  }
  radiance_ = gl::Texture(GL_TEXTURE_2D, GL_RGBA32F, frame.width(), frame.height());
  irradiance_ = gl::Texture(GL_TEXTURE_2D, GL_RGBA32F, frame.width(), frame.height());
  radiance_.setFilter(GL_NEAREST, GL_NEAREST);
  irradiance_.setFilter(GL_NEAREST, GL_NEAREST);
  fb_.attachColour(0, radiance_);
  fb_.attachColour(1, irradiance_);
  fb_.attachDepth(frame.gDepth());
  fb_.finalise(2);
}

std::unique_ptr<TechniqueInputBuilder> KinectValTechnique::inputBuilder() const {
  SurfelOptions surfels;
  surfels.voxel = static_cast<float>(knobs_.voxel);
  surfels.decay = static_cast<float>(knobs_.decay);
  return std::make_unique<RealValBuilder>(knobs_.stride, knobs_.fusion, surfels);
}

void KinectValTechnique::beginLights(const FrameResources& frame, gl::Profiler*) {
  gpu_.beginVirtual(frame.lights().size() * ValGpu::rsmValCapacity(frame.rsmRho().position.width(), knobs_.rsmStride));
}

void KinectValTechnique::light(const FrameResources& frame, size_t index, gl::Profiler* profiler) {
  // The virtual object's lit texels become VALs (virtual -> virtual bounce), compacted on the GPU.
  auto s = timed(profiler, "val.rsm_vals");
  gpu_.appendRsmVals(frame.rsmRho(), frame.lights().at(index), knobs_.rsmStride);
}

void KinectValTechnique::update(const FrameResources& frame, gl::Profiler* profiler) {
  const CameraView& camera = frame.camera();
  const cv::Vec3f eye(capture::translationOf(camera.T_world_camera));
  static const std::vector<Val> kNone;
  const auto* input = dynamic_cast<const RealVals*>(frame.techniqueInput(name()));
  const std::vector<Val>& realVals = input ? input->vals : kNone;
  stats_ = {realVals.size(), 0, 0, 0, knobs_.bruteForce};
  transforms_.clear();
  for (const FrameObject& o : frame.objects()) transforms_.push_back(o.T_world_object);
  // The real VALs up, then on the GPU: dimmed where the objects shadow them, the virtual ones of the light
  // stage after them, weighed (nothing read back; the counts are read when stats are asked for). Only when
  // something they depend on changed: the world-space half of the technique, not the camera's.
  const FrameVersions& v = frame.versions();
  const std::array<uint64_t, 4> key{v.geometry, v.lights, v.ambient, v.own};
  if (assembled_ != key) {  // a new input of its own bumps `own`
    auto s = timed(profiler, "val.upload");
    gpu_.assemble(realVals, frame);
    assembled_ = key;
  }
  const float zero[4] = {0, 0, 0, 0};
  glClearNamedFramebufferfv(fb_.id(), GL_COLOR, 0, zero);
  glClearNamedFramebufferfv(fb_.id(), GL_COLOR, 1, zero);
  if (knobs_.bruteForce) {
    bruteForce(frame, profiler);
  } else {
    // Receivers: every object's sparse points in the lighting world, seen from the camera.
    std::vector<Receiver> receivers;
    std::vector<cv::Vec3f> positions, normals;
    std::vector<float> radii;
    std::vector<int> base;
    for (size_t o = 0; o < objects_.size(); ++o) {
      const Object& vo = objects_[o];
      base.push_back(static_cast<int>(receivers.size()));
      const cv::Matx44d& T = frame.objects()[o].T_world_object;
      const cv::Matx33f N = normalMatrix(T);
      const float k = phongExponent(vo.material.roughness);
      for (size_t i = 0; i < vo.points.positions.size(); ++i) {
        const Receiver r = seenFrom(cv::Vec3f(capture::transformPoint(T, cv::Vec3d(vo.points.positions[i]))),
                                    cv::normalize(N * vo.points.normals[i]), eye, k);
        receivers.push_back(r);
        positions.push_back(r.position);
        normals.push_back(r.normal);
        radii.push_back(vo.points.discRadius[i]);
      }
    }
    stats_.receivers = receivers.size();
    {
      auto s = timed(profiler, "val.gather");
      gpu_.gather(receivers);
    }
    if (knobs_.occlusion) {
      auto s = timed(profiler, "val.occlude");
      gpu_.occlude(positions, normals, radii);
    }

    // Per-vertex interpolation and per-pixel evaluation on the visible virtual surfaces.
    auto s = timed(profiler, "val.shade");
    fb_.bind();
    glViewport(0, 0, frame.width(), frame.height());
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LEQUAL);
    glDepthMask(GL_FALSE);
    const gl::Program& p = meshProgram_;
    p.use();
    const auto vp = toGl(projectionFromIntrinsics(camera.intrinsics, camera.nearPlane, camera.farPlane) *
                         capture::inversePose(camera.T_world_camera));
    p.setMat4("uViewProj", vp.data());
    setVec3(p, "uEye", cv::Vec3d(eye));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, gpu_.vplBuffer().id());
    for (size_t o = 0; o < objects_.size(); ++o) {
      const Object& vo = objects_[o];
      const cv::Matx44d& T = frame.objects()[o].T_world_object;
      const auto m = toGl(T);
      p.setMat4("uModel", m.data());
      setMat3(p, "uNormalModel", normalMatrix(T));
      p.set("uBase", base[o]);
      setVec3(p, "uSpecular", cv::Vec3d(vo.material.specular, vo.material.specular, vo.material.specular));
      p.set("uExponent", phongExponent(vo.material.roughness));
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, vo.weights.id());
      frame.objects()[o].gpu.draw();
    }
    glDepthMask(GL_TRUE);
    glDepthFunc(GL_LESS);
    glDisable(GL_DEPTH_TEST);
  }

  // Per-run facts; flicker = frame-to-frame change of the sparse points' irradiance (model space, so a
  // moving camera alone changes nothing), relative to its mean.
  runStats_ = {{"real_vals", stats_.realVals}, {"receivers", stats_.receivers}};
  ++runs_;
}

void KinectValTechnique::bruteForce(const FrameResources& frame, gl::Profiler* profiler) {
  auto staging = timed(profiler, "val.bruteforce_staging", false);  // G-buffer read-back, radiance upload (CPU)
  // Every visible virtual pixel is a receiver of every VAL (no interpolation, no occlusion): the reference
  // the sparse method is measured against. The gather runs on the GPU; the per-pixel material comes from
  // the G-buffer (albedo) and the object index in the normal's w.
  const cv::Vec3f eye(capture::translationOf(frame.camera().T_world_camera));
  const cv::Mat pos = frame.downloadGBuffer(0), nrm = frame.downloadGBuffer(1), alb = frame.downloadGBuffer(2);
  std::vector<Receiver> receivers;
  std::vector<int> pixels, objects;
  for (int y = 0; y < pos.rows; ++y)
    for (int x = 0; x < pos.cols; ++x) {
      const cv::Vec4f p = pos.at<cv::Vec4f>(y, x), n = nrm.at<cv::Vec4f>(y, x), a = alb.at<cv::Vec4f>(y, x);
      if (p[3] < 0.5f || a[3] < 0.5f) continue;
      const int o = static_cast<int>(std::lround(n[3])) - 1;
      if (o < 0 || o >= static_cast<int>(objects_.size())) continue;
      receivers.push_back(
          seenFrom({p[0], p[1], p[2]}, {n[0], n[1], n[2]}, eye, phongExponent(objects_[o].material.roughness)));
      pixels.push_back(y * pos.cols + x);
      objects.push_back(o);
    }
  stats_.receivers = receivers.size();
  {
    auto s = timed(profiler, "val.gather");
    gpu_.gather(receivers);
  }
  std::vector<cv::Vec3f> E, S;
  gpu_.downloadSums(E, S);
  cv::Mat radiance(pos.size(), CV_32FC4, cv::Scalar::all(0)), irradiance(pos.size(), CV_32FC4, cv::Scalar::all(0));
  for (size_t i = 0; i < receivers.size(); ++i) {
    const Material& m = objects_[static_cast<size_t>(objects[i])].material;
    const cv::Vec4f a = alb.at<cv::Vec4f>(pixels[i]);
    const cv::Vec3f L = valRadiance(E[i], S[i], {a[0], a[1], a[2]}, cv::Vec3f::all(m.specular), receivers[i].exponent);
    radiance.at<cv::Vec4f>(pixels[i]) = {L[0], L[1], L[2], 1.f};
    irradiance.at<cv::Vec4f>(pixels[i]) = {E[i][0], E[i][1], E[i][2], 1.f};
  }
  radiance_.upload(GL_RGBA, GL_FLOAT, radiance.ptr(), 4);
  irradiance_.upload(GL_RGBA, GL_FLOAT, irradiance.ptr(), 4);
}

TechniqueOutputs KinectValTechnique::outputs() const {
  // The object's indirect light, shaded here with its material (diffuse and glossy): radiance only.
  TechniqueOutputs o;
  o.virtualRadiance = &radiance_;
  return o;
}

void KinectValTechnique::downloadValSums(std::vector<cv::Vec3f>& E, std::vector<cv::Vec3f>& S) const {
  gpu_.downloadSums(E, S);
}

KinectValTechnique::Stats KinectValTechnique::valStats() const {
  Stats s = stats_;
  if (runs_ > 0) {
    const ValGpu::Counts c = gpu_.downloadCounts();
    s.virtualVals = c.virtualVals;
    s.shadowedVals = c.dimmed;
  }
  return s;
}

nlohmann::json KinectValTechnique::stats() const {
  if (statsRun_ != runs_) {
    statsRun_ = runs_;
    std::vector<cv::Vec3f> E, S;
    gpu_.downloadSums(E, S);
    double sum = 0;
    for (const auto& e : E) sum += capture::luminance(cv::Vec3d(e));
    const ValGpu::Counts c = gpu_.downloadCounts();
    irradianceStats_ = {{"mean_irradiance", E.empty() ? 0.0 : sum / static_cast<double>(E.size())},
                        {"virtual_vals", c.virtualVals},
                        {"shadowed_vals", c.dimmed}};
    if (!stats_.bruteForce && !prevE_.empty() && prevE_.size() == E.size() && sum > 0) {
      double change = 0;
      for (size_t i = 0; i < E.size(); ++i)
        change += std::abs(capture::luminance(cv::Vec3d(E[i])) - capture::luminance(cv::Vec3d(prevE_[i])));
      irradianceStats_["flicker"] = change / sum;
    }
    prevE_ = stats_.bruteForce ? std::vector<cv::Vec3f>() : E;
  }
  nlohmann::json out = runStats_;
  if (runs_ > 0) out.update(irradianceStats_);
  return out;
}

cv::Mat KinectValTechnique::debugImage(const std::string& view, const DebugContext& context,
                                       nlohmann::json& info) const {
  if (view == "val_irradiance") {
    // Bounce irradiance the virtual object receives, on a linear scale.
    const cv::Mat e = download4(irradiance_);
    cv::Mat rgb, lum, mask;
    cv::cvtColor(e, rgb, cv::COLOR_RGBA2RGB);
    cv::cvtColor(rgb, lum, cv::COLOR_RGB2GRAY);
    cv::extractChannel(e, mask, 3);
    mask.convertTo(mask, CV_8U, 255);
    double lo = 0, hi = 0;
    cv::minMaxLoc(lum, &lo, &hi, nullptr, nullptr, mask);
    info["debug_val_irradiance_max"] = hi;
    return linearImage(rgb, hi > 0 ? 1.0 / hi : 0.0);
  }
  if (view == "val_sparse_points") {
    if (!context.T_world_camera || context.composite.empty()) return {};
    cv::Mat img = context.composite.clone();
    std::vector<cv::Vec3f> E, S;
    gpu_.downloadSums(E, S);
    double maxE = 1e-12;
    for (const auto& e : E) maxE = std::max(maxE, capture::luminance(cv::Vec3d(e)));
    const capture::Pose T_camera_world = capture::inversePose(*context.T_world_camera);
    const capture::Intrinsics& k = context.intrinsics;
    size_t at = 0;
    for (size_t oi = 0; oi < objects_.size(); ++oi) {
      const auto& pts = objects_[oi].points;
      const capture::Pose T = T_camera_world * transforms_.at(oi);
      for (size_t i = 0; i < pts.positions.size(); ++i, ++at) {
        const cv::Vec3d c = capture::transformPoint(T, cv::Vec3d(pts.positions[i]));
        const cv::Vec3d n = capture::rotationOf(T) * cv::Vec3d(pts.normals[i]);
        if (c[2] <= 0 || n.dot(c) > 0) continue;  // behind the camera or on the far side of the object
        const double e = at < E.size() ? capture::luminance(cv::Vec3d(E[at])) / maxE : 0.0;
        const auto g = cv::saturate_cast<uchar>(255.0 * std::sqrt(e));
        cv::circle(img, cv::Point2d(k.fx * c[0] / c[2] + k.cx, k.fy * c[1] / c[2] + k.cy), 2, cv::Scalar(g, g, 255 - g),
                   cv::FILLED, cv::LINE_AA);
      }
    }
    info["debug_sparse_points"] = at;
    return img;
  }
  return {};
}

size_t KinectValTechnique::gpuBytes() const { return radiance_.bytes() + irradiance_.bytes(); }

}  // namespace mrgi::lighting
