#include "groundtruth/scene.h"

namespace mrgi::groundtruth {

int Scene::addMaterial(Material m) {
  materials.push_back(std::move(m));
  return static_cast<int>(materials.size()) - 1;
}

void Scene::addQuad(cv::Vec3f p0, cv::Vec3f e1, cv::Vec3f e2, int material) {
  const int base = static_cast<int>(vertices.size());
  vertices.insert(vertices.end(), {p0, p0 + e1, p0 + e1 + e2, p0 + e2});
  uvs.insert(uvs.end(), {{0, 0}, {1, 0}, {1, 1}, {0, 1}});
  normals.resize(vertices.size(), cv::Vec3f(0, 0, 0));  // flat: the geometric normal
  vertexAlbedo.resize(vertices.size(), cv::Vec3f(1, 1, 1));
  triangles.push_back({base, base + 1, base + 2});
  triangles.push_back({base, base + 2, base + 3});
  triangleMaterial.insert(triangleMaterial.end(), {material, material});
}

void Scene::addMesh(const std::vector<cv::Vec3f>& positions, const std::vector<cv::Vec3f>& meshNormals,
                    const std::vector<uint32_t>& indices, int material, const cv::Matx44d& T) {
  const int base = static_cast<int>(vertices.size());
  const cv::Matx33d R(T(0, 0), T(0, 1), T(0, 2), T(1, 0), T(1, 1), T(1, 2), T(2, 0), T(2, 1), T(2, 2));
  const cv::Matx33d N = R.inv().t();  // normals transform by the inverse transpose (non-uniform scale)
  for (size_t i = 0; i < positions.size(); ++i) {
    const cv::Vec3d p = R * cv::Vec3d(positions[i]) + cv::Vec3d(T(0, 3), T(1, 3), T(2, 3));
    vertices.emplace_back(static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2]));
    cv::Vec3f n(0, 0, 0);
    if (i < meshNormals.size()) {
      const cv::Vec3d m = N * cv::Vec3d(meshNormals[i]);
      const double len = cv::norm(m);
      if (len > 0)
        n = cv::Vec3f(static_cast<float>(m[0] / len), static_cast<float>(m[1] / len), static_cast<float>(m[2] / len));
    }
    normals.push_back(n);
    uvs.emplace_back(0, 0);
    vertexAlbedo.emplace_back(1, 1, 1);
  }
  for (size_t t = 0; t + 2 < indices.size(); t += 3) {
    triangles.emplace_back(base + static_cast<int>(indices[t]), base + static_cast<int>(indices[t + 1]),
                           base + static_cast<int>(indices[t + 2]));
    triangleMaterial.push_back(material);
  }
}

void Scene::addBox(cv::Vec3f lo, cv::Vec3f hi, int material, bool inward) {
  const cv::Vec3f d = hi - lo;
  const cv::Vec3f ex(d[0], 0, 0), ey(0, d[1], 0), ez(0, 0, d[2]);
  auto quad = [&](cv::Vec3f p, cv::Vec3f a, cv::Vec3f b) {
    if (inward)
      addQuad(p, b, a, material);
    else
      addQuad(p, a, b, material);
  };
  quad(lo, ez, ey);       // -x
  quad(lo + ex, ey, ez);  // +x
  quad(lo, ex, ez);       // -y
  quad(lo + ey, ez, ex);  // +y
  quad(lo, ey, ex);       // -z
  quad(lo + ez, ex, ey);  // +z
}

}  // namespace mrgi::groundtruth
