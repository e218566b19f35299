// The GLSL SH twin (lighting/sh.glsl) against the C++ reference (lighting/sh.h), on llvmpipe in CI.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gl/context.h"
#include "gl/error.h"
#include "gl/objects.h"
#include "gl/program.h"
#include "lighting/sh.h"

using namespace mrgi;

TEST(GL, ShGlslMatchesCpuReference) {
  gl::ContextConfig cfg;
  cfg.width = 16, cfg.height = 16;
  auto ctx = gl::createContext(cfg);
  const int B = 8, n = 512, stride = B * B + 2 * B;
  std::mt19937 rng(4);
  std::normal_distribution<float> g;
  std::vector<cv::Vec4f> dirs(n);
  std::vector<float> alphas(n);
  for (int i = 0; i < n; ++i) {
    cv::Vec3f d(g(rng), g(rng), g(rng));
    d = cv::normalize(d);
    const float exponent = std::pow(10.f, -1.f + 5.f * i / n);  // 0.1 .. 1e4
    dirs[i] = {d[0], d[1], d[2], exponent};
    alphas[i] = std::min(static_cast<float>(CV_PI), std::pow(10.f, -6.f + 6.5f * i / n));  // 1e-6 .. pi
  }
  gl::Buffer dirBuf(n * sizeof(cv::Vec4f), dirs.data()), alphaBuf(n * sizeof(float), alphas.data());
  gl::Buffer out(n * stride * sizeof(float), nullptr);
  gl::Program prog = gl::Program::compute("lighting/shaders/sh_eval.comp", {{"SH_BANDS", "8"}});
  prog.use();
  prog.set("uCount", n);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, dirBuf.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, alphaBuf.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, out.id());
  glDispatchCompute((n + 63) / 64, 1, 1);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  std::vector<float> gpu(n * stride);
  out.download(0, gpu.size() * sizeof(float), gpu.data());
  gl::checkGlError("sh_eval");
  double worstY = 0, worstS = 0, worstCone = 0;
  for (int i = 0; i < n; ++i) {
    const auto y = lighting::sh::evaluate(cv::Vec3d(dirs[i][0], dirs[i][1], dirs[i][2]), B);
    const auto s = lighting::sh::phongLobeFactors(dirs[i][3], B);
    const auto z = lighting::sh::coneZonal(alphas[i], B);
    const double zScale = std::max(1e-30, std::abs(z[0]));  // cone coefficients scale with the cone's area
    for (int k = 0; k < B * B; ++k) worstY = std::max(worstY, std::abs(gpu[i * stride + k] - y[k]));
    for (int l = 0; l < B; ++l) {
      worstS = std::max(worstS, std::abs(gpu[i * stride + B * B + l] - s[l]));
      worstCone = std::max(worstCone, std::abs(gpu[i * stride + B * B + B + l] - z[l]) / zScale);
      ASSERT_TRUE(std::isfinite(gpu[i * stride + B * B + B + l])) << alphas[i];
    }
  }
  // float vs double: basis values are O(1) with up to 8th-degree polynomials (measured ~1e-6).
  EXPECT_LT(worstY, 2e-5);
  EXPECT_LT(worstS, 2e-5);
  EXPECT_LT(worstCone, 1e-4);  // relative to the cone's band-0 coefficient, alpha from 1e-6 to pi
}
