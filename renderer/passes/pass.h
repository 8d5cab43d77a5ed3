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
#include "renderer/vk/pipeline.h"
#include "renderer/vk/resources.h"

namespace tessera {

// Formats of the frame's targets; pipelines are built against them.
inline constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;
inline constexpr VkFormat kHdrFormat = VK_FORMAT_R16G16B16A16_SFLOAT;
inline constexpr VkFormat kLdrFormat = VK_FORMAT_R8G8B8A8_SRGB;
inline constexpr VkFormat kHizFormat = VK_FORMAT_R32_SFLOAT;
inline constexpr VkFormat kIdFormat = VK_FORMAT_R32_UINT;

struct FrameTargets {
  uint32_t width = 0, height = 0;
  vk::Image depth;
  vk::Image hdr;
  vk::Image ldr;
  vk::Image hiz;         // depth pyramid (R32F, mips), for gpu_occlusion
  std::vector<VkImageView> hiz_levels;  // one storage view per level (owned by the renderer)
  uint32_t hiz_width = 1, hiz_height = 1;
  vk::Buffer readback;  // width * height * 4 bytes, host visible
  const vk::Image& Get(Resource r) const {
    return r == Resource::kDepth      ? depth
           : r == Resource::kHdrColor ? hdr
           : r == Resource::kHiz      ? hiz
                                      : ldr;
  }
};

// The draws of one frame: indexed indirect commands (firstInstance = drawable) and their counts,
// written by the culling pass (GPU modes) or by the CPU (none, cpu_frustum), for each segment
// and batch of the scene's DrawPlan. gpu_occlusion has two phases, the other modes one.
// Phase p's segment commands start at command 2p * items (each segment at its first item), its
// batch commands at (2p + 1) * items; its counts at p * count_stride: segments, then batches,
// then the kCullStat* statistics.
struct DrawLists {
  VkBuffer commands = VK_NULL_HANDLE;
  VkBuffer counts = VK_NULL_HANDLE;
  uint32_t items = 0;
  uint32_t count_stride = 0;
  uint32_t phases = 1;
  std::vector<uint32_t> blend_order;  // segments of the blend group, back to front

  VkDeviceSize CommandOffset(uint32_t phase, bool batch, uint32_t first_item) const {
    return (VkDeviceSize(2 * phase + (batch ? 1 : 0)) * items + first_item) *
           sizeof(VkDrawIndexedIndirectCommand);
  }
  VkDeviceSize CountOffset(uint32_t phase, uint32_t index) const {
    return (VkDeviceSize(phase) * count_stride + index) * sizeof(uint32_t);
  }
};

// What the geometry-culling passes read and write besides the draw lists (handles owned by the
// renderer).
struct CullBuffers {
  VkBuffer uniforms = VK_NULL_HANDLE;   // CullUniforms per phase, at uniform_stride
  VkDeviceSize uniform_stride = 0;
  VkBuffer bases = VK_NULL_HANDLE;      // scratch, a uint per segment and batch
  VkBuffer vis_prev = VK_NULL_HANDLE;   // visibility bits of the view's last frame
  VkBuffer vis_next = VK_NULL_HANDLE;   // this frame's (gpu_occlusion)
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
  uint32_t indirect_draws = 0;  // vkCmdDrawIndexedIndirectCount calls recorded
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
  const CullBuffers* cull = nullptr;
};

// A pass's own descriptor set layout and pipeline layout (one set), destroyed together.
class PassLayout {
 public:
  PassLayout() = default;
  static absl::StatusOr<PassLayout> Create(const vk::Context& ctx,
                                           const std::vector<VkDescriptorSetLayoutBinding>& bindings,
                                           const std::vector<VkPushConstantRange>& push,
                                           const char* name);
  ~PassLayout() { Reset(); }
  PassLayout(PassLayout&& o) noexcept { *this = std::move(o); }
  PassLayout& operator=(PassLayout&& o) noexcept;
  PassLayout(const PassLayout&) = delete;
  PassLayout& operator=(const PassLayout&) = delete;

  VkPipelineLayout pipeline_layout() const { return layout_; }
  // Allocates a set of this layout from the frame's pool (reset every frame).
  VkDescriptorSet Allocate(const PassContext& ctx) const;

 private:
  void Reset();
  VkDevice device_ = VK_NULL_HANDLE;
  VkDescriptorSetLayout set_layout_ = VK_NULL_HANDLE;
  VkPipelineLayout layout_ = VK_NULL_HANDLE;
};

class Pass {
 public:
  virtual ~Pass() = default;
  virtual PassId id() const = 0;
  // Records the pass. Its resources are already in the layouts PassUses(id()) declares.
  virtual void Record(PassContext& ctx) = 0;
};

// Factories: each builds its pipelines once, for the target formats above.
// kDepthPrepass, or kDepthPrepassLate (the second gpu_occlusion phase).
absl::StatusOr<std::unique_ptr<Pass>> CreateDepthPrepass(const vk::Context& ctx,
                                                         const SceneLayout& layout,
                                                         PassId id = PassId::kDepthPrepass);
absl::StatusOr<std::unique_ptr<Pass>> CreateForwardPass(const vk::Context& ctx,
                                                        const SceneLayout& layout);
absl::StatusOr<std::unique_ptr<Pass>> CreateTransparentPass(const vk::Context& ctx,
                                                            const SceneLayout& layout);
absl::StatusOr<std::unique_ptr<Pass>> CreateTonemapPass(const vk::Context& ctx);
absl::StatusOr<std::unique_ptr<Pass>> CreateLightCullPass(const vk::Context& ctx);
absl::StatusOr<std::unique_ptr<Pass>> CreateReadbackPass();
// Geometry culling: kCull (gpu_frustum, or the first gpu_occlusion phase) or kCullLate.
absl::StatusOr<std::unique_ptr<Pass>> CreateCullPass(const vk::Context& ctx, PassId id);
absl::StatusOr<std::unique_ptr<Pass>> CreateHizBuildPass(const vk::Context& ctx);

// Begins dynamic rendering over the whole frame with these attachments (either may be null)
// and sets the full-frame viewport and scissor.
void BeginRendering(const PassContext& ctx, const VkRenderingAttachmentInfo* color,
                    const VkRenderingAttachmentInfo* depth);
// Shared by the geometry passes: binds the pipeline, the frame's set and the scene buffers.
void BeginSceneDraw(const PassContext& ctx, VkPipeline pipeline);
// Draws the segments of `group` from the lists of phases [phase_begin, phase_end), binding each
// segment's material texture set (when `textured`) and cull mode only when they change. The
// blend group is drawn in DrawLists::blend_order.
void RecordSegments(const PassContext& ctx, AlphaMode group, uint32_t phase_begin,
                    uint32_t phase_end, bool textured = true);
// Draws every item of the scene, unculled, with direct draws (tests: the drawable-id image).
void RecordAllDirect(const PassContext& ctx);
// Draws the opaque group without materials: one indirect draw per batch (cull mode).
void RecordBatches(const PassContext& ctx, uint32_t phase);

// The drawable-id pipeline (tests): writes drawable + 1 into an R32_UINT target where a surface
// lies at the depth attachment's depth (GREATER_OR_EQUAL, no depth writes).
absl::StatusOr<vk::Pipeline> CreateIdPipeline(const vk::Context& ctx, const SceneLayout& layout);

}  // namespace tessera
