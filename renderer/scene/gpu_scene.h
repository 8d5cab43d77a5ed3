#pragma once
// The scene on the device: one vertex buffer, one index buffer, Drawable and Material storage
// buffers, and the textures in sampler2DArray buckets by size and colour space.
#include <cstdint>
#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "renderer/scene/cpu_scene.h"
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

class GpuScene {
 public:
  // Uploads `scene` and waits for the copies. Errors: RESOURCE_EXHAUSTED when device memory
  // runs out, INVALID_ARGUMENT when the scene exceeds a device limit (e.g. array layers).
  // `material_layout` is the layout of descriptor set 1 (gpu::kMaterialSet): one set per
  // material is allocated and written here.
  static absl::StatusOr<std::unique_ptr<GpuScene>> Upload(vk::Context& ctx, const CpuScene& scene,
                                                          VkDescriptorSetLayout material_layout);
  ~GpuScene();

  const vk::Buffer& vertices() const { return vertices_; }
  const vk::Buffer& indices() const { return indices_; }
  const vk::Buffer& drawables() const { return drawables_; }
  const vk::Buffer& materials() const { return materials_; }
  // The texture buckets; a scene without textures has one 1x1 placeholder, so every material
  // set binding is valid.
  const std::vector<vk::Image>& texture_buckets() const { return buckets_; }
  // Descriptor set 1 of material `m`: the material as a uniform range and its textures' buckets.
  VkDescriptorSet material_set(uint32_t m) const { return material_sets_[m]; }
  VkSampler sampler() const { return sampler_.handle(); }
  const std::vector<DrawItem>& draws() const { return draws_; }
  const std::vector<Light>& lights() const { return lights_; }
  const Aabb& bounds() const { return bounds_; }
  uint64_t device_bytes() const { return device_bytes_; }

 private:
  vk::Buffer vertices_, indices_, drawables_, materials_;
  vk::Buffer material_uniforms_;  // the materials again, each at a uniform-offset-aligned stride
  std::vector<vk::Image> buckets_;
  vk::Sampler sampler_;
  VkDevice device_ = VK_NULL_HANDLE;
  VkDescriptorPool material_pool_ = VK_NULL_HANDLE;
  std::vector<VkDescriptorSet> material_sets_;
  std::vector<DrawItem> draws_;
  std::vector<Light> lights_;
  Aabb bounds_;
  uint64_t device_bytes_ = 0;
};

}  // namespace tessera
