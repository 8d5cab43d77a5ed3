// libFuzzer target: glTF/GLB import from an in-memory file set (file_set.h), the whole path an
// upload takes on the server (pre-scan, tinygltf, image decoding, validation, CPU scene
// building), without the device upload, under FuzzImportLimits() (file_set.h).
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "renderer/scene/gltf_import.h"
#include "tests/fuzz/file_set.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const tessera::ImportLimits limits = tessera::fuzz::FuzzImportLimits();
  const tessera::GltfSource source = tessera::fuzz::UnpackFileSet(data, size);
  absl::StatusOr<tessera::CpuScene> scene = tessera::ImportGltf(source, limits);
  if (scene.ok()) {
    // What the renderer trusts of a scene: every index in range, every number finite.
    const tessera::CpuScene& s = *scene;
    for (const tessera::Drawable& d : s.drawables) {
      if (d.primitive >= s.primitives.size() || d.mesh >= s.meshes.size()) __builtin_trap();
    }
    for (const tessera::Primitive& p : s.primitives) {
      if (uint64_t(p.first_index) + p.index_count > s.indices.size()) __builtin_trap();
      if (uint64_t(p.first_vertex) + p.vertex_count > s.vertices.size()) __builtin_trap();
      if (p.material >= s.materials.size()) __builtin_trap();
      for (uint32_t i = p.first_index; i < p.first_index + p.index_count; ++i)
        if (s.indices[i] >= p.vertex_count) __builtin_trap();
    }
    auto finite = [](const glm::vec3& v) {
      return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
    };
    for (const tessera::Drawable& d : s.drawables)
      if (!finite(d.world_bounds.min) || !finite(d.world_bounds.max)) __builtin_trap();
    for (const tessera::Light& l : s.lights)
      if (!finite(l.color * l.intensity) || !finite(l.position) || !std::isfinite(l.range))
        __builtin_trap();
    for (const tessera::Material& m : s.materials) {
      for (const tessera::TextureRef* r :
           {&m.base_color, &m.metallic_roughness, &m.normal, &m.occlusion, &m.emissive}) {
        if (r->texture < -1 || r->texture >= int32_t(s.textures.size())) __builtin_trap();
      }
    }
    for (const tessera::Texture& t : s.textures) {
      if (t.image == nullptr ||
          t.image->rgba8.size() != size_t(t.image->width) * t.image->height * 4)
        __builtin_trap();
    }
  }
  return 0;
}
