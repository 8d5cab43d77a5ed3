#pragma once
// The scene on the device: one vertex buffer, one index buffer, Drawable and Material storage
// buffers, and the textures in sampler2DArray buckets by size and colour space.
#include <cstdint>
#include <map>
#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "renderer/scene/cpu_scene.h"
#include "renderer/scene/scene_animator.h"
#include "renderer/vk/context.h"
#include "renderer/vk/resources.h"
#include "shaders/common/gpu_types.h"

namespace tessera {

// Where each texture lives: bucket (one sampler2DArray) and layer. Pure data, so the
// bucketing rules are unit-tested without a device.
struct TextureBucketPlan {
  struct Bucket {
    uint32_t width = 0, height = 0;
    bool srgb = false;
    uint32_t layers = 0;
  };
  std::vector<Bucket> buckets;  // at most gpu::kMaxTextureBuckets
  struct Slot {
    uint32_t bucket = 0, layer = 0;
  };
  std::vector<Slot> slots;  // one per texture
};

// Sizes are rounded to powers of two (at most `max_size` per side) so textures of similar
// size share a bucket; while there are more than kMaxTextureBuckets buckets, the bucket with
// the fewest layers is merged into the same-colour-space bucket closest in area.
TextureBucketPlan PlanTextureBuckets(const std::vector<Texture>& textures, uint32_t max_size);

// Textures larger than this on a side are downscaled into their bucket.
inline constexpr uint32_t kMaxTextureSide = 4096;

// What GpuScene::Upload(scene) will count as device_bytes(): buffers at their requested sizes
// and texture buckets with their mip chains. `uniform_align` is the device's
// minUniformBufferOffsetAlignment, `max_texture_size` the bucket side limit Upload uses.
uint64_t EstimateDeviceBytes(const CpuScene& scene, uint32_t max_texture_size,
                             uint64_t uniform_align);

// One draw: a drawable and what state it needs.
struct DrawItem {
  uint32_t drawable = 0;  // index into the Drawable buffer; becomes firstInstance
  uint32_t material = 0;  // selects the material's texture descriptor set
  uint32_t first_index = 0;
  uint32_t index_count = 0;
  int32_t vertex_offset = 0;
  AlphaMode alpha = AlphaMode::kOpaque;
  bool double_sided = false;
  Aabb world_bounds;
};

// How the draws are grouped for indirect drawing (pure data, unit-tested). Items are the
// scene's draws in draw order: opaque, alpha-mask, blend; within a group single-sided before
// double-sided, then by material, then by drawable. A segment is a run of items with one
// pipeline state (group, cull mode, material) and becomes one vkCmdDrawIndexedIndirectCount; a
// blended item is a segment of its own, because blending needs back-to-front order, which the
// CPU sorts each frame. A batch is a run of opaque items with one cull mode: the depth prepass
// reads no material, so it draws the whole opaque group with one indirect draw per cull mode.
struct DrawSegment {
  AlphaMode group = AlphaMode::kOpaque;
  bool double_sided = false;
  uint32_t material = 0;
  uint32_t first_item = 0, item_count = 0;
};
struct DrawBatch {
  bool double_sided = false;
  uint32_t first_item = 0, item_count = 0;
};
struct DrawPlan {
  std::vector<uint32_t> order;  // item i draws draws[order[i]]
  std::vector<DrawSegment> segments;
  std::vector<DrawBatch> batches;
};
DrawPlan PlanDraws(const std::vector<DrawItem>& draws);

// glTF (3.7.2.1): the determinant of a node's world transform gives its triangles' winding:
// counter-clockwise front faces where it is positive, clockwise where negative (a mirrored
// node). The pipelines cull with counter-clockwise front faces, so a mirrored drawable draws a
// copy of its primitive's indices wound the other way: appended to the scene's index buffer,
// once per primitive (pure data, unit-tested). Skinned primitives keep their winding: glTF
// ignores a skinned mesh's node transform.
bool MirrorsWinding(const glm::mat4& world);
inline constexpr uint32_t kNotMirrored = 0xffffffffu;
struct MirrorPlan {
  std::vector<uint32_t> first;  // per primitive: its copy's first index, or kNotMirrored
  uint64_t indices = 0;         // indices appended after the scene's
  // The first index `d` draws from: its primitive's copy where it mirrors and has one.
  uint32_t FirstIndex(const CpuScene& scene, const Drawable& d) const {
    const bool copy = MirrorsWinding(d.world) && first[d.primitive] != kNotMirrored;
    return copy ? first[d.primitive] : scene.primitives[d.primitive].first_index;
  }
};
MirrorPlan PlanMirroredRanges(const CpuScene& scene);
// Appends the copies to `indices` (the scene's) and their neighbours to `adjacency`
// (TriangleAdjacency's: each copy's triangles keep their numbers, and so their neighbours).
// `surfaces` (SurfaceIndices', adjacency.h) likewise, corner for corner as the indices.
void AppendMirroredRanges(const CpuScene& scene, const MirrorPlan& plan,
                          std::vector<uint32_t>& indices, std::vector<uint32_t>& adjacency,
                          std::vector<uint32_t>& surfaces);

class GpuScene {
 public:
  // Uploads `scene` and waits for the copies. Errors: RESOURCE_EXHAUSTED when device memory
  // runs out, INVALID_ARGUMENT when the scene exceeds a device limit (e.g. array layers).
  // `material_layout` is the layout of descriptor set 1 (gpu::kMaterialSet): one set per
  // material is allocated and written here; with `bucket_layout`, also the bucket set
  // (gpu::kBindingBuckets: every bucket, for the visibility shading that indexes them).
  static absl::StatusOr<std::unique_ptr<GpuScene>> Upload(
      vk::Context& ctx, const CpuScene& scene, VkDescriptorSetLayout material_layout,
      VkDescriptorSetLayout bucket_layout = VK_NULL_HANDLE);
  ~GpuScene();

  const vk::Buffer& vertices() const { return vertices_; }
  const vk::Buffer& indices() const { return indices_; }
  // Per index, the triangle across that edge (adjacency.h), for vis_mlaa_coverage analytic.
  const vk::Buffer& adjacency() const { return adjacency_; }
  // Per index, the vertex that stands for it in vis_mlaa's surface test (SurfaceIndices,
  // adjacency.h), laid out as the index buffer; and as a texel buffer (R32_UINT) beside
  // index_texels().
  const vk::Buffer& surfaces() const { return surfaces_; }
  VkBufferView surface_texels() const { return surface_texels_.get(); }
  const vk::Buffer& drawables() const { return drawables_; }
  const vk::Buffer& materials() const { return materials_; }
  // The index, vertex and drawable buffers as uniform texel buffers for the visibility passes
  // (R32_UINT, R32G32_UINT, R32G32B32A32_UINT: gpu_types.h, kVisBindingIndexTexels), each over
  // as much of its buffer as maxTexelBufferElements allows. vis_texels(): they cover the whole
  // buffers and DeviceInfo::texel_buffers is on: the visibility passes read them instead of the
  // storage buffers.
  VkBufferView index_texels() const { return index_texels_.get(); }
  VkBufferView vertex_texels() const { return vertex_texels_.get(); }
  VkBufferView drawable_texels() const { return drawable_texels_.get(); }
  bool vis_texels() const { return vis_texels_; }
  // The texture buckets; a scene without textures has one 1x1 placeholder, so every material
  // set binding is valid.
  const std::vector<vk::Image>& texture_buckets() const { return buckets_; }
  // Descriptor set 1 of material `m`: the material as a uniform range and its textures' buckets.
  VkDescriptorSet material_set(uint32_t m) const { return material_sets_[m]; }
  // The bucket set (every bucket; slots past the scene's buckets hold bucket 0), where Upload
  // was given its layout; else null.
  VkDescriptorSet bucket_set() const { return bucket_set_; }
  uint32_t material_count() const { return uint32_t(material_sets_.size()); }
  // The texture slots material `m` has a texture in (bit k: slot k, gpu::kMaterialTexturesAll),
  // gpu::kMaterialVertexColors where its primitives have vertex colours, and
  // gpu::kMaterialTintedSpecular where its specular colour may be tinted; the distinct sets of
  // them the scene's materials have, ascending: the shading passes build a pipeline per set
  // (shading.glsl's specialization constant 1).
  uint32_t material_textures(uint32_t m) const { return material_textures_[m]; }
  const std::vector<uint32_t>& texture_sets() const { return texture_sets_; }
  VkSampler sampler() const { return sampler_.handle(); }
  // The draws in item order (DrawPlan): draws()[i] is item i.
  const std::vector<DrawItem>& draws() const { return draws_; }
  const std::vector<DrawSegment>& segments() const { return plan_.segments; }
  const std::vector<DrawBatch>& batches() const { return plan_.batches; }
  // GpuCullItem per item, what cull.comp reads.
  const vk::Buffer& cull_items() const { return cull_items_; }
  const std::vector<Light>& lights() const { return lights_; }
  const Aabb& bounds() const { return bounds_; }
  uint64_t device_bytes() const { return device_bytes_; }
  // Unique per uploaded scene in this process (never reused, unlike the address): keys state
  // the renderer keeps per scene and view, such as TAA history.
  uint64_t serial() const { return serial_; }
  // Triangles of the largest draw (vis_mlaa: must fit an id's triangle field).
  uint32_t max_draw_triangles() const { return max_draw_triangles_; }

  // gpu_occlusion: each view's visibility bits (one per item) from its last frame, double
  // buffered: a frame reads bits[prev] and writes the other. Kept by the renderer, under its
  // mutex; it drops the least recently used view past a small number of views.
  struct ViewVisibility {
    vk::Buffer bits[2];
    uint32_t prev = 0;
    uint64_t last_used = 0;
  };
  std::map<uint64_t, ViewVisibility>& views() const { return views_; }

  // Animation (scene_animator.h). Pose() poses the scene for a frame: the moving drawables' world
  // bounds here (draws(), bounds()) and their records, joint matrices and morph weights in the
  // pose buffer, for the skinning pass to copy and apply. Returns whether the pose changed; the
  // renderer calls it under its lock, so frames of different scene times take turns.
  bool animated() const { return animator_ != nullptr; }
  const SceneAnimator* animator() const { return animator_.get(); }
  bool Pose(int animation, double scene_time, bool loop);
  // The item (draws() index) of drawable `d` of an animated scene.
  uint32_t item_of(uint32_t d) const { return item_of_drawable_[d]; }
  // The device does not hold the last Pose yet: the frame's skinning pass must run (and then
  // PoseRecorded()).
  bool pose_pending() const { return pose_pending_; }
  void PoseRecorded() { pose_pending_ = false; }
  // Changes with every new pose (0 for a scene that never moves): cached shadow maps key on it.
  uint64_t pose_serial() const { return pose_serial_; }
  // What the skinning pass binds, and its copies of the moving drawables' records from the pose
  // buffer into drawables() (one region each).
  const vk::Buffer& skin_attributes() const { return skin_attributes_; }
  const vk::Buffer& morph_deltas() const { return morph_deltas_; }
  const vk::Buffer& pose_buffer() const { return pose_; }
  const std::vector<VkBufferCopy>& pose_copies() const { return pose_copies_; }
  // skin.comp's jobs (gpu::GpuSkinJob, one per deformed drawable), how many, and the workgroups
  // they need in all.
  const vk::Buffer& skin_jobs() const { return skin_jobs_; }
  uint32_t skin_job_count() const { return animator_ ? uint32_t(animator_->skin_jobs()) : 0u; }
  uint64_t skin_groups() const { return skin_groups_; }

 private:
  // Upload's steps: the draws in item order with their GPU records, the buffers, the texture
  // buckets and sampler, one descriptor set per material.
  void PlanScene(const CpuScene& scene, std::vector<gpu::GpuDrawable>* drawables,
                 std::vector<gpu::GpuCullItem>* items);
  absl::Status UploadBuffers(vk::Context& ctx, const CpuScene& scene,
                             const std::vector<gpu::GpuMaterial>& materials,
                             const std::vector<gpu::GpuDrawable>& drawables,
                             const std::vector<gpu::GpuCullItem>& items);
  absl::Status UploadAnimation(vk::Context& ctx, const CpuScene& scene);
  // Takes `src` into `dst`, counting it in device_bytes().
  absl::Status Keep(vk::Buffer& dst, absl::StatusOr<vk::Buffer> src);
  absl::Status MakeTexelViews(vk::Context& ctx, const std::string& name);
  absl::Status UploadTextures(vk::Context& ctx, const CpuScene& scene,
                              const TextureBucketPlan& plan);
  absl::Status WriteMaterialSets(vk::Context& ctx, const std::vector<gpu::GpuMaterial>& materials,
                                 VkDescriptorSetLayout material_layout,
                                 VkDescriptorSetLayout bucket_layout);

  vk::Buffer vertices_, indices_, adjacency_, surfaces_, drawables_, materials_;
  // after their buffers
  vk::UniqueBufferView index_texels_, vertex_texels_, drawable_texels_, surface_texels_;
  bool vis_texels_ = false;
  vk::Buffer material_uniforms_;  // the materials again, each at a uniform-offset-aligned stride
  VkDeviceSize material_stride_ = 0;
  std::vector<vk::Image> buckets_;
  vk::Sampler sampler_;
  VkDevice device_ = VK_NULL_HANDLE;
  vk::UniqueDescriptorPool material_pool_;
  std::vector<VkDescriptorSet> material_sets_;
  VkDescriptorSet bucket_set_ = VK_NULL_HANDLE;
  std::vector<uint32_t> material_textures_, texture_sets_;
  std::vector<DrawItem> draws_;
  DrawPlan plan_;
  vk::Buffer cull_items_;
  mutable std::map<uint64_t, ViewVisibility> views_;
  std::vector<Light> lights_;
  Aabb bounds_;
  uint64_t device_bytes_ = 0;
  uint64_t serial_ = 0;
  uint32_t max_draw_triangles_ = 0;
  MirrorPlan mirrors_;  // PlanScene's, for UploadBuffers
  // Animation: the animator, each drawable's item (draws_ index), the bounds of the drawables
  // that never move, and the device side (see the accessors).
  std::unique_ptr<SceneAnimator> animator_;
  std::vector<uint32_t> item_of_drawable_;
  Aabb static_bounds_;
  vk::Buffer skin_attributes_, morph_deltas_, pose_;
  VkDeviceSize pose_weights_offset_ = 0, pose_records_offset_ = 0;
  std::vector<VkBufferCopy> pose_copies_;
  vk::Buffer skin_jobs_;
  uint64_t skin_groups_ = 0;
  std::vector<gpu::GpuDrawable> records_;  // per animator drawable, its record (Pose rewrites)
  bool pose_pending_ = false;
  uint64_t pose_serial_ = 0;
};

// The pose buffer's layout for an animator: joint matrices, then morph weights, then the moving
// drawables' records (16-byte aligned). Shared with EstimateDeviceBytes.
struct PoseLayout {
  VkDeviceSize weights_offset = 0, records_offset = 0, size = 0;
};
PoseLayout PlanPoseBuffer(const SceneAnimator& animator);

}  // namespace tessera
