#pragma once
// The interface every render pass implements, and what a pass gets to record with.
// A pass records its own commands only; the frame graph (frame_graph.h) decides whether it
// runs and makes the layout transitions its declared uses need, and the renderer wraps it in
// GPU timestamps.
#include <vulkan/vulkan.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "renderer/frame_graph.h"
#include "renderer/scene/gpu_scene.h"
#include "renderer/settings.h"
#include "renderer/vk/context.h"
#include "renderer/vk/resources.h"

namespace tessera {

// Formats of the frame's targets; pipelines are built against them.
inline constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;
inline constexpr VkFormat kHdrFormat = VK_FORMAT_R16G16B16A16_SFLOAT;
inline constexpr VkFormat kLdrFormat = VK_FORMAT_R8G8B8A8_SRGB;

struct FrameTargets {
  uint32_t width = 0, height = 0;
  vk::Image depth;
  vk::Image hdr;
  vk::Image ldr;
  vk::Buffer readback;  // width * height * 4 bytes, host visible
  const vk::Image& Get(Resource r) const {
    return r == Resource::kDepth ? depth : r == Resource::kHdrColor ? hdr : ldr;
  }
};

// The draws of one frame after culling, by render group.
struct DrawLists {
  std::vector<const DrawItem*> opaque;
  std::vector<const DrawItem*> mask;
  std::vector<const DrawItem*> blend;  // sorted back to front
};

// The forward+ buffers of a frame (handles owned by the renderer).
struct LightCullBuffers {
  VkBuffer frame_ubo = VK_NULL_HANDLE;
  VkBuffer bounds = VK_NULL_HANDLE;           // GpuLightBounds per local light
  VkBuffer tile_counts = VK_NULL_HANDLE;      // uint per tile
  VkBuffer tile_lights = VK_NULL_HANDLE;      // uint per tile x kMaxLightsPerTile
  VkBuffer counts_readback = VK_NULL_HANDLE;  // host copy of tile_counts
  VkBuffer row_lights = VK_NULL_HANDLE;       // lights binned by tile row (gpu_types.h)
  uint32_t tiles = 0;
};

struct PassStats {
  uint32_t draws = 0;
  uint64_t triangles = 0;
};

// Layouts shared by the scene passes: set 0 = frame + lights UBOs, drawable/material SSBOs,
// local lights and the tile lists;
// set 1 = the material's texture buckets (shaders/common/gpu_types.h has the bindings).
struct SceneLayout {
  VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
  VkDescriptorSetLayout material_set_layout = VK_NULL_HANDLE;
  VkPipelineLayout pipeline_layout = VK_NULL_HANDLE;
};

struct PassContext {
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  const vk::Context* vk = nullptr;
  const FrameTargets* targets = nullptr;
  const GpuScene* scene = nullptr;
  const DrawLists* draws = nullptr;
  const Settings* settings = nullptr;
  VkPipelineLayout scene_pipeline_layout = VK_NULL_HANDLE;
  VkDescriptorSet scene_set = VK_NULL_HANDLE;
  VkDescriptorPool frame_pool = VK_NULL_HANDLE;  // reset every frame; passes may allocate
  PassStats* stats = nullptr;
  const LightCullBuffers* light_buffers = nullptr;
};

class Pass {
 public:
  virtual ~Pass() = default;
  virtual PassId id() const = 0;
  // Records the pass. Its resources are already in the layouts PassUses(id()) declares.
  virtual void Record(PassContext& ctx) = 0;
};

// Factories: each builds its pipelines once, for the target formats above.
absl::StatusOr<std::unique_ptr<Pass>> CreateDepthPrepass(const vk::Context& ctx,
                                                         const SceneLayout& layout);
absl::StatusOr<std::unique_ptr<Pass>> CreateForwardPass(const vk::Context& ctx,
                                                        const SceneLayout& layout);
absl::StatusOr<std::unique_ptr<Pass>> CreateTransparentPass(const vk::Context& ctx,
                                                            const SceneLayout& layout);
absl::StatusOr<std::unique_ptr<Pass>> CreateTonemapPass(const vk::Context& ctx);
absl::StatusOr<std::unique_ptr<Pass>> CreateLightCullPass(const vk::Context& ctx);
absl::StatusOr<std::unique_ptr<Pass>> CreateReadbackPass();

// Begins dynamic rendering over the whole frame with these attachments (either may be null)
// and sets the full-frame viewport and scissor.
void BeginRendering(const PassContext& ctx, const VkRenderingAttachmentInfo* color,
                    const VkRenderingAttachmentInfo* depth);
// Shared by the geometry passes: binds the pipeline, the frame's set and the scene buffers.
void BeginSceneDraw(const PassContext& ctx, VkPipeline pipeline);
// Draws `items` with firstInstance = drawable index, switching the cull mode per item's
// double-sidedness and (when `textured`) the material texture set only when they change.
void RecordDraws(const PassContext& ctx, const std::vector<const DrawItem*>& items,
                 bool textured = true);

}  // namespace tessera
