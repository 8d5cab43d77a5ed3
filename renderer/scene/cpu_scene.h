#pragma once
// The CPU-side scene: what the glTF importer and the demo-scene generator produce, and what
// GpuScene uploads. Plain data; no Vulkan, no tinygltf.
#include <algorithm>
#include <array>
#include <cstdint>
#include <glm/glm.hpp>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "renderer/scene/animation.h"

namespace tessera {

// Axis-aligned bounding box. Default-constructed it is empty (min > max).
struct Aabb {
  glm::vec3 min{std::numeric_limits<float>::max()};
  glm::vec3 max{std::numeric_limits<float>::lowest()};

  bool empty() const { return min.x > max.x || min.y > max.y || min.z > max.z; }
  void extend(const glm::vec3& p) {
    min = glm::min(min, p);
    max = glm::max(max, p);
  }
  void extend(const Aabb& b) {
    if (!b.empty()) {
      extend(b.min);
      extend(b.max);
    }
  }
  glm::vec3 center() const { return (min + max) * 0.5f; }
  glm::vec3 extent() const { return max - min; }
  // Corner i (0..7): bit 0 picks max.x over min.x, bit 1 max.y, bit 2 max.z.
  glm::vec3 corner(int i) const {
    return glm::vec3(i & 1 ? max.x : min.x, i & 2 ? max.y : min.y, i & 4 ? max.z : min.z);
  }
  // Distance from `p` to the farthest corner (0 for an empty box).
  float farthest_distance(const glm::vec3& p) const {
    float d = 0.0f;
    if (!empty())
      for (int i = 0; i < 8; ++i) d = std::max(d, glm::length(corner(i) - p));
    return d;
  }
  // Radius of the sphere around center() that encloses the box.
  float radius() const { return empty() ? 0.0f : glm::length(max - min) * 0.5f; }
  // The AABB of this box after an affine transform (exact for the transformed box's corners).
  Aabb transformed(const glm::mat4& m) const;
};

// The single vertex layout of the scene vertex buffer (attribute locations in
// shaders/common/gpu_types.h). 64 bytes.
struct Vertex {
  glm::vec3 position{0.0f};
  glm::vec3 normal{0.0f, 0.0f, 1.0f};
  glm::vec4 tangent{1.0f, 0.0f, 0.0f, 1.0f};  // xyz tangent, w bitangent sign
  glm::vec2 uv0{0.0f};
  glm::vec2 uv1{0.0f};
  // COLOR_0, linear RGBA in [0, 1], as IEEE halves: (r, g) and (b, a) each packed as GLSL's
  // packHalf2x16 (PackVertexColor). White where the file gives none. A scene built in code sets
  // its primitive's vertex_colors too: the visibility shading reads colours only then.
  glm::uvec2 color{kWhiteHalves, kWhiteHalves};
  static constexpr uint32_t kWhiteHalves = 0x3C003C00u;  // two halves of 1.0
};

// `rgba` clamped to [0, 1] (a non-finite channel is 1) as Vertex::color holds it.
glm::uvec2 PackVertexColor(glm::vec4 rgba);
glm::vec4 UnpackVertexColor(glm::uvec2 packed);

enum class AlphaMode : uint32_t { kOpaque = 0, kMask = 1, kBlend = 2 };
enum class WrapMode : uint32_t { kRepeat = 0, kClampToEdge = 1, kMirroredRepeat = 2 };

// Decoded RGBA8 pixels. Shared between textures that use the same glTF image.
struct Image {
  std::string name;  // the glTF image name or URI, for messages
  uint32_t width = 0;
  uint32_t height = 0;
  std::vector<uint8_t> rgba8;  // width * height * 4 bytes, top row first
};

// A glTF texture as a material uses it: image + sampler + colour space.
struct Texture {
  std::shared_ptr<const Image> image;
  bool srgb = false;  // base colour and emissive are sRGB, data textures are linear
  WrapMode wrap_s = WrapMode::kRepeat;
  WrapMode wrap_t = WrapMode::kRepeat;
};

// A material's use of a texture (glTF textureInfo + KHR_texture_transform).
struct TextureRef {
  int32_t texture = -1;   // index into CpuScene::textures; -1 = none
  uint32_t texcoord = 0;  // TEXCOORD_n set, 0 or 1
  glm::vec2 offset{0.0f};
  glm::vec2 scale{1.0f};
  float rotation = 0.0f;  // radians
  // The 3x2 uv transform of KHR_texture_transform: uv' = T * R * S * uv.
  glm::mat3 uv_transform() const;
};

struct Material {
  std::string name;
  glm::vec4 base_color_factor{1.0f};
  float metallic_factor = 1.0f;
  float roughness_factor = 1.0f;
  glm::vec3 emissive_factor{0.0f};
  float emissive_strength = 1.0f;  // KHR_materials_emissive_strength
  float normal_scale = 1.0f;
  float occlusion_strength = 1.0f;
  AlphaMode alpha_mode = AlphaMode::kOpaque;
  float alpha_cutoff = 0.5f;
  bool double_sided = false;
  // KHR_materials_unlit: the surface's colour is its base colour (factor x texture), not lit;
  // alpha mode and double-sidedness still apply, every other property is ignored.
  bool unlit = false;
  // KHR_materials_ior and KHR_materials_specular: the dielectric's reflectance. Its F0 is
  // ((ior - 1) / (ior + 1))^2 (0.04 at the default 1.5; ior 0 gives 1) times the specular colour,
  // clamped to 1, times the specular factor, which is also its F90. Metals are unaffected.
  float ior = 1.5f;
  float specular_factor = 1.0f;
  glm::vec3 specular_color_factor{1.0f};
  TextureRef base_color;
  TextureRef metallic_roughness;
  TextureRef normal;
  TextureRef occlusion;
  TextureRef emissive;
  TextureRef specular_color;  // rgb, sRGB: multiplies specular_color_factor
  TextureRef specular;        // alpha: multiplies specular_factor

  // Every texture slot, in the order of gpu::GpuMaterial's (bindings kBindingBaseColorTex on).
  std::array<const TextureRef*, 7> TextureSlots() const {
    return {&base_color, &metallic_roughness, &normal,  &occlusion,
            &emissive,   &specular_color,     &specular};
  }
};

// One glTF primitive as an indexed triangle list inside the scene's single vertex and index
// buffers. Indices are relative to first_vertex.
struct Primitive {
  uint32_t first_index = 0;
  uint32_t index_count = 0;
  uint32_t first_vertex = 0;
  uint32_t vertex_count = 0;
  uint32_t material = 0;  // index into CpuScene::materials (always valid)
  Aabb bounds;            // object space (at rest)
  bool skinned = false;   // has JOINTS_0 and WEIGHTS_0 (CpuScene::skin_joints/skin_weights)
  // The file gave no normals: face normals, each triangle with its own three vertices in order
  // (vertex 3t + k is corner k of triangle t), so a deformed pose recomputes them.
  bool flat_normals = false;
  // The file gave COLOR_0 (Vertex::color multiplies the base colour; else every vertex is white).
  bool vertex_colors = false;
  // Morph targets: target t's delta for the primitive's vertex v is
  // CpuScene::morph_deltas[first_morph_delta + t * vertex_count + v].
  uint32_t morph_targets = 0;
  uint64_t first_morph_delta = 0;
};

// One vertex's displacement by one morph target (glTF 3.7.2.2).
struct MorphDelta {
  glm::vec3 position{0.0f};
  glm::vec3 normal{0.0f};
  glm::vec3 tangent{0.0f};
};

// A glTF skin: the joints (node indices) and their inverse bind matrices.
struct Skin {
  std::string name;
  std::vector<uint32_t> joints;
  std::vector<glm::mat4> inverse_bind;  // one per joint (identity when the file gives none)
};

struct Mesh {
  std::string name;
  std::vector<uint32_t> primitives;  // indices into CpuScene::primitives
};

// One instance of one primitive: what a draw call draws.
struct Drawable {
  glm::mat4 world{1.0f};
  uint32_t primitive = 0;
  uint32_t mesh = 0;
  uint32_t node = 0;  // glTF node index, for messages
  Aabb world_bounds;
  // EXT_mesh_gpu_instancing: this instance's transform under its node (`world` is the node's
  // world transform times it; an animated node's drawables are posed so). Identity otherwise.
  glm::mat4 instance{1.0f};
};

enum class LightType : uint32_t { kDirectional = 0, kPoint = 1, kSpot = 2 };

// KHR_lights_punctual light placed in the world by its node.
struct Light {
  std::string name;
  LightType type = LightType::kPoint;
  glm::vec3 color{1.0f};
  float intensity = 1.0f;  // candela (point/spot), lux (directional)
  float range = 0.0f;      // 0 = infinite
  glm::vec3 position{0.0f};
  glm::vec3 direction{0.0f, 0.0f, -1.0f};  // where the light points, normalized
  float inner_cone_angle = 0.0f;           // radians
  float outer_cone_angle = 0.7853982f;     // radians (pi/4)
  int32_t node = -1;                       // the glTF node that places it (-1: generated)
};

// Whether the renderer shades `l` as a local light, culled per tile (a point or spot light with a
// range), rather than as a global one (directional, or reaching everywhere).
inline bool IsLocalLight(const Light& l) {
  return !(l.type == LightType::kDirectional || l.range <= 0.0f);
}

// A perspective camera from the file, with its node's world transform.
struct SceneCamera {
  std::string name;
  glm::mat4 world{1.0f};  // camera looks down its local -Z, +Y up
  float yfov = 0.8f;      // radians
  float aspect = 0.0f;    // 0 = not given
  float znear = 0.01f;
  float zfar = 0.0f;  // 0 = infinite
  int32_t node = -1;  // the glTF node that places it
};

// Counts as the file declares them (glTF arrays) and as instanced by the default scene.
struct SceneCounts {
  uint32_t nodes = 0;       // glTF nodes
  uint32_t meshes = 0;      // glTF meshes
  uint32_t primitives = 0;  // glTF primitives over all meshes (each mesh counted once)
  uint64_t triangles = 0;   // triangles drawn: over every drawable of the default scene
  uint32_t materials = 0;   // glTF materials (without the default material)
  uint32_t textures = 0;    // glTF textures
  uint32_t images = 0;      // glTF images
  uint32_t lights = 0;      // KHR_lights_punctual lights placed in the scene
  uint32_t cameras = 0;     // cameras placed in the scene
};

struct CpuScene;
// For scenes built in code (one node per drawable, one image per texture): fills `counts`
// from the arrays.
void CountGeneratedScene(CpuScene& scene);

struct CpuScene {
  std::string name;
  std::vector<Vertex> vertices;
  std::vector<uint32_t> indices;
  std::vector<Primitive> primitives;
  std::vector<Mesh> meshes;
  std::vector<Material> materials;  // the file's, plus a default one when a primitive has none
  std::vector<Texture> textures;
  std::vector<Drawable> drawables;
  std::vector<Light> lights;
  std::vector<SceneCamera> cameras;
  std::vector<SceneNode> nodes;        // every glTF node (animation.h); empty for generated scenes
  std::vector<Animation> animations;   // validated; sampled by EvaluatePose
  std::vector<Skin> skins;
  // Per vertex of `vertices` when any primitive is skinned (else empty): up to 4 joints (indices
  // into the skin of the node that draws it) and their weights (zero for unskinned vertices).
  std::vector<glm::uvec4> skin_joints;
  std::vector<glm::vec4> skin_weights;
  std::vector<MorphDelta> morph_deltas;  // see Primitive::first_morph_delta
  Aabb bounds;  // world bounds of all drawables
  SceneCounts counts;
  std::vector<std::string> warnings;  // things skipped or fixed up on import
};

}  // namespace tessera
