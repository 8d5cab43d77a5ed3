#pragma once
// The interface every render pass implements, and what a pass gets to record with.
// A pass records its own commands only; the frame graph (frame_graph.h) decides whether it
// runs and makes the layout transitions its declared uses need, and the renderer wraps it in
// GPU timestamps.
#include <vulkan/vulkan.h>

#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "absl/functional/function_ref.h"
#include "absl/status/statusor.h"
#include "renderer/graph/frame_graph.h"
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
// The tonemap's target when it runs in compute: the same bytes, sRGB-encoded by the shader.
inline constexpr VkFormat kLdrComputeFormat = VK_FORMAT_R8G8B8A8_UNORM;
inline constexpr VkFormat kHizFormat = VK_FORMAT_R32_SFLOAT;
inline constexpr VkFormat kIdFormat = VK_FORMAT_R32_UINT;
inline constexpr VkFormat kShadowFormat = VK_FORMAT_D16_UNORM;  // the shadow atlas (16-bit)
// ssao: visibility + depth (RGBA16F, not RG16F: a storage format without
// shaderStorageImageExtendedFormats, for post_stage compute).
inline constexpr VkFormat kAoFormat = VK_FORMAT_R16G16B16A16_SFLOAT;
inline constexpr VkFormat kExposureFormat = VK_FORMAT_R32_SFLOAT;  // adapted log2 luma, 1x1
// taa's object motion: uv offsets (a colour-attachment and sampled format on every device).
inline constexpr VkFormat kMotionFormat = VK_FORMAT_R16G16_SFLOAT;
// Bloom's downsample chain: this many levels, the first at half the frame's size (the upsample
// chain has one fewer). Six levels reach 1/64 of the frame: a glow about a tenth of its width.
inline constexpr uint32_t kBloomLevels = 6;

// One frame's targets: references into the renderer's pool (graph/target_pool.h); the ones
// the frame's settings do not use are empty.
struct FrameTargets {
  uint32_t width = 0, height = 0;
  vk::ImageRef depth;
  vk::ImageRef hdr;
  vk::ImageRef ldr;
  vk::ImageRef hiz;            // depth pyramid (R32F, mips), for the gpu culling modes
  vk::MipViewsRef hiz_levels;  // one storage view per level
  uint32_t hiz_width = 1, hiz_height = 1;
  VkBuffer readback = VK_NULL_HANDLE;  // width * height * 4 bytes, host visible
  uint32_t samples = 1;                // msaa's and vis_mlaa's samples (vis_mlaa_coverage analytic:
                                       // the resolve's; its targets have one), else 1
  vk::ImageRef depth_ms, hdr_ms, vis_ms;
  vk::ImageRef vis_id, vis_coverage;
  vk::ImageRef post_hdr;
  vk::ImageRef fxaa;
  vk::ImageRef ao, ao_temp;  // ssao's size
  // bloom: the downsample chain from half the frame's size (at least 32 texels a side, so all
  // kBloomLevels mips exist) and the upsample chain (one mip fewer), with a view per mip.
  vk::ImageRef bloom_down, bloom_up;
  vk::MipViewsRef bloom_down_levels, bloom_up_levels;
  vk::ImageRef motion;  // taa on animated scenes
  // The long-lived resources this frame imports (renderer-owned; empty when unused).
  vk::ImageRef shadow_atlas, taa_history, taa_history_next, exposure_state;
  const vk::Image& Get(Resource r) const {
    switch (r) {
      case Resource::kDepth: return depth;
      case Resource::kHdrColor: return hdr;
      case Resource::kLdrColor: return ldr;
      case Resource::kHiz: return hiz;
      case Resource::kDepthMs: return depth_ms;
      case Resource::kHdrMs: return hdr_ms;
      case Resource::kVisMs: return vis_ms;
      case Resource::kVisId: return vis_id;
      case Resource::kVisCoverage: return vis_coverage;
      case Resource::kPostHdr: return post_hdr;
      case Resource::kFxaaColor: return fxaa;
      case Resource::kAo: return ao;
      case Resource::kAoTemp: return ao_temp;
      case Resource::kBloomDown: return bloom_down;
      case Resource::kBloomUp: return bloom_up;
      case Resource::kMotion: return motion;
      case Resource::kShadowAtlas:
        return shadow_atlas;
      case Resource::kTaaHistory:
        return taa_history;
      case Resource::kTaaHistoryNext:
        return taa_history_next;
      case Resource::kExposureState:
        return exposure_state;
      // Buffers have no image: the graph records memory barriers for them.
      case Resource::kDrawLists:
      case Resource::kVisibilityBits:
      case Resource::kLightLists:
      case Resource::kShadeLists:
      case Resource::kEdgeSurfaces:
      case Resource::kPosedGeometry:
      case Resource::kCount: break;
    }
    return ldr;
  }
};

// One draw of an item (firstInstance = its drawable): indexed, and the same draw non-indexed over
// the item's range of the index buffer for pulled vertices (common/vis_pull.glsl).
struct DrawCommand {
  VkDrawIndexedIndirectCommand indexed;
  VkDrawIndirectCommand pulled;
};
static_assert(sizeof(DrawCommand) == gpu::kDrawCommandWords * 4);

// The draws of one frame: indirect draw commands (DrawCommand) and their counts,
// written by the culling pass (GPU modes) or by the CPU (none, cpu_frustum), for each segment
// and batch of the scene's DrawPlan. gpu_occlusion has two phases, the other modes one.
// Phase p's segment commands start at command 2p * items (each segment at its first item), its
// batch commands at (2p + 1) * items; its counts at p * count_stride: segments, then batches,
// then the kCullStat* statistics. A device without drawIndirectCount draws every list's whole
// capacity: the commands past a list's count are all zero (indexCount 0 draws nothing).
struct DrawLists {
  VkBuffer commands = VK_NULL_HANDLE;
  VkBuffer counts = VK_NULL_HANDLE;
  uint32_t items = 0;
  uint32_t count_stride = 0;
  uint32_t phases = 1;
  std::vector<uint32_t> blend_order;  // segments of the blend group, back to front

  VkDeviceSize CommandOffset(uint32_t phase, bool batch, uint32_t first_item) const {
    return (VkDeviceSize(2 * phase + (batch ? 1 : 0)) * items + first_item) * sizeof(DrawCommand);
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
  VkBuffer local_lights = VK_NULL_HANDLE;     // GpuLight per local light
  uint32_t tiles = 0;
  // light_binning gpu: the pass first fills `bounds` (light_bounds.comp) and `row_lights`
  // (light_bins.comp, `rows` workgroups) from the `lights` local lights.
  bool gpu_binning = false;
  uint32_t lights = 0;
  uint32_t rows = 0;
  uint64_t row_entries = 0;  // of row_lights in use (header and lists)
};

// The visibility pipeline's buffers (handles owned by the renderer): per material a
// GpuShadeEntry, one more for the sky (entry `materials`) and two for vis_mlaa's edge list
// (`materials + 1`) and blend list (`materials + 2`: the edge pixels with more than one surface,
// by edge list index), the pixel lists (a uint per pixel of the frame, four with vis_mlaa: its
// resolve lists its edge pixels there first, then the blend list, and the materials' lists follow
// them, so geometric AA can read both after the shading; they hold the runner-up surfaces too),
// and a host copy of the entries for the frame's statistics.
struct ShadeBuffers {
  VkBuffer entries = VK_NULL_HANDLE;
  VkBuffer pixels = VK_NULL_HANDLE;
  VkBuffer entries_readback = VK_NULL_HANDLE;
  // vis_mlaa, per entry of the edge list (Resource::kEdgeSurfaces): the runner-up surface
  // (uvec2: the id to shade and its word, shaders/common/runner_up.glsl) and a colour (RGBA16F
  // packed in a uvec2: the runner-up's shading, then geometric AA's blend).
  VkBuffer runner_ups = VK_NULL_HANDLE;
  VkBuffer edge_colors = VK_NULL_HANDLE;
  uint32_t materials = 0;
  // vis_mlaa's entries after the sky's: the edge list's and the blend list's.
  uint32_t edge_entry() const { return materials + 1; }
  uint32_t blend_entry() const { return materials + 2; }
  // Then the classification's (every frame; shaders/common/vis_classify.glsl): the sky's list,
  // and the dispatch sizes of its fill that writes the sky and of the one that lists it.
  uint32_t sky_list_entry() const { return materials + 3; }
  uint32_t fill_entry(bool list_sky) const { return materials + (list_sky ? 5 : 4); }
};

struct PassStats {
  uint32_t indirect_draws = 0;  // vkCmdDrawIndexedIndirectCount calls recorded
  uint32_t material_draws =
      0;  // the visibility shading's dispatches (FrameStats::shading_dispatches)
  // The invocations of its direct dispatches (the one-dispatch shading's over the frame); those
  // of its indirect dispatches are read back with the entries.
  uint64_t shading_invocations = 0;
};

// The visibility shading (vis_mlaa and the visibility pipeline): the materials of the opaque and
// alpha-mask drawables in the frustum, ascending (the shading dispatches once for each).
struct VisFrame {
  std::vector<uint32_t> materials;
  uint32_t triangle_bits = 20;  // low bits of an id: triangle; high bits: drawable + 1
};

// taa: this frame's history images (per view, kept by the renderer) and how to blend.
struct TaaFrame {
  const vk::Image* history_read = nullptr;   // last frame's output (shader-read layout)
  const vk::Image* history_write = nullptr;  // this frame's output (any layout)
  glm::mat4 reproject{1.0f};  // this frame's unjittered clip -> last frame's
  float current_weight = 1.0f;
  bool history_valid = false;  // history_read holds last frame (else it was never written)
  bool camera_moved = false;   // the view's camera moved since its last frame
  // Animated scenes (features/motion.cpp): when the pose changed since the view's last frame, the
  // motion pass runs; with valid history it draws each moved drawable's motion (`draws`) for TAA
  // (`motion`), and it keeps this frame's deformed vertices in `kept` for the next frame.
  struct MotionDraw {
    uint32_t item = 0;  // into GpuScene::draws()
    bool kept = false;  // deformed: its last vertices are in `kept`, else its rest ones moved
    glm::mat4 prev_world{1.0f};
  };
  bool motion_pass = false;
  bool motion = false;
  std::vector<MotionDraw> draws;
  // The view's copy of the deformed vertices (SceneAnimator::copy_vertices from
  // first_copy_vertex on; null: the scene deforms nothing).
  const vk::Buffer* kept = nullptr;
};

// Layouts shared by the scene passes: set 0 = frame + lights UBOs, drawable/material SSBOs,
// local lights and the tile lists;
// set 1 = the material's texture buckets (shaders/common/gpu_types.h has the bindings), or in
// the visibility shading of devices that index sampler arrays, the scene's bucket set.
struct SceneLayout {
  VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
  VkDescriptorSetLayout material_set_layout = VK_NULL_HANDLE;
  VkPipelineLayout pipeline_layout = VK_NULL_HANDLE;
  VkDescriptorSetLayout bucket_set_layout = VK_NULL_HANDLE;
};

// shadows: the atlas (kept by the renderer across frames, outside the frame graph: it is in
// shader-read layout between frames) and the faces this frame renders into it.
struct ShadowFace {
  uint32_t x = 0, y = 0, size = 0;  // texels of the atlas
  glm::mat4 view_proj{1.0f};        // world -> the face's clip space
  std::vector<uint32_t> items;      // the scene's draw items in the face's frustum
};
struct ShadowFrame {
  const vk::Image* atlas = nullptr;
  bool atlas_new = false;  // never written: cleared whole, from the undefined layout
  std::vector<ShadowFace> faces;
};

// ssao's parameters (shaders/ssao.frag).
struct SsaoFrame {
  glm::vec4 proj{0.0f};    // proj00, proj11, p22, p32
  glm::vec4 params{0.0f};  // radius (world), strength, bias, unused
};

// Exposure (shaders/common/exposure.glsl), read by bloom and tonemap, and auto exposure's
// adaptation (shaders/exposure.comp).
struct ExposureFrame {
  glm::vec4 params{1.0f, 0.0f, 0.18f, 0.0f};  // 2^exposure_ev, 1 for auto, key, unused
  // auto: the view's 1x1 state (R32F, general layout between frames, kept by the renderer).
  const vk::Image* state = nullptr;
  bool state_valid = false;  // holds an earlier frame's value (else: undefined contents)
  float rate = 1.0f;         // how far to move towards this frame's average (1: at once)
  // What bloom and tonemap bind as the state: `state`, or a stand-in without auto exposure.
  VkImageView view = VK_NULL_HANDLE;
  VkImageLayout layout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
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
  const VisFrame* vis = nullptr;
  const ShadeBuffers* shade = nullptr;
  const TaaFrame* taa = nullptr;
  const ShadowFrame* shadows = nullptr;
  const SsaoFrame* ssao = nullptr;
  const ExposureFrame* exposure = nullptr;
  // The atlas the shading reads (the real one, or a 1x1 stand-in without shadows), in
  // shader-read layout outside the shadow pass; the tonemap pass shows it as a debug view.
  const vk::Image* shadow_atlas_view = nullptr;
  const vk::Image* ao_view = nullptr;  // ssao's result, or a 1x1 stand-in (shader-read layout)
  // The colour passes draw into; Settings::samples where multisampled.
  uint32_t samples = 1;
  // The HDR colour the post passes read (FramePlan::scene_color).
  Resource post_color = Resource::kHdrColor;
  const FrameFeatures* features = nullptr;  // what PrepareScene saw
};

// A pass's own descriptor set layout and pipeline layout (one set), destroyed together.
// A descriptor set of `layout` from the frame's pool (reset every frame).
VkDescriptorSet AllocateFrameSet(const PassContext& ctx, VkDescriptorSetLayout layout);

// Writes the bindings of a descriptor set: combined image samplers, storage images (general
// layout) and buffers (whole unless a range is given, or up to the device's storage buffer range:
// StorageBuffer), in one vkUpdateDescriptorSets.
class SetWriter {
 public:
  SetWriter(VkDevice device, VkDescriptorSet set) : device_(device), set_(set) {}
  SetWriter& Sampled(uint32_t binding, VkSampler sampler, VkImageView view,
                     VkImageLayout layout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL);
  SetWriter& Storage(uint32_t binding, VkImageView view);
  SetWriter& Buffer(uint32_t binding, VkBuffer buffer,
                    VkDescriptorType type = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                    VkDeviceSize offset = 0, VkDeviceSize range = VK_WHOLE_SIZE);
  SetWriter& TexelBuffer(uint32_t binding, VkBufferView view);
  // `buffer` as a storage buffer, all of it or as much as the device's maxStorageBufferRange
  // allows. The scene's index and vertex buffers (and the adjacency) may be larger; a frame whose
  // shaders would read past the range does not run those shaders
  // (Renderer::Impl::CheckVisibilityIds: texel views instead, or another path).
  SetWriter& StorageBuffer(uint32_t binding, const PassContext& ctx, const vk::Buffer& buffer);
  // The visibility passes' buffers: the scene's index and vertex buffers (kVisBindingIndices,
  // kVisBindingVertices) and their texel views with the drawables' (kVisBindingIndexTexels...,
  // VisibilityBufferBindings), and the shading's entries and pixel lists (kShadeBinding*).
  SetWriter& VisibilityBuffers(const PassContext& ctx);
  // The scene's geometry as vis.glsl reads it: the index and vertex buffers and the texel views
  // of them and of the drawables (SceneGeometryBindings).
  SetWriter& SceneGeometry(const PassContext& ctx);
  void Update();
  VkDescriptorSet set() const { return set_; }

 private:
  // A new write of one descriptor at `binding`, for the caller to point at its info.
  VkWriteDescriptorSet& Write(uint32_t binding, VkDescriptorType type);
  VkDevice device_;
  VkDescriptorSet set_;
  std::deque<VkDescriptorImageInfo> images_;  // stable addresses for the writes
  std::deque<VkDescriptorBufferInfo> buffers_;
  std::deque<VkBufferView> texel_views_;
  std::vector<VkWriteDescriptorSet> writes_;
};

// One binding of a descriptor set layout: a single descriptor of `type` for `stages`.
inline VkDescriptorSetLayoutBinding LayoutBinding(uint32_t binding, VkDescriptorType type,
                                                  VkShaderStageFlags stages) {
  return {binding, type, 1, stages, nullptr};
}

// The bindings SetWriter::VisibilityBuffers writes, for a compute pass's set 2.
std::vector<VkDescriptorSetLayoutBinding> VisibilityBufferBindings();
// The bindings SetWriter::SceneGeometry writes (vis.glsl's), for `stages`.
std::vector<VkDescriptorSetLayoutBinding> SceneGeometryBindings(VkShaderStageFlags stages);

// The value of vis.glsl's specialization constant kVisTexels for `scene` (GpuScene::vis_texels):
// a visibility pass's pipeline is built per value.
inline uint32_t VisTexels(const GpuScene& scene) { return scene.vis_texels() ? 1u : 0u; }

class PassLayout {
 public:
  PassLayout() = default;
  // The pass's set of `bindings`, after the sets `before` (e.g. the scene's sets 0 and 1: the
  // pass's set is then set 2) in the pipeline layout.
  static absl::StatusOr<PassLayout> Create(
      const vk::Context& ctx, const std::vector<VkDescriptorSetLayoutBinding>& bindings,
      const std::vector<VkPushConstantRange>& push, const char* name,
      const std::vector<VkDescriptorSetLayout>& before = {});

  VkPipelineLayout pipeline_layout() const { return layout_.get(); }
  // Allocates a set of this layout from the frame's pool (reset every frame).
  VkDescriptorSet Allocate(const PassContext& ctx) const;

 private:
  VkDevice device_ = VK_NULL_HANDLE;
  vk::UniqueDescriptorSetLayout set_layout_;
  vk::UniquePipelineLayout layout_;
};

class Pass {
 public:
  virtual ~Pass() = default;
  virtual PassId id() const = 0;
  // Before recording a frame with these settings: builds what the pass lacks for them (e.g.
  // pipelines for a sample count it has not drawn at yet).
  virtual absl::Status Prepare(const vk::Context& ctx, const Settings& settings) {
    (void)ctx;
    (void)settings;
    return absl::OkStatus();
  }
  // Then, for the frame's scene: builds what the pass lacks for its materials (the shading
  // passes: a pipeline per set of texture slots, GpuScene::texture_sets) and for what the frame
  // holds (`features`: e.g. whether its lights fit texel buffers).
  virtual absl::Status PrepareScene(const vk::Context& ctx, const Settings& settings,
                                    const GpuScene& scene, const FrameFeatures& features) {
    (void)ctx;
    (void)settings;
    (void)scene;
    (void)features;
    return absl::OkStatus();
  }
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
// vis_mlaa: kVisibility or kVisibilityLate.
absl::StatusOr<std::unique_ptr<Pass>> CreateVisibilityPass(const vk::Context& ctx,
                                                           const SceneLayout& layout, PassId id);
absl::StatusOr<std::unique_ptr<Pass>> CreateVisResolvePass(const vk::Context& ctx,
                                                           const SceneLayout& layout);
absl::StatusOr<std::unique_ptr<Pass>> CreateGeometricAaPass(const vk::Context& ctx);
// The visibility shading: kVisClassify and kShade (features/vis_shade.cpp).
absl::StatusOr<std::unique_ptr<Pass>> CreateVisClassifyPass(const vk::Context& ctx,
                                                            const SceneLayout& layout);
// Where the device shades in one dispatch (DeviceInfo::shade_all_materials) and that shading's
// layouts exceed its descriptor limits, `one_dispatch` (when given) gets the refusal and the pass
// shades per material only; the caller turns the one dispatch off (DisableShadeAllMaterials).
absl::StatusOr<std::unique_ptr<Pass>> CreateShadePass(const vk::Context& ctx,
                                                      const SceneLayout& layout,
                                                      absl::Status* one_dispatch = nullptr);
absl::StatusOr<std::unique_ptr<Pass>> CreateTaaPass(const vk::Context& ctx);
// taa on animated scenes: the moved geometry's motion (TaaFrame::draws), and the pose kept.
absl::StatusOr<std::unique_ptr<Pass>> CreateMotionPass(const vk::Context& ctx,
                                                       const SceneLayout& layout);
absl::StatusOr<std::unique_ptr<Pass>> CreateFxaaPass(const vk::Context& ctx);
// shadows: renders ShadowFrame::faces into the atlas.
absl::StatusOr<std::unique_ptr<Pass>> CreateShadowPass(const vk::Context& ctx,
                                                       const SceneLayout& layout);
// ssao: obscurance at the size of FrameTargets::ao, blurred in place through ao_temp.
absl::StatusOr<std::unique_ptr<Pass>> CreateSsaoPass(const vk::Context& ctx);
// Auto exposure: the average log2 luma of the tonemap's input into ExposureFrame::state.
absl::StatusOr<std::unique_ptr<Pass>> CreateExposurePass(const vk::Context& ctx);
// Bloom: FrameTargets::bloom_down / bloom_up from the tonemap's input.
absl::StatusOr<std::unique_ptr<Pass>> CreateBloomPass(const vk::Context& ctx);
// An animated scene's pose: drawable records and skinned/morphed vertices (skin.comp).
absl::StatusOr<std::unique_ptr<Pass>> CreateSkinningPass(const vk::Context& ctx);
// The HDR colour the post passes read: the post-AA colour where an AA pass made one.
const vk::Image& PostColor(const PassContext& ctx);
// A full-screen post pass: one fragment shader reading combined image samplers (bindings 0..n-1,
// in the order of `inputs`) with a push-constant block, writing `outputs` colour targets.
// Shared by tonemap, geometric AA, TAA and FXAA.
struct PostInput {
  VkImageView view = VK_NULL_HANDLE;
  VkSampler sampler = VK_NULL_HANDLE;
  VkImageLayout layout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
};
// The sample count of the forward path's targets: Settings::samples with msaa, else 1.
inline uint32_t ForwardSamples(const PassContext& ctx) {
  return ctx.settings->aa == AaMode::kMsaa ? ctx.samples : 1;
}

class FullscreenProgram {
 public:
  FullscreenProgram() = default;
  // Whether a program runs its compute shader for these settings; the pass's Setup declares its
  // graph uses with the same rule (Access::kComputeRead / kComputeWrite).
  using ComputeRule = bool (*)(const Settings&);
  static bool Compute(const Settings& s) { return s.post_stage == PostStage::kCompute; }
  // With `compute_shader` (shaders/common/post_io.glsl) the program also runs as a compute
  // shader where `rule` says so: the same inputs, the outputs storage images at the bindings
  // after them.
  static absl::StatusOr<FullscreenProgram> Create(const vk::Context& ctx, const char* name,
                                                  const char* fragment_shader, uint32_t inputs,
                                                  uint32_t push_size,
                                                  std::vector<VkFormat> outputs,
                                                  const char* compute_shader = nullptr,
                                                  ComputeRule rule = &Compute);
  // Every pixel of `outputs` written once (cleared contents are not loaded): one full-screen
  // triangle, or in compute one invocation per pixel (outputs in the general layout).
  // `extent`: the outputs' size when it is not the frame's (0 x 0: the frame's); in compute, the
  // grid of invocations, which a shader taking several pixels each makes smaller (bloom_down's
  // kBloomDownQuads).
  // `variant`: the shaders' specialization constant 0, built by Ensure (variant 0 by Create).
  void Draw(const PassContext& ctx, const std::vector<PostInput>& inputs,
            const std::vector<VkImageView>& outputs, const void* push,
            VkExtent2D extent = {0, 0}, uint32_t variant = 0) const;
  // A program whose shaders have variants (specialization constant 0: a number its pass makes
  // from the settings, e.g. the tonemap's view, bloom and curve) builds the pipeline of a variant
  // on its first use, the one these settings run (fragment or compute). lavapipe runs the code of
  // untaken branches under a lane mask, so a branch on a push constant costs what its code does;
  // a variant holds only the code it runs.
  absl::Status Ensure(const vk::Context& ctx, const Settings& s, uint32_t variant);

 private:
  bool RunsCompute(const Settings& s) const { return !compute_shader_.empty() && rule_(s); }
  absl::StatusOr<vk::Pipeline> Build(const vk::Context& ctx, bool compute, uint32_t variant) const;

  VkDevice device_ = VK_NULL_HANDLE;
  std::string name_, fragment_shader_, compute_shader_;  // no compute shader: empty
  std::vector<VkFormat> outputs_;
  PassLayout layout_;
  PassLayout compute_layout_;
  std::map<uint32_t, vk::Pipeline> pipelines_, compute_pipelines_;  // by variant
  ComputeRule rule_ = &Compute;
  uint32_t inputs_ = 0;
  uint32_t push_size_ = 0;
};
// What a pass builds per sample count (its pipelines), or per another key, made on first use.
template <typename T>
class PerSampleCount {
 public:
  // Builds the entry for `samples` with make(samples) -> StatusOr<T> unless it exists.
  template <typename Make>
  absl::Status Ensure(uint32_t samples, Make make) {
    if (by_samples_.count(samples)) return absl::OkStatus();
    absl::StatusOr<T> made = make(samples);
    if (!made.ok()) return made.status();
    by_samples_.emplace(samples, std::move(*made));
    return absl::OkStatus();
  }
  const T& at(uint32_t samples) const { return by_samples_.at(samples); }

 private:
  std::map<uint32_t, T> by_samples_;
};

// Samplers for post passes: nearest or bilinear, clamp to edge.
absl::StatusOr<vk::Sampler> CreateClampSampler(const vk::Context& ctx, bool linear,
                                               const char* name);

// Begins dynamic rendering over the whole frame with these attachments (either may be null)
// and sets the full-frame viewport and scissor.
void BeginRendering(const PassContext& ctx, const VkRenderingAttachmentInfo* color,
                    const VkRenderingAttachmentInfo* depth);
// The same with `color_count` colour attachments, over `extent` (0 x 0: the frame's size).
void BeginRendering(const PassContext& ctx, const VkRenderingAttachmentInfo* colors,
                    uint32_t color_count, const VkRenderingAttachmentInfo* depth,
                    VkExtent2D extent = {0, 0});
// Makes `depth` (a multisampled attachment) resolve into the frame's single-sampled depth: the
// farthest sample where the device can (conservative for the depth pyramid and light culling),
// else sample 0.
void ResolveDepthInto(const PassContext& ctx, VkRenderingAttachmentInfo& depth);
// Shared by the geometry passes: binds the pipeline, the frame's set and the scene buffers.
// `layout`: the pipeline's layout when it is not the scene's (a pass with sets or push constants
// of its own after the scene's sets).
// `pipeline` null: none bound here (RecordSegments' pipeline_of binds each segment's).
void BeginSceneDraw(const PassContext& ctx, VkPipeline pipeline,
                    VkPipelineLayout layout = VK_NULL_HANDLE);
// The debug view shading.glsl draws for these settings (its specialization constant 2): the
// views of surfaces (normals, base colour, depth, light heatmap, cascades), else kDebugNone
// (lit; the tonemap shows the other views).
uint32_t ShadingDebugView(const Settings& s);
// The effects shading.glsl has code for with these settings (its specialization constant 0):
// gpu::kShadowsOn | kSsaoOn | kIblOn. ShadingConstantsFor adds kLocalLightsOn for a frame with
// local lights and kGlobalLightsOn for one whose global lights need DirectLight's loop.
uint32_t ShadingEffects(const Settings& s);

// The specialization constants a shading pipeline (forward, transparent, visibility shade) is
// built with: shading.glsl's 0 (ShadingEffects), 1 (the material's texture slots), 2
// (ShadingDebugView) and 4 (the lights through texel buffers: FrameFeatures::light_texels), and
// vis.glsl's 3 (VisTexels; the visibility shading only). Key() packs them into 24 bits for a
// pass's map of pipelines, which may add bits of its own above kShadingKeyBits.
struct ShadingConstants {
  uint32_t effects = 0, textures = 0, debug = 0, vis_texels = 0, light_texels = 0;
  uint32_t Key() const {
    return effects | textures << 5 | debug << 14 | vis_texels << 22 | light_texels << 23;
  }
  static ShadingConstants FromKey(uint32_t key) {
    return {key & 31u, (key >> 5) & 0x1ffu, (key >> 14) & 0xffu, (key >> 22) & 1u,
            (key >> 23) & 1u};
  }
  // In constant_id order.
  std::vector<uint32_t> Values() const {
    return {effects, textures, debug, vis_texels, light_texels};
  }
};
inline constexpr uint32_t kShadingKeyBits = 24;
ShadingConstants ShadingConstantsFor(const Settings& s, const FrameFeatures& features,
                                     uint32_t textures);
// RecordSegments' default: every segment with the pipeline already bound.
inline VkPipeline NoPipelineChange(uint32_t) { return VK_NULL_HANDLE; }
// Binds what a draw needs that differs from the last one drawn: its material's set (when
// `textured`) and its cull mode. `layout` as BeginSceneDraw's.
struct DrawState {
  VkPipelineLayout layout = VK_NULL_HANDLE;
  int cull = -1;
  uint32_t material = UINT32_MAX;
  VkPipeline pipeline = VK_NULL_HANDLE;
  void Apply(const PassContext& ctx, bool double_sided, uint32_t m, bool textured);
};
// The geometry of the visibility pass with pulled vertices (DeviceInfo::vertex_pulling,
// common/vis_pull.glsl): its pipelines' layout, the scene's sets then a set of the scene's
// geometry (kVisSet: SceneGeometryBindings), and that set. The draws are the commands'
// non-indexed halves (DrawCommand::pulled).
struct PulledGeometry {
  VkPipelineLayout layout = VK_NULL_HANDLE;
  VkDescriptorSet set = VK_NULL_HANDLE;
};
// Draws the segments of `group` from the lists of phases [phase_begin, phase_end), binding each
// segment's material texture set (when `textured`) and cull mode only when they change. The
// blend group is drawn in DrawLists::blend_order. With `pipeline_of`, each segment is drawn with
// the pipeline it gives for the segment's material (bound when it changes; same layout).
// With `pulled`, the draws are non-indexed and the material sets bound with its layout.
void RecordSegments(const PassContext& ctx, AlphaMode group, uint32_t phase_begin,
                    uint32_t phase_end, bool textured = true,
                    absl::FunctionRef<VkPipeline(uint32_t)> pipeline_of = NoPipelineChange,
                    const PulledGeometry* pulled = nullptr);
// Draws every item of the scene, unculled, with direct draws (tests: the drawable-id image).
void RecordAllDirect(const PassContext& ctx);
// Draws the opaque group without materials: one indirect draw per batch (cull mode).
void RecordBatches(const PassContext& ctx, uint32_t phase, const PulledGeometry* pulled = nullptr);
// The depth prepass's and visibility pass's draws of a phase: the opaque batches with `opaque`,
// then the alpha-mask segments (materials bound for the alpha test) with `mask`; with `pulled`,
// non-indexed (PulledGeometry).
void RecordDepthGeometry(const PassContext& ctx, VkPipeline opaque, VkPipeline mask,
                         uint32_t phase, const PulledGeometry* pulled = nullptr);

// The drawable-id pipeline (tests): writes drawable + 1 into an R32_UINT target where a surface
// lies at the depth attachment's depth (GREATER_OR_EQUAL, no depth writes).
absl::StatusOr<vk::Pipeline> CreateIdPipeline(const vk::Context& ctx, const SceneLayout& layout);

}  // namespace tessera
