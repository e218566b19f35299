#include "lighting/reference/scene.h"

namespace mrgi::lighting::reference {

int Scene::addMaterial(Material m) {
  materials.push_back(std::move(m));
  return static_cast<int>(materials.size()) - 1;
}

void Scene::addQuad(cv::Vec3f p0, cv::Vec3f e1, cv::Vec3f e2, int material) {
  const int base = static_cast<int>(vertices.size());
  vertices.insert(vertices.end(), {p0, p0 + e1, p0 + e1 + e2, p0 + e2});
  uvs.insert(uvs.end(), {{0, 0}, {1, 0}, {1, 1}, {0, 1}});
  triangles.push_back({base, base + 1, base + 2});
  triangles.push_back({base, base + 2, base + 3});
  triangleMaterial.insert(triangleMaterial.end(), {material, material});
}

void Scene::addBox(cv::Vec3f lo, cv::Vec3f hi, int material, bool inward) {
  const cv::Vec3f d = hi - lo;
  const cv::Vec3f ex(d[0], 0, 0), ey(0, d[1], 0), ez(0, 0, d[2]);
  auto quad = [&](cv::Vec3f p, cv::Vec3f a, cv::Vec3f b) {
    if (inward) addQuad(p, b, a, material);
    else addQuad(p, a, b, material);
  };
  quad(lo, ez, ey);              // -x
  quad(lo + ex, ey, ez);         // +x
  quad(lo, ex, ez);              // -y
  quad(lo + ey, ez, ex);         // +y
  quad(lo, ey, ex);              // -z
  quad(lo + ez, ex, ey);         // +z
}

}  // namespace mrgi::lighting::reference
