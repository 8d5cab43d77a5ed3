// libFuzzer target: glTF/GLB import from an in-memory file set (file_set.h), the whole path an
// upload takes on the server (pre-scan, tinygltf, image decoding, validation, CPU scene
// building), without the device upload, under FuzzImportLimits() (file_set.h).
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "renderer/scene/gltf_import.h"
#include "renderer/scene/scene_animator.h"
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
      // The reflectance is finite and in range (MakeMaterial's F0 from the IOR, times the colour).
      if (!(m.ior == 0.0f || (m.ior >= 1.0f && std::isfinite(m.ior))) ||
          !(m.specular_factor >= 0.0f && m.specular_factor <= 1.0f) ||
          !finite(m.specular_color_factor) ||
          glm::any(glm::lessThan(m.specular_color_factor, glm::vec3(0.0f))))
        __builtin_trap();
      for (const tessera::TextureRef* r : m.TextureSlots()) {
        if (r->texture < -1 || r->texture >= int32_t(s.textures.size())) __builtin_trap();
      }
    }
    for (const tessera::Texture& t : s.textures) {
      if (t.image == nullptr ||
          t.image->rgba8.size() != size_t(t.image->width) * t.image->height * 4)
        __builtin_trap();
    }
    // Animation: the skinning pass reads joint matrices by the vertices' joint indices and
    // morph deltas by the primitives' ranges; poses at a few times, each animation.
    for (const tessera::Primitive& p : s.primitives) {
      if (p.morph_targets > 0 &&
          p.first_morph_delta + uint64_t(p.morph_targets) * p.vertex_count > s.morph_deltas.size())
        __builtin_trap();
    }
    if (std::unique_ptr<tessera::SceneAnimator> a = tessera::SceneAnimator::Create(s)) {
      for (const tessera::AnimatedDrawable& d : a->drawables()) {
        if (d.skin < 0) continue;
        const tessera::Primitive& p = s.primitives[d.primitive];
        const size_t joints = s.skins[size_t(d.skin)].joints.size();
        for (uint32_t v = p.first_vertex; v < p.first_vertex + p.vertex_count; ++v)
          for (int k = 0; k < 4; ++k)
            if (s.skin_weights[v][k] != 0.0f && s.skin_joints[v][k] >= joints) __builtin_trap();
      }
      for (int anim = -1; anim < int(s.animations.size()) && anim < 4; ++anim) {
        for (double t : {0.0, 0.37, 1e5}) a->Pose(anim, t, anim % 2 == 0);
      }
    }
  }
  return 0;
}
