#include "renderer/scene/cpu_scene.h"

#include <cmath>
#include <glm/gtc/packing.hpp>

namespace tessera {

Aabb Aabb::transformed(const glm::mat4& m) const {
  if (empty()) return {};
  // Arvo's method: the transformed box is the centre moved plus |M| times the half extent.
  const glm::vec3 c = glm::vec3(m * glm::vec4(center(), 1.0f));
  const glm::vec3 h = extent() * 0.5f;
  glm::vec3 r(0.0f);
  for (int col = 0; col < 3; ++col) r += glm::abs(glm::vec3(m[col])) * h[col];
  Aabb out;
  out.min = c - r;
  out.max = c + r;
  return out;
}

glm::uvec2 PackVertexColor(glm::vec4 rgba) {
  for (int c = 0; c < 4; ++c)
    rgba[c] = std::isfinite(rgba[c]) ? std::clamp(rgba[c], 0.0f, 1.0f) : 1.0f;
  return glm::uvec2(glm::packHalf2x16(glm::vec2(rgba.r, rgba.g)),
                    glm::packHalf2x16(glm::vec2(rgba.b, rgba.a)));
}

glm::vec4 UnpackVertexColor(glm::uvec2 packed) {
  return glm::vec4(glm::unpackHalf2x16(packed.x), glm::unpackHalf2x16(packed.y));
}

glm::mat3 TextureRef::uv_transform() const {
  // glTF KHR_texture_transform: T * R * S, with R rotating uv by -rotation (column-major).
  const float c = std::cos(rotation), s = std::sin(rotation);
  const glm::mat3 t(1, 0, 0, 0, 1, 0, offset.x, offset.y, 1);
  const glm::mat3 r(c, -s, 0, s, c, 0, 0, 0, 1);
  const glm::mat3 sc(scale.x, 0, 0, 0, scale.y, 0, 0, 0, 1);
  return t * r * sc;
}

void CountGeneratedScene(CpuScene& scene) {
  SceneCounts& c = scene.counts;
  c = SceneCounts{};
  c.nodes = static_cast<uint32_t>(scene.drawables.size());
  c.meshes = static_cast<uint32_t>(scene.meshes.size());
  c.primitives = static_cast<uint32_t>(scene.primitives.size());
  for (const Drawable& d : scene.drawables)
    c.triangles += scene.primitives[d.primitive].index_count / 3;
  c.materials = static_cast<uint32_t>(scene.materials.size());
  c.textures = static_cast<uint32_t>(scene.textures.size());
  c.images = static_cast<uint32_t>(scene.textures.size());
  c.lights = static_cast<uint32_t>(scene.lights.size());
  c.cameras = static_cast<uint32_t>(scene.cameras.size());
}

}  // namespace tessera
