#pragma once
// Shadows on the CPU side (pure math, unit-tested without a device): the sun's cascades, the
// views of spot and point lights, which local lights get shadows, and the atlas that holds
// every shadow map of a frame and caches them between frames.
//
// Conventions shared with the shadow pass and shaders/common/shadows.glsl:
//  - Shadow maps use standard Z (near 0, far 1; the atlas is cleared to 1, rendered LESS and
//    compared LESS_OR_EQUAL), unlike the camera's reverse Z.
//  - A view's `view_proj` maps world to Vulkan clip space of its face: x, y in [-1, 1] across
//    the whole face (borders included), y down (NDC -1 is the face's top row, as the viewport
//    puts it), depth 0..1.
//  - `world_to_atlas` is view_proj followed by the face's placement in the atlas: after the
//    divide by w, xy is the atlas texture coordinate (0..1 over the whole atlas) and z the
//    depth to compare.
//  - Every map keeps a border of kShadowBorderTexels texels around the region its light
//    needs, so the 4 bilinear taps of the 3x3 PCF never read a neighbouring map.
#include <cstdint>
#include <glm/glm.hpp>
#include <optional>
#include <vector>

#include "renderer/camera.h"
#include "renderer/scene/cpu_scene.h"

namespace tessera {

inline constexpr uint32_t kShadowBorderTexels = 2;
inline constexpr uint32_t kMaxCascades = 4;
// Point-light faces in the order the shader picks them: +X, -X, +Y, -Y, +Z, -Z.
inline constexpr uint32_t kCubeFaces = 6;

// ---- the sun's cascades ------------------------------------------------------------------------
struct CascadeParams {
  uint32_t count = 4;         // 1..kMaxCascades
  uint32_t resolution = 1024; // texels per side of each cascade's map (border included)
  float split_lambda = 0.75f; // practical split: blend of logarithmic (1) and uniform (0)
};

struct Cascade {
  float split_near = 0.0f, split_far = 0.0f;  // view distances of the camera slice covered
  // The slice's bounding sphere: its radius depends only on the split distances and the
  // field of view (not on the camera's rotation), so the map's world size never changes as the
  // camera turns; its centre is snapped to whole texels in the light's basis.
  glm::vec3 center{0.0f};
  float radius = 0.0f;
  float texel_world = 0.0f;  // world size of one texel of this cascade
  // The snapped centre in the light's basis (x, y): always a whole multiple of texel_world.
  glm::vec2 light_origin{0.0f};
  glm::mat4 view_proj{1.0f};  // world -> clip (orthographic), see the conventions above
};

// An orthonormal basis for a light direction that depends on the direction alone (so texel
// snapping in it is stable): rows x, y are the map's axes, z = direction.
glm::mat3 LightBasis(glm::vec3 direction);

// Cascades covering the camera's view from its near plane to `shadow_distance` (view distance;
// callers pass the distance to the farthest corner of the scene bounds, capped by the far
// plane). The orthographic depth range covers `scene_bounds` along the light, so every caster
// in the scene is in the map. `sun_direction` is where the light travels (GpuLight direction).
std::vector<Cascade> ComputeCascades(const Camera& camera, float aspect, glm::vec3 sun_direction,
                                     const Aabb& scene_bounds, float shadow_distance,
                                     const CascadeParams& params);

// ---- spot and point lights --------------------------------------------------------------------
// The near plane of a local light's shadow views: a small fraction of its range.
float ShadowNear(const Light& light);
// The far plane: the light's range, or (range 0, unbounded) the farthest corner of the scene.
float ShadowFar(const Light& light, const Aabb& scene_bounds);

// A spot light's perspective view over its outer cone, widened so the border texels lie
// outside the cone.
glm::mat4 SpotViewProj(const Light& light, uint32_t resolution, const Aabb& scene_bounds);

// Face f (+X, -X, +Y, -Y, +Z, -Z) of a point light's unrolled cubemap: a perspective view
// down that axis, wider than 90 degrees by the border: the 90-degree square covers
// resolution - 2 * kShadowBorderTexels texels in the middle of the face.
glm::mat4 PointFaceViewProj(const Light& light, uint32_t face, uint32_t resolution,
                            const Aabb& scene_bounds);

// Which face of a point light's cubemap a light-to-surface vector falls in: the axis of its
// largest component, positive before negative (the shader does the same comparisons).
uint32_t CubeFace(glm::vec3 light_to_surface);

// ---- which lights cast shadows --------------------------------------------------------------
// Indices into `lights` (point and spot lights with a range) of at most `count` lights to
// shadow: those whose sphere of influence meets the camera's frustum, the most important first
// (intensity x range^2 / distance^2 from the camera to the sphere, ties by index).
std::vector<uint32_t> ChooseShadowedLights(const std::vector<Light>& lights,
                                           const Frustum& camera_frustum, glm::vec3 camera_position,
                                           uint32_t count);

// ---- the atlas ---------------------------------------------------------------------------------
// A square of the atlas, in texels.
struct AtlasRect {
  uint32_t x = 0, y = 0, size = 0;
};

// world_to_atlas of a face placed at `rect` in an atlas `atlas_size` texels wide (see above).
glm::mat4 AtlasTransform(const AtlasRect& rect, uint32_t atlas_size);

// Places the faces (cascades, spot maps, cubemap faces) of a frame in one square atlas and
// remembers them between frames, so a face whose view has not changed is not rendered again.
// Faces are power-of-two squares from a quadtree (buddy) allocator: a face keeps its place
// while it is used; when there is no room, the faces least recently used (never those of the
// frame being built) are evicted, oldest first, until a block of the size is free.
class ShadowAtlas {
 public:
  // `size` is a power of two; `min_face` the smallest face handed out (a power of two).
  explicit ShadowAtlas(uint32_t size, uint32_t min_face = 64);

  uint32_t size() const { return size_; }

  // Starts a frame: faces acquired from now on belong to it and cannot be evicted by it.
  void BeginFrame();

  struct Placement {
    AtlasRect rect;
    bool cached = false;  // the face holds this content from an earlier frame: skip rendering
  };
  // The place of face `key` (a stable identity: the light and the face) at `size` texels with
  // contents `content` (a hash of everything the map depends on: its view, the scene...).
  // Cached when the face already holds exactly that; otherwise it is (re)placed and must be
  // rendered this frame. nullopt when even evicting every face of earlier frames leaves no
  // block of that size (the caller may ask again smaller, or leave the light unshadowed).
  std::optional<Placement> Acquire(uint64_t key, uint32_t size, uint64_t content);

  // Gives face `key` back (a light whose other faces did not fit: its placed faces must not stay
  // marked as holding contents that were never rendered). No-op for an unknown key.
  void Release(uint64_t key);

  // Forgets every face (after a failed frame, or when the atlas image is recreated).
  void Clear();

  // Statistics.
  uint32_t faces() const;            // faces held
  uint64_t texels_used() const;      // sum of their areas
  uint32_t evictions() const { return evictions_; }  // faces evicted since construction

 private:
  struct Face {
    AtlasRect rect;
    uint64_t content = 0;
    uint64_t last_frame = 0;
    uint32_t level = 0;
  };
  // The implementation keeps, per quadtree level, the free blocks, and the held faces by key.
  std::optional<AtlasRect> Allocate(uint32_t level);
  void Free(const AtlasRect& rect, uint32_t level);

  uint32_t size_;
  uint32_t min_face_;
  uint32_t levels_;  // level 0: the whole atlas; level L: blocks of size >> L
  uint64_t frame_ = 0;
  uint32_t evictions_ = 0;
  std::vector<std::vector<AtlasRect>> free_;  // per level
  std::vector<std::pair<uint64_t, Face>> held_;  // by key (small: a linear scan is fine)
};

// A 64-bit FNV-1a of raw bytes, for face contents (matrices, sizes, serials).
uint64_t HashBytes(const void* data, size_t size, uint64_t seed = 14695981039346656037ull);

}  // namespace tessera
