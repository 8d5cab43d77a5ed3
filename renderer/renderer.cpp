#include "renderer/renderer.h"

#include <algorithm>
#include <bit>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <glm/gtc/packing.hpp>
#include <limits>
#include <map>
#include <mutex>

#include "absl/strings/str_cat.h"
#include "renderer/frame_graph.h"
#include "renderer/ibl.h"
#include "renderer/ibl_maps.h"
#include "renderer/light_culling.h"
#include "renderer/shadows.h"
#include "renderer/passes/pass.h"
#include "renderer/scene/gpu_scene.h"
#include "renderer/vk/context.h"
#include "renderer/vk/resources.h"
#include "renderer/vk/vk_check.h"
#include "shaders/common/gpu_types.h"

namespace tessera {

namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

constexpr uint32_t kMaxTimestamps = 2 * static_cast<uint32_t>(PassId::kCount);
// Views whose visibility bits a scene keeps for gpu_occlusion (least recently used dropped).
constexpr size_t kMaxViews = 64;
// Level 0 of the depth pyramid is the power of two at or below half the frame size: on lavapipe
// the pyramid's cost is per texel (1280x720: 14.3 ms from a 1024x512 level 0, 6.4 ms from 512x256),
// and the occlusion test reads a coarser level for all but tiny drawables anyway.
constexpr uint32_t kHizLevel0Divisor = 2;
// Auto exposure maps the frame's average luma to middle grey (Reinhard's key, 0.18) and moves a
// tenth of the way towards each frame's average: about 90% of a change within 22 frames, under a
// second at 30 frames a second. A view's first frame takes its own average at once.
constexpr float kExposureKey = 0.18f;
constexpr float kExposureAdaptRate = 0.1f;
// Pipeline statistics gathered per geometry pass, in the order Vulkan returns them.
constexpr VkQueryPipelineStatisticFlags kPipelineStats =
    VK_QUERY_PIPELINE_STATISTIC_INPUT_ASSEMBLY_PRIMITIVES_BIT |
    VK_QUERY_PIPELINE_STATISTIC_CLIPPING_PRIMITIVES_BIT |
    VK_QUERY_PIPELINE_STATISTIC_FRAGMENT_SHADER_INVOCATIONS_BIT;

bool IsGeometryPass(PassId id) {
  return id == PassId::kDepthPrepass || id == PassId::kDepthPrepassLate ||
         id == PassId::kVisibility || id == PassId::kVisibilityLate ||
         id == PassId::kForward || id == PassId::kTransparent;
}

// TAA's sub-pixel jitter: the Halton (2, 3) sequence over 16 frames, in pixels around the
// pixel centre.
glm::vec2 TaaJitter(uint32_t frame) {
  auto halton = [](uint32_t i, uint32_t base) {
    float f = 1.0f, r = 0.0f;
    for (; i > 0; i /= base) {
      f /= float(base);
      r += f * float(i % base);
    }
    return r;
  };
  const uint32_t i = frame % 16 + 1;
  return glm::vec2(halton(i, 2) - 0.5f, halton(i, 3) - 0.5f);
}

// vis_mlaa: the bits of a visibility id that hold the triangle. 12 bits of drawable + 1 and 20
// of triangle while the drawables fit; past 4095 drawables the drawable takes the bits it needs.
uint32_t VisTriangleBits(uint32_t drawables) {
  const uint32_t drawable_bits = std::max(12u, uint32_t(std::bit_width(drawables)));
  return 32 - drawable_bits;
}

struct AccessInfo {
  VkPipelineStageFlags2 stage;
  VkAccessFlags2 access;
  VkImageLayout layout;
};

// How each declared Access maps to Vulkan synchronization.
AccessInfo ToVulkan(Access a) {
  constexpr VkPipelineStageFlags2 kDepthStages =
      VK_PIPELINE_STAGE_2_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_2_LATE_FRAGMENT_TESTS_BIT;
  switch (a) {
    case Access::kNone:
      return {VK_PIPELINE_STAGE_2_NONE, VK_ACCESS_2_NONE, VK_IMAGE_LAYOUT_UNDEFINED};
    case Access::kDepthWrite:
      return {kDepthStages,
              VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT |
                  VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT,
              VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL};
    case Access::kDepthTest:
      return {kDepthStages, VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT,
              VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL};
    case Access::kColorWrite:
      return {VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT,
              VK_ACCESS_2_COLOR_ATTACHMENT_READ_BIT | VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT,
              VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
    case Access::kSampled:
      return {VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT, VK_ACCESS_2_SHADER_SAMPLED_READ_BIT,
              VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    case Access::kComputeRead:
      return {VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_SAMPLED_READ_BIT,
              VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    case Access::kTransferSrc:
      return {VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_READ_BIT,
              VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL};
    case Access::kComputeWrite:
      return {VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
              VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT | VK_ACCESS_2_SHADER_SAMPLED_READ_BIT,
              VK_IMAGE_LAYOUT_GENERAL};
    case Access::kDepthResolve:
      // Depth resolves write in the colour-output stage with colour-attachment access.
      return {kDepthStages | VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT,
              VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT |
                  VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT |
                  VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT,
              VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL};
  }
  return {};
}

gpu::GpuLight ToGpu(const Light& l) {
  gpu::GpuLight g{};
  g.position_range = glm::vec4(l.position, l.range);
  g.color_intensity = glm::vec4(l.color, l.intensity);
  g.direction_type = glm::vec4(glm::normalize(l.direction), float(static_cast<uint32_t>(l.type)));
  // glTF spot falloff: smooth between cos(outer) and cos(inner).
  const float cos_outer = std::cos(l.outer_cone_angle);
  const float cos_inner = std::cos(l.inner_cone_angle);
  const float scale = 1.0f / std::max(0.001f, cos_inner - cos_outer);
  g.spot = glm::vec4(scale, -cos_outer * scale, 0.0f, 0.0f);
  return g;
}

// Replaces `*out` with a new buffer (the old one is idle: every frame waits for its fence).
absl::Status MakeBuffer(const vk::Context& ctx, VkDeviceSize size, VkBufferUsageFlags usage,
                        vk::MemoryUsage memory, const char* name, vk::Buffer* out) {
  absl::StatusOr<vk::Buffer> b = vk::Buffer::Create(ctx, size, usage, memory, name);
  if (!b.ok()) return b.status();
  *out = std::move(*b);
  return absl::OkStatus();
}

// The light a scene without lights gets: a warm sun from above and in front.
// Per-view state kept in a map (`last_used` in each value): drops the least recently used.
template <typename Map>
void DropLeastRecentlyUsed(Map& map) {
  if (map.empty()) return;
  map.erase(std::min_element(map.begin(), map.end(), [](const auto& a, const auto& b) {
    return a.second.last_used < b.second.last_used;
  }));
}

void DestroyViews(VkDevice device, std::vector<VkImageView>& views) {
  for (VkImageView v : views) vkDestroyImageView(device, v, nullptr);
  views.clear();
}

// A 2D view of each of `image`'s mips (for passes that write one mip and read another), appended
// to `views`; on failure the ones made are destroyed.
absl::Status CreateLevelViews(VkDevice device, const vk::Image& image, const char* name,
                              std::vector<VkImageView>& views) {
  for (uint32_t level = 0; level < image.desc().mip_levels; ++level) {
    VkImageViewCreateInfo vi{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
    vi.image = image.handle();
    vi.viewType = VK_IMAGE_VIEW_TYPE_2D;
    vi.format = image.desc().format;
    vi.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, level, 1, 0, 1};
    VkImageView view;
    if (vkCreateImageView(device, &vi, nullptr, &view) != VK_SUCCESS) {
      DestroyViews(device, views);
      return absl::ResourceExhaustedError(absl::StrCat(name, " level view"));
    }
    views.push_back(view);
  }
  return absl::OkStatus();
}

Light DefaultSun() {
  Light sun;
  sun.name = "default_sun";
  sun.type = LightType::kDirectional;
  sun.color = glm::vec3(1.0f, 0.96f, 0.90f);
  sun.intensity = 3.0f;
  sun.direction = glm::normalize(glm::vec3(-0.35f, -1.0f, -0.45f));
  return sun;
}

// vis_mlaa: per material on screen, the pixel rectangle its drawables in the frustum can cover
// (their projected bounds; the whole frame when a box reaches behind the eye).
std::vector<MaterialRect> MaterialRects(const GpuScene& gs, const Frustum& frustum,
                                        const glm::mat4& view_proj, uint32_t width,
                                        uint32_t height) {
  std::vector<MaterialRect> out;
  std::map<uint32_t, glm::ivec4> rects;  // material -> x0, y0, x1, y1 (exclusive)
  const glm::ivec2 size{int(width), int(height)};
  for (const DrawItem& d : gs.draws()) {
    if (d.alpha == AlphaMode::kBlend || !AabbIntersectsFrustum(d.world_bounds, frustum)) continue;
    glm::vec2 lo(1e30f), hi(-1e30f);
    bool behind = false;
    for (int c = 0; c < 8; ++c) {
      const glm::vec4 clip = view_proj * glm::vec4(d.world_bounds.corner(c), 1.0f);
      if (clip.w <= 1e-6f) {
        behind = true;
        break;
      }
      const glm::vec2 pixel = (glm::vec2(clip) / clip.w * 0.5f + 0.5f) * glm::vec2(size);
      lo = glm::min(lo, pixel);
      hi = glm::max(hi, pixel);
    }
    glm::ivec4 r(0, 0, size.x, size.y);
    if (!behind) {
      r = glm::ivec4(glm::clamp(glm::ivec2(glm::floor(lo)) - 1, glm::ivec2(0), size),
                     glm::clamp(glm::ivec2(glm::ceil(hi)) + 1, glm::ivec2(0), size));
    }
    auto [it, fresh] = rects.emplace(d.material, r);
    if (!fresh) {
      it->second = glm::ivec4(glm::min(glm::ivec2(it->second), glm::ivec2(r)),
                              glm::max(glm::ivec2(it->second.z, it->second.w), glm::ivec2(r.z, r.w)));
    }
  }
  for (const auto& [material, r] : rects) {
    if (r.z <= r.x || r.w <= r.y) continue;
    out.push_back(
        {material, VkRect2D{{r.x, r.y}, {uint32_t(r.z - r.x), uint32_t(r.w - r.y)}}});
  }
  return out;
}

}  // namespace

Scene::~Scene() = default;

struct Renderer::Impl {
  std::shared_ptr<vk::Context> ctx;  // shared with the scenes, which may outlive the renderer
  std::mutex mutex;                  // the queue and everything below
  SceneLayout scene_layout;
  std::array<std::unique_ptr<Pass>, static_cast<size_t>(PassId::kCount)> passes;
  VkCommandPool command_pool = VK_NULL_HANDLE;
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  VkFence fence = VK_NULL_HANDLE;
  VkQueryPool queries = VK_NULL_HANDLE;
  VkDescriptorPool frame_pool = VK_NULL_HANDLE;
  vk::Buffer frame_ubo;
  vk::Buffer lights_ubo;
  // Forward+: local lights and their bounds (grown to the largest count seen), tile lists
  // (sized for the tile grid).
  vk::Buffer local_lights;
  vk::Buffer light_bounds;
  vk::Buffer tile_counts;
  vk::Buffer tile_lights;
  vk::Buffer tile_counts_readback;
  vk::Buffer row_lights;  // lights binned by tile row (light_cull.comp)
  uint32_t row_capacity = 0;
  uint32_t light_capacity = 0;
  uint32_t tile_capacity = 0;
  // Geometry culling (grown to the largest scene drawn): the draw lists, the culling pass's
  // uniforms (one range per phase) and scratch, and a stand-in for the visibility bits of the
  // modes that keep none.
  vk::Buffer draw_commands;
  vk::Buffer draw_counts;
  vk::Buffer cull_uniforms;
  vk::Buffer cull_bases;
  vk::Buffer no_visibility;
  VkDeviceSize cull_uniform_stride = 0;
  uint32_t command_capacity = 0;
  uint32_t count_capacity = 0;
  uint32_t base_capacity = 0;
  VkQueryPool stat_queries = VK_NULL_HANDLE;  // pipeline statistics, one per pass
  vk::Pipeline id_pipeline;                   // FrameCapture::want_ids, made on first use
  uint64_t frame_counter = 0;
  FrameTargets targets;
  // taa: each (scene, view)'s history, least recently used dropped past kMaxTaaViews.
  struct TaaHistory {
    vk::Image images[2];
    bool written[2] = {false, false};
    uint32_t current = 0;  // the image last written
    uint32_t frames = 0;   // frames blended into it since the last reset (capped)
    uint32_t jitter_index = 0;
    glm::mat4 view_proj{0.0f};  // unjittered, of the last frame
    uint64_t last_used = 0;
  };
  std::map<std::pair<uint64_t, uint64_t>, TaaHistory> taa_history;
  // Shadows: the atlas (made at the settings' size on first use), where its faces are and what
  // they hold (ShadowAtlas), the uniforms the shading reads, and a 1x1 stand-in bound while
  // shadows are off.
  vk::Image shadow_atlas;
  vk::Image shadow_placeholder;
  std::unique_ptr<ShadowAtlas> shadow_faces;
  bool shadow_atlas_written = false;  // false: its contents (and layout) are undefined
  vk::Buffer shadow_ubo;
  vk::Sampler shadow_sampler;  // comparison, bilinear
  vk::Sampler linear_sampler;  // ssao visibility
  vk::Image ao_placeholder;    // 1x1, shader-read layout: what the shading reads without ssao
  // Auto exposure: each (scene, view)'s adapted average (ExposureFrame::state), least recently
  // used dropped past kMaxExposureViews.
  struct ExposureState {
    vk::Image image;
    bool written = false;
    uint64_t last_used = 0;
  };
  std::map<std::pair<uint64_t, uint64_t>, ExposureState> exposure_state;
  // IBL: the maps (made when ibl first runs), the hash of the sky they hold, and a 1x1 cube
  // bound while ibl is off.
  std::unique_ptr<IblMaps> ibl;
  uint64_t ibl_sky_hash = 0;
  vk::Image cube_placeholder;

  ~Impl() {
    if (!ctx) return;
    VkDevice d = ctx->device();
    vkDeviceWaitIdle(d);
    for (auto& p : passes) p.reset();
    taa_history.clear();
    exposure_state.clear();
    ibl.reset();
    cube_placeholder = vk::Image();
    shadow_atlas = vk::Image();
    shadow_placeholder = vk::Image();
    shadow_ubo = vk::Buffer();
    shadow_sampler = vk::Sampler();
    linear_sampler = vk::Sampler();
    ao_placeholder = vk::Image();
    DestroyHizViews();
    targets = FrameTargets{};
    frame_ubo = vk::Buffer();
    if (stat_queries) vkDestroyQueryPool(d, stat_queries, nullptr);
    lights_ubo = vk::Buffer();
    for (vk::Buffer* b : {&local_lights, &light_bounds, &tile_counts, &tile_lights,
                          &tile_counts_readback, &row_lights})
      *b = vk::Buffer();
    if (frame_pool) vkDestroyDescriptorPool(d, frame_pool, nullptr);
    if (queries) vkDestroyQueryPool(d, queries, nullptr);
    if (fence) vkDestroyFence(d, fence, nullptr);
    if (command_pool) vkDestroyCommandPool(d, command_pool, nullptr);
    if (scene_layout.pipeline_layout)
      vkDestroyPipelineLayout(d, scene_layout.pipeline_layout, nullptr);
    if (scene_layout.set_layout) vkDestroyDescriptorSetLayout(d, scene_layout.set_layout, nullptr);
    if (scene_layout.material_set_layout)
      vkDestroyDescriptorSetLayout(d, scene_layout.material_set_layout, nullptr);
  }

  absl::Status Init();
  absl::Status InitShadows();
  absl::Status EnsureShadowAtlas(uint32_t size);
  absl::Status EnsureAo(uint32_t width, uint32_t height);
  // bloom's chains for the current targets (half their size, kBloomLevels mips).
  absl::Status EnsureBloom();
  absl::StatusOr<ExposureState*> Exposure(const GpuScene& scene, uint64_t view);
  // shadows: places this frame's shadow views in the atlas, fills shadow_ubo's views, marks the
  // shadowed lights in `gl` / `ll` (the light buffers, in the order of `global` / `local`) and
  // lists the faces to render in `out`.
  absl::Status PrepareShadows(const GpuScene& gs, const Camera& camera, float aspect,
                              uint64_t view, const Settings& s, const glm::mat4& view_proj,
                              const std::vector<Light>& global, const std::vector<Light>& local,
                              gpu::GpuLight* gl, gpu::GpuLight* ll, Frame& frame,
                              ShadowFrame* out);
  absl::Status EnsureTargets(uint32_t width, uint32_t height);
  // The targets the AA mode needs, at its sample count.
  absl::Status EnsureAaTargets(const Settings& s);
  absl::StatusOr<TaaHistory*> Taa(const GpuScene& scene, uint64_t view);
  absl::Status EnsureLightBuffers(uint32_t lights, uint32_t tiles);
  absl::Status EnsureRowBuffer(size_t entries);
  absl::Status EnsureCullBuffers(uint32_t items, uint32_t lists);
  void DestroyHizViews();
  // Copies the depth, the light lists (`tiles` of them), the tonemap's input `hdr` (in the
  // sampled layout) and auto exposure's `exposure` state (general layout; may be null).
  absl::Status Capture(FrameCapture* capture, uint32_t tiles, const vk::Image& hdr,
                       const vk::Image* exposure);
  // Capture helpers: begins `cmd`; makes the copies recorded so far visible to the host,
  // submits and waits.
  void BeginOneTime();
  absl::Status EndCopiesAndWait();
  absl::Status CaptureIds(const GpuScene& scene, VkDescriptorSet scene_set,
                          FrameCapture* capture);
  // none / cpu_frustum: the CPU writes phase 0's lists (and its in-frustum statistic).
  void CountDrawn(const GpuScene& gs, const DrawLists& draws, const std::vector<PassId>& pass_ids,
                  FrameStats& stats, std::vector<uint32_t>* drawn_out) const;
  void WriteCpuLists(const GpuScene& scene, const DrawLists& lists, const Frustum* frustum);
  absl::StatusOr<GpuScene::ViewVisibility*> Visibility(const GpuScene& scene, uint64_t view);
  // The frame's set 0; binds the shadow atlas when `shadows` (else the 1x1 stand-in).
  VkDescriptorSet WriteSceneSet(const GpuScene& scene, bool shadows, bool ssao, bool ibl);
  // ibl: makes the maps and bakes `sky` unless they hold it; true when it baked.
  absl::StatusOr<bool> EnsureIbl(const SkyParams& sky);
};

absl::Status Renderer::Impl::Init() {
  VkDevice d = ctx->device();
  std::vector<VkDescriptorSetLayoutBinding> bindings = {
      {gpu::kBindingFrame, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1,
       VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, nullptr},
      {gpu::kBindingLights, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1, VK_SHADER_STAGE_FRAGMENT_BIT,
       nullptr},
      {gpu::kBindingDrawables, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1,
       VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, nullptr},
      {gpu::kBindingMaterials, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1,
       VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, nullptr},
      {gpu::kBindingLocalLights, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_FRAGMENT_BIT,
       nullptr},
      {gpu::kBindingTileCounts, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_FRAGMENT_BIT,
       nullptr},
      {gpu::kBindingTileLights, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_FRAGMENT_BIT,
       nullptr},
      {gpu::kBindingShadows, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1, VK_SHADER_STAGE_FRAGMENT_BIT,
       nullptr},
      {gpu::kBindingShadowAtlas, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
       VK_SHADER_STAGE_FRAGMENT_BIT, nullptr},
      {gpu::kBindingAo, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT,
       nullptr},
      {gpu::kBindingIrradiance, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
       VK_SHADER_STAGE_FRAGMENT_BIT, nullptr},
      {gpu::kBindingSpecular, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
       VK_SHADER_STAGE_FRAGMENT_BIT, nullptr},
      {gpu::kBindingBrdfLut, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
       VK_SHADER_STAGE_FRAGMENT_BIT, nullptr},
      {gpu::kBindingEnvironment, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
       VK_SHADER_STAGE_FRAGMENT_BIT, nullptr},
  };
  VkDescriptorSetLayoutCreateInfo li{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  li.bindingCount = static_cast<uint32_t>(bindings.size());
  li.pBindings = bindings.data();
  VK_RETURN_IF_ERROR(vkCreateDescriptorSetLayout(d, &li, nullptr, &scene_layout.set_layout),
                     "scene set layout");
  std::vector<VkDescriptorSetLayoutBinding> texture_bindings = {
      {gpu::kBindingMaterialUniform, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1,
       VK_SHADER_STAGE_FRAGMENT_BIT, nullptr}};
  for (uint32_t k = 0; k < gpu::kMaterialTextureSlots; ++k)
    texture_bindings.push_back({gpu::kBindingBaseColorTex + k,
                                VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
                                VK_SHADER_STAGE_FRAGMENT_BIT, nullptr});
  li.bindingCount = static_cast<uint32_t>(texture_bindings.size());
  li.pBindings = texture_bindings.data();
  VK_RETURN_IF_ERROR(
      vkCreateDescriptorSetLayout(d, &li, nullptr, &scene_layout.material_set_layout),
      "material set layout");
  const VkDescriptorSetLayout set_layouts[] = {scene_layout.set_layout,
                                               scene_layout.material_set_layout};
  VkPipelineLayoutCreateInfo pli{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  pli.setLayoutCount = 2;
  pli.pSetLayouts = set_layouts;
  VK_RETURN_IF_ERROR(vkCreatePipelineLayout(d, &pli, nullptr, &scene_layout.pipeline_layout),
                     "scene pipeline layout");

  auto add = [this](absl::StatusOr<std::unique_ptr<Pass>> pass) -> absl::Status {
    if (!pass.ok()) return pass.status();
    passes[static_cast<size_t>((*pass)->id())] = std::move(*pass);
    return absl::OkStatus();
  };
  if (absl::Status s = add(CreateDepthPrepass(*ctx, scene_layout)); !s.ok()) return s;
  if (absl::Status s = add(CreateDepthPrepass(*ctx, scene_layout, PassId::kDepthPrepassLate));
      !s.ok())
    return s;
  if (absl::Status s = add(CreateCullPass(*ctx, PassId::kCull)); !s.ok()) return s;
  if (absl::Status s = add(CreateCullPass(*ctx, PassId::kCullLate)); !s.ok()) return s;
  if (absl::Status s = add(CreateHizBuildPass(*ctx)); !s.ok()) return s;
  if (absl::Status s = add(CreateForwardPass(*ctx, scene_layout)); !s.ok()) return s;
  if (absl::Status s = add(CreateTransparentPass(*ctx, scene_layout)); !s.ok()) return s;
  if (absl::Status s = add(CreateTonemapPass(*ctx)); !s.ok()) return s;
  if (absl::Status s = add(CreateLightCullPass(*ctx)); !s.ok()) return s;
  if (absl::Status s = add(CreateReadbackPass()); !s.ok()) return s;
  if (absl::Status s = add(CreateVisibilityPass(*ctx, scene_layout, PassId::kVisibility)); !s.ok())
    return s;
  if (absl::Status s = add(CreateVisibilityPass(*ctx, scene_layout, PassId::kVisibilityLate));
      !s.ok())
    return s;
  if (absl::Status s = add(CreateVisResolvePass(*ctx, scene_layout)); !s.ok()) return s;
  if (absl::Status s = add(CreateVisShadePass(*ctx, scene_layout)); !s.ok()) return s;
  if (absl::Status s = add(CreateGeometricAaPass(*ctx)); !s.ok()) return s;
  if (absl::Status s = add(CreateTaaPass(*ctx)); !s.ok()) return s;
  if (absl::Status s = add(CreateFxaaPass(*ctx)); !s.ok()) return s;
  if (absl::Status s = add(CreateShadowPass(*ctx, scene_layout)); !s.ok()) return s;
  if (absl::Status s = add(CreateSsaoPass(*ctx)); !s.ok()) return s;
  if (absl::Status s = add(CreateExposurePass(*ctx)); !s.ok()) return s;
  if (absl::Status s = add(CreateBloomPass(*ctx)); !s.ok()) return s;

  VkCommandPoolCreateInfo pci{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  pci.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  pci.queueFamilyIndex = ctx->queue_family();
  VK_RETURN_IF_ERROR(vkCreateCommandPool(d, &pci, nullptr, &command_pool), "command pool");
  VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  ai.commandPool = command_pool;
  ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  ai.commandBufferCount = 1;
  VK_RETURN_IF_ERROR(vkAllocateCommandBuffers(d, &ai, &cmd), "command buffer");
  VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  VK_RETURN_IF_ERROR(vkCreateFence(d, &fci, nullptr, &fence), "fence");
  VkQueryPoolCreateInfo qi{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
  qi.queryType = VK_QUERY_TYPE_TIMESTAMP;
  qi.queryCount = kMaxTimestamps;
  VK_RETURN_IF_ERROR(vkCreateQueryPool(d, &qi, nullptr, &queries), "query pool");
  if (ctx->info().pipeline_statistics) {
    VkQueryPoolCreateInfo si{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    si.queryType = VK_QUERY_TYPE_PIPELINE_STATISTICS;
    si.queryCount = static_cast<uint32_t>(PassId::kCount);
    si.pipelineStatistics = kPipelineStats;
    VK_RETURN_IF_ERROR(vkCreateQueryPool(d, &si, nullptr, &stat_queries), "statistics pool");
  }

  // Per frame: the scene set, light culling, two culling phases, a set per pyramid level, the
  // vis_mlaa and post passes' sets.
  // Shadows, ssao, ibl: six more images and a uniform buffer in the scene set; the post passes
  // allocate a set per draw (bloom: eleven).
  const VkDescriptorPoolSize sizes[] = {
      {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 12},
      {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 40},
      {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 192},
      {VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 48},
  };
  VkDescriptorPoolCreateInfo dpi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  dpi.maxSets = 128;
  dpi.poolSizeCount = 4;
  dpi.pPoolSizes = sizes;
  VK_RETURN_IF_ERROR(vkCreateDescriptorPool(d, &dpi, nullptr, &frame_pool), "descriptor pool");

  absl::StatusOr<vk::Buffer> fu =
      vk::Buffer::Create(*ctx, sizeof(gpu::FrameUniforms), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT,
                         vk::MemoryUsage::kUpload, "frame_uniforms");
  if (!fu.ok()) return fu.status();
  frame_ubo = std::move(*fu);
  absl::StatusOr<vk::Buffer> lu =
      vk::Buffer::Create(*ctx, sizeof(gpu::GpuLight) * gpu::kMaxLights,
                         VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, vk::MemoryUsage::kUpload, "lights");
  if (!lu.ok()) return lu.status();
  lights_ubo = std::move(*lu);
  if (absl::Status s = EnsureRowBuffer(1024); !s.ok()) return s;
  const VkDeviceSize align =
      std::max<VkDeviceSize>(16, ctx->limits().minUniformBufferOffsetAlignment);
  cull_uniform_stride = (sizeof(gpu::CullUniforms) + align - 1) / align * align;
  if (absl::Status s = MakeBuffer(*ctx, 2 * cull_uniform_stride, VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT,
                                  vk::MemoryUsage::kUpload, "cull_uniforms", &cull_uniforms);
      !s.ok())
    return s;
  if (absl::Status s = MakeBuffer(*ctx, 4,
                                  VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                      VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                  vk::MemoryUsage::kUpload, "no_visibility", &no_visibility);
      !s.ok())
    return s;
  std::memset(no_visibility.mapped(), 0, 4);
  if (absl::Status s = EnsureCullBuffers(1, 1); !s.ok()) return s;
  if (absl::Status s = InitShadows(); !s.ok()) return s;
  return EnsureLightBuffers(1, 1);
}

absl::Status Renderer::Impl::InitShadows() {
  if (absl::Status s = MakeBuffer(*ctx, sizeof(gpu::ShadowUniforms),
                                  VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, vk::MemoryUsage::kUpload,
                                  "shadow_uniforms", &shadow_ubo);
      !s.ok())
    return s;
  std::memset(shadow_ubo.mapped(), 0, sizeof(gpu::ShadowUniforms));
  // The hardware shadow sampler: bilinear comparison taps (the PCF's 4 taps each weigh 2x2
  // texels). Standard Z: lit where the reference is nearer than (or at) the stored depth.
  VkSamplerCreateInfo si{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
  si.magFilter = si.minFilter = VK_FILTER_LINEAR;
  si.addressModeU = si.addressModeV = si.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
  si.compareEnable = VK_TRUE;
  si.compareOp = VK_COMPARE_OP_LESS_OR_EQUAL;
  absl::StatusOr<vk::Sampler> ss = vk::Sampler::Create(*ctx, si, "shadow_compare");
  if (!ss.ok()) return ss.status();
  shadow_sampler = std::move(*ss);
  absl::StatusOr<vk::Sampler> ls = CreateClampSampler(*ctx, true, "ao_linear");
  if (!ls.ok()) return ls.status();
  linear_sampler = std::move(*ls);
  // What the scene set binds while shadows are off: a 1x1 atlas in shader-read layout.
  vk::ImageDesc desc;
  desc.format = kShadowFormat;
  desc.usage = VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT;
  absl::StatusOr<vk::Image> placeholder = vk::Image::Create(*ctx, desc, "shadow_placeholder");
  if (!placeholder.ok()) return placeholder.status();
  shadow_placeholder = std::move(*placeholder);
  // And without ssao, a 1x1 AO image (its contents are never read: the shaders test a flag).
  desc.format = kAoFormat;
  desc.usage = VK_IMAGE_USAGE_SAMPLED_BIT;
  absl::StatusOr<vk::Image> ao = vk::Image::Create(*ctx, desc, "ao_placeholder");
  if (!ao.ok()) return ao.status();
  ao_placeholder = std::move(*ao);
  // And without ibl, a 1x1 cube (never read either).
  desc.format = VK_FORMAT_R16G16B16A16_SFLOAT;
  desc.array_layers = 6;
  desc.view_type = VK_IMAGE_VIEW_TYPE_CUBE;
  absl::StatusOr<vk::Image> cube = vk::Image::Create(*ctx, desc, "cube_placeholder");
  if (!cube.ok()) return cube.status();
  cube_placeholder = std::move(*cube);
  BeginOneTime();
  VkImageMemoryBarrier2 b[3];
  for (int i = 0; i < 3; ++i) {
    b[i] = vk::MakeImageBarrier(
        i == 0 ? shadow_placeholder : i == 1 ? ao_placeholder : cube_placeholder,
        {VK_PIPELINE_STAGE_2_NONE, VK_ACCESS_2_NONE, VK_IMAGE_LAYOUT_UNDEFINED,
         VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT, VK_ACCESS_2_SHADER_SAMPLED_READ_BIT,
         VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL});
  }
  vk::CmdBarrier(cmd, b, 3);
  return EndCopiesAndWait();
}

absl::Status Renderer::Impl::EnsureShadowAtlas(uint32_t size) {
  if (shadow_atlas && shadow_atlas.desc().width == size) return absl::OkStatus();
  vkDeviceWaitIdle(ctx->device());
  shadow_atlas = vk::Image();
  vk::ImageDesc desc;
  desc.width = desc.height = size;
  desc.format = kShadowFormat;
  desc.usage = VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT;
  absl::StatusOr<vk::Image> atlas = vk::Image::Create(*ctx, desc, "shadow_atlas");
  if (!atlas.ok()) return atlas.status();
  shadow_atlas = std::move(*atlas);
  shadow_faces = std::make_unique<ShadowAtlas>(size);
  shadow_atlas_written = false;
  return absl::OkStatus();
}

absl::Status Renderer::Impl::PrepareShadows(const GpuScene& gs, const Camera& camera,
                                            float aspect, uint64_t view, const Settings& s,
                                            const glm::mat4& view_proj,
                                            const std::vector<Light>& global,
                                            const std::vector<Light>& local, gpu::GpuLight* gl,
                                            gpu::GpuLight* ll, Frame& frame, ShadowFrame* out) {
  auto& su = *static_cast<gpu::ShadowUniforms*>(shadow_ubo.mapped());
  if (absl::Status st = EnsureShadowAtlas(s.shadow_atlas_size); !st.ok()) return st;
  ShadowAtlas& atlas = *shadow_faces;
  out->atlas = &shadow_atlas;
  out->atlas_new = !shadow_atlas_written;
  if (out->atlas_new) atlas.Clear();
  atlas.BeginFrame();
  const uint32_t evictions_before = atlas.evictions();
  const uint32_t size = s.shadow_atlas_size;
  const std::vector<DrawItem>& items = gs.draws();
  FrameStats& stats = frame.stats;
  uint32_t views = 0;
  // Places one face; lists it for rendering unless the atlas already holds exactly it.
  auto add_face = [&](uint64_t key, uint32_t res, const glm::mat4& face_view_proj, float texel,
                      bool perspective) {
    uint64_t content = HashBytes(&face_view_proj, sizeof(face_view_proj), gs.serial());
    content = HashBytes(&res, sizeof(res), content);
    std::optional<ShadowAtlas::Placement> placed = atlas.Acquire(key, res, content);
    if (!placed) return false;
    gpu::GpuShadowView& v = su.views[views++];
    v.world_to_atlas = AtlasTransform(placed->rect, size) * face_view_proj;
    v.params = glm::vec4(texel, perspective ? 1.0f : 0.0f, 0.0f, 0.0f);
    if (placed->cached && s.shadow_cache) return true;
    ShadowFace face{placed->rect.x, placed->rect.y, placed->rect.size, face_view_proj, {}};
    // The face's own culling: every item in its frustum (all of them with culling none).
    // Blended surfaces cast no shadow.
    const Frustum frustum = FrustumFromViewProj(face_view_proj);
    for (uint32_t i = 0; i < items.size(); ++i) {
      if (items[i].alpha == AlphaMode::kBlend) continue;
      if (s.culling != CullingMode::kNone &&
          !AabbIntersectsFrustum(items[i].world_bounds, frustum))
        continue;
      face.items.push_back(i);
    }
    out->faces.push_back(std::move(face));
    return true;
  };
  auto key_of = [&](uint64_t kind, uint64_t a, uint64_t b) {
    const uint64_t k[4] = {kind, gs.serial(), a, b};
    return HashBytes(k, sizeof(k));
  };

  // The sun: the first directional light, in cascades that follow this view's camera (so the
  // key carries the view: two viewers of one scene do not overwrite each other's cascades).
  const glm::vec3 eye = CameraPosition(camera);
  uint32_t cascades = 0;
  for (size_t i = 0; i < global.size(); ++i) {
    if (global[i].type != LightType::kDirectional) continue;
    const Aabb& b = gs.bounds();
    float distance = b.farthest_distance(eye);
    if (camera.zfar > 0.0f) distance = std::min(distance, camera.zfar);
    distance = std::max(distance, camera.znear * 2.0f);
    CascadeParams cp;
    cp.count = kMaxCascades;
    cp.resolution = size / 4;
    const std::vector<Cascade> cs =
        ComputeCascades(camera, aspect, global[i].direction, b, distance, cp);
    bool placed = true;
    for (uint32_t c = 0; c < cs.size() && placed; ++c)
      placed = add_face(key_of(1, view, c), cp.resolution, cs[c].view_proj, cs[c].texel_world,
                        false);
    if (!placed) {  // an atlas too small for them: the sun stays unshadowed
      views = 0;
      out->faces.clear();
      frame.settings.notes.push_back(
          {"shadows", "the sun's cascades did not fit the shadow atlas; the sun is unshadowed"});
      break;
    }
    // The spheres the shader picks cascades by, less the normal offset's 1.5 texels (and half a
    // texel of snapping): an offset lookup then stays inside the map's filter border.
    for (uint32_t c = 0; c < cs.size(); ++c)
      su.cascade_spheres[c] = glm::vec4(cs[c].center, cs[c].radius - 2.0f * cs[c].texel_world);
    cascades = uint32_t(cs.size());
    gl[i].spot.z = 1.0f;  // views 0 .. cascades - 1
    gl[i].spot.w = float(cascades);
    ++stats.shadowed_lights;
    break;
  }

  // Point and spot lights: the most important ones in view. A spot has one view, a point
  // light six (its unrolled cubemap); a light whose faces do not fit even at half size stays
  // unshadowed.
  const std::vector<uint32_t> chosen =
      ChooseShadowedLights(local, FrustumFromViewProj(view_proj), eye, s.shadow_lights);
  uint32_t dropped = 0;
  for (uint32_t li : chosen) {
    const Light& l = local[li];
    const bool spot = l.type == LightType::kSpot;
    const uint32_t faces = spot ? 1 : kCubeFaces;
    bool placed = false;
    for (uint32_t res = std::max(size / (spot ? 8 : 16), 64u); res >= 64 && !placed; res /= 2) {
      const uint32_t first = views;
      const size_t rendered = out->faces.size();
      placed = true;
      const float border = float(res) / float(res - 2 * kShadowBorderTexels);
      const float tan_half =
          spot ? std::tan(std::min(l.outer_cone_angle, glm::radians(89.0f))) * border : border;
      for (uint32_t f = 0; f < faces && placed; ++f) {
        const glm::mat4 vp = spot ? SpotViewProj(l, res, gs.bounds())
                                  : PointFaceViewProj(l, f, res, gs.bounds());
        placed = add_face(key_of(2, li, f), res, vp, 2.0f * tan_half / float(res), true);
      }
      if (!placed) {  // give back the faces placed: they were never rendered
        for (uint32_t f = 0; f < faces; ++f) atlas.Release(key_of(2, li, f));
        views = first;
        out->faces.resize(rendered);
        continue;
      }
      ll[li].spot.z = float(first + 1);
      ll[li].spot.w = float(faces);
      ++stats.shadowed_lights;
    }
    if (!placed) ++dropped;
  }
  if (dropped > 0) {
    frame.settings.notes.push_back(
        {"shadow_lights", absl::StrCat(dropped, " of ", chosen.size(),
                                       " lights did not fit the shadow atlas and are unshadowed "
                                       "(use a larger shadow_atlas_size)")});
  }
  su.counts = glm::uvec4(views, cascades, 0u, gpu::kShadowsOn);
  su.atlas = glm::vec4(float(size), 1.0f / float(size), 1.5f, 0.0f);
  stats.shadow_views = views;
  stats.shadow_faces_rendered = uint32_t(out->faces.size());
  for (const ShadowFace& f : out->faces) stats.shadow_draws += uint32_t(f.items.size());
  stats.shadow_evictions = atlas.evictions() - evictions_before;
  // Until this frame's submit succeeds the atlas is not known to hold what the faces say.
  if (!out->faces.empty()) shadow_atlas_written = false;
  return absl::OkStatus();
}

absl::Status Renderer::Impl::EnsureAo(uint32_t width, uint32_t height) {
  if (targets.ao && targets.ao.desc().width == width && targets.ao.desc().height == height)
    return absl::OkStatus();
  vkDeviceWaitIdle(ctx->device());
  vk::ImageDesc desc;
  desc.width = width;
  desc.height = height;
  desc.format = kAoFormat;
  desc.usage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT;
  absl::StatusOr<vk::Image> ao = vk::Image::Create(*ctx, desc, "ao");
  if (!ao.ok()) return ao.status();
  absl::StatusOr<vk::Image> temp = vk::Image::Create(*ctx, desc, "ao_temp");
  if (!temp.ok()) return temp.status();
  targets.ao = std::move(*ao);
  targets.ao_temp = std::move(*temp);
  return absl::OkStatus();
}

absl::Status Renderer::Impl::EnsureCullBuffers(uint32_t items, uint32_t lists) {
  items = std::max(items, 1u);
  // Two phases, each with a segment region and a batch region of `items` commands.
  const uint32_t commands = 4 * items;
  constexpr VkBufferUsageFlags kListUsage = VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT |
                                            VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                            VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  if (commands > command_capacity) {
    if (absl::Status s =
            MakeBuffer(*ctx, VkDeviceSize(commands) * sizeof(VkDrawIndexedIndirectCommand),
                       kListUsage, vk::MemoryUsage::kUpload, "draw_commands", &draw_commands);
        !s.ok())
      return s;
    command_capacity = commands;
  }
  const uint32_t counts = 2 * (lists + gpu::kCullStatCount);
  if (counts > count_capacity) {
    if (absl::Status s = MakeBuffer(*ctx, VkDeviceSize(counts) * 4, kListUsage,
                                    vk::MemoryUsage::kUpload, "draw_counts", &draw_counts);
        !s.ok())
      return s;
    count_capacity = counts;
  }
  if (lists > base_capacity) {
    if (absl::Status s = MakeBuffer(*ctx, VkDeviceSize(lists) * 4,
                                    VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                    vk::MemoryUsage::kDeviceLocal, "cull_bases", &cull_bases);
        !s.ok())
      return s;
    base_capacity = lists;
  }
  return absl::OkStatus();
}

void Renderer::Impl::DestroyHizViews() {
  for (auto* levels : {&targets.hiz_levels, &targets.bloom_down_levels, &targets.bloom_up_levels})
    DestroyViews(ctx->device(), *levels);
}

absl::Status Renderer::Impl::EnsureBloom() {
  // At least 2^(kBloomLevels - 1) texels a side, so every level exists (a tiny frame's bloom is
  // then magnified).
  constexpr uint32_t kMin = 1u << (kBloomLevels - 1);
  const uint32_t width = std::max(kMin, targets.width / 2);
  const uint32_t height = std::max(kMin, targets.height / 2);
  if (targets.bloom_down && targets.bloom_down.desc().width == width &&
      targets.bloom_down.desc().height == height &&
      targets.bloom_down_levels.size() == kBloomLevels &&
      targets.bloom_up_levels.size() == kBloomLevels - 1)
    return absl::OkStatus();
  vkDeviceWaitIdle(ctx->device());
  const VkDevice d = ctx->device();
  DestroyViews(d, targets.bloom_down_levels);
  DestroyViews(d, targets.bloom_up_levels);
  auto make = [&](uint32_t mips, const char* name, vk::Image* image,
                  std::vector<VkImageView>* views) -> absl::Status {
    vk::ImageDesc desc;
    desc.width = width;
    desc.height = height;
    desc.format = kHdrFormat;
    desc.mip_levels = mips;
    desc.usage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT;
    absl::StatusOr<vk::Image> img = vk::Image::Create(*ctx, desc, name);
    if (!img.ok()) return img.status();
    *image = std::move(*img);
    return CreateLevelViews(d, *image, name, *views);
  };
  absl::Status st =
      make(kBloomLevels, "bloom_down", &targets.bloom_down, &targets.bloom_down_levels);
  if (st.ok()) st = make(kBloomLevels - 1, "bloom_up", &targets.bloom_up, &targets.bloom_up_levels);
  if (!st.ok()) {  // all or nothing: the next frame with bloom tries again
    DestroyViews(d, targets.bloom_down_levels);
    DestroyViews(d, targets.bloom_up_levels);
    targets.bloom_down = vk::Image();
    targets.bloom_up = vk::Image();
  }
  return st;
}

absl::StatusOr<Renderer::Impl::ExposureState*> Renderer::Impl::Exposure(const GpuScene& scene,
                                                                        uint64_t view) {
  constexpr size_t kMaxExposureViews = 64;  // 1x1 images: cheap to keep
  const std::pair<uint64_t, uint64_t> key{scene.serial(), view};
  auto it = exposure_state.find(key);
  if (it != exposure_state.end()) {
    it->second.last_used = ++frame_counter;
    return &it->second;
  }
  if (exposure_state.size() >= kMaxExposureViews) DropLeastRecentlyUsed(exposure_state);
  vk::ImageDesc desc;
  desc.format = kExposureFormat;
  desc.usage = VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_SAMPLED_BIT |
               VK_IMAGE_USAGE_TRANSFER_SRC_BIT;  // FrameCapture::exposure_log2
  absl::StatusOr<vk::Image> img = vk::Image::Create(*ctx, desc, "exposure_state");
  if (!img.ok()) return img.status();
  ExposureState e;
  e.image = std::move(*img);
  e.last_used = ++frame_counter;
  return &exposure_state.emplace(key, std::move(e)).first->second;
}

absl::StatusOr<GpuScene::ViewVisibility*> Renderer::Impl::Visibility(const GpuScene& scene,
                                                                      uint64_t view) {
  auto& views = scene.views();
  auto it = views.find(view);
  if (it == views.end()) {
    if (views.size() >= kMaxViews) DropLeastRecentlyUsed(views);
    GpuScene::ViewVisibility v;
    const VkDeviceSize bytes = VkDeviceSize((scene.draws().size() + 31) / 32 + 1) * 4;
    for (vk::Buffer& b : v.bits) {
      if (absl::Status s = MakeBuffer(*ctx, bytes,
                                      VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                          VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                      vk::MemoryUsage::kUpload, "visibility_bits", &b);
          !s.ok())
        return s;
      std::memset(b.mapped(), 0, bytes);  // nothing seen yet: the first phase draws nothing
    }
    it = views.emplace(view, std::move(v)).first;
  }
  it->second.last_used = ++frame_counter;
  return &it->second;
}

// What a frame drew, from the lists it executed (counts clamped to the list sizes, as the
// draws clamp them to maxDrawCount): drawables, draws and triangles per pass, and the drawn
// drawables when `drawn_out` is set.
void Renderer::Impl::CountDrawn(const GpuScene& gs, const DrawLists& draws,
                                const std::vector<PassId>& pass_ids, FrameStats& stats,
                                std::vector<uint32_t>* drawn_out) const {
  const uint32_t item_count = uint32_t(gs.draws().size());
  const uint32_t segment_count = uint32_t(gs.segments().size());
  const uint32_t list_count = segment_count + uint32_t(gs.batches().size());
  const auto* commands = static_cast<const VkDrawIndexedIndirectCommand*>(draw_commands.mapped());
  const auto* counts = static_cast<const uint32_t*>(draw_counts.mapped());
  struct ListSums {
    uint64_t triangles = 0;
    uint32_t draws = 0;
  };
  auto sum_list = [&](uint32_t phase, bool batch, uint32_t first, uint32_t capacity,
                      uint32_t count_index, std::vector<uint32_t>* drawn) {
    ListSums r;
    const uint32_t n = std::min(counts[draws.CountOffset(phase, count_index) / 4], capacity);
    const VkDrawIndexedIndirectCommand* c =
        commands + draws.CommandOffset(phase, batch, first) / sizeof(VkDrawIndexedIndirectCommand);
    for (uint32_t k = 0; k < n; ++k) {
      r.triangles += c[k].indexCount / 3;
      if (drawn) drawn->push_back(c[k].firstInstance);
    }
    r.draws = n;
    return r;
  };
  // Per phase and group: the segments' sums; per phase: the opaque batches'.
  ListSums group_sums[2][3] = {};
  ListSums batch_sums[2] = {};
  std::vector<uint32_t> drawn;
  uint32_t late = 0;
  for (uint32_t p = 0; p < draws.phases; ++p) {
    for (uint32_t i = 0; i < segment_count; ++i) {
      const DrawSegment& seg = gs.segments()[i];
      const ListSums r = sum_list(p, false, seg.first_item, seg.item_count, i, &drawn);
      ListSums& g = group_sums[p][static_cast<uint32_t>(seg.group)];
      g.triangles += r.triangles;
      g.draws += r.draws;
      if (p == 1) late += r.draws;
    }
    for (uint32_t b = 0; b < gs.batches().size(); ++b) {
      const DrawBatch& batch = gs.batches()[b];
      const ListSums r =
          sum_list(p, true, batch.first_item, batch.item_count, segment_count + b, nullptr);
      batch_sums[p].triangles += r.triangles;
      batch_sums[p].draws += r.draws;
    }
  }
  const uint32_t* stats0 = counts + draws.CountOffset(0, list_count) / 4;
  stats.drawables_in_frustum = stats0[gpu::kCullStatInFrustum];
  stats.drawables_drawn = uint32_t(drawn.size());
  stats.drawables_culled = item_count - uint32_t(drawn.size());
  stats.drawables_late = late;
  if (draws.phases == 2) {
    stats.drawables_stale = counts[draws.CountOffset(1, list_count) / 4 + gpu::kCullStatStale];
  }
  auto add = [&](const ListSums& r) {
    stats.triangles_submitted += r.triangles;
    stats.draws += r.draws;
  };
  for (PassId id : pass_ids) {
    const uint32_t o = static_cast<uint32_t>(AlphaMode::kOpaque);
    const uint32_t k = static_cast<uint32_t>(AlphaMode::kMask);
    const uint32_t b = static_cast<uint32_t>(AlphaMode::kBlend);
    if (id == PassId::kDepthPrepass || id == PassId::kDepthPrepassLate) {
      const uint32_t p = id == PassId::kDepthPrepassLate ? 1 : 0;
      add(batch_sums[p]);
      add(group_sums[p][k]);
    } else if (id == PassId::kForward || id == PassId::kTransparent) {
      for (uint32_t p = 0; p < draws.phases; ++p) {
        if (id == PassId::kForward) {
          add(group_sums[p][o]);
          add(group_sums[p][k]);
        } else {
          add(group_sums[p][b]);
        }
      }
    }
  }
  if (drawn_out) {
    std::sort(drawn.begin(), drawn.end());
    *drawn_out = std::move(drawn);
  }
}

void Renderer::Impl::WriteCpuLists(const GpuScene& scene, const DrawLists& lists,
                                       const Frustum* frustum) {
  const std::vector<DrawItem>& items = scene.draws();
  std::vector<uint8_t> visible(items.size(), 1);
  uint32_t in_frustum = 0;
  for (size_t i = 0; i < items.size(); ++i) {
    if (frustum) visible[i] = AabbIntersectsFrustum(items[i].world_bounds, *frustum) ? 1 : 0;
    in_frustum += visible[i];
  }
  auto* commands = static_cast<VkDrawIndexedIndirectCommand*>(draw_commands.mapped());
  auto* counts = static_cast<uint32_t*>(draw_counts.mapped());
  auto write = [&](bool batch, uint32_t first, uint32_t count, uint32_t count_index) {
    VkDrawIndexedIndirectCommand* out =
        commands + lists.CommandOffset(0, batch, first) / sizeof(VkDrawIndexedIndirectCommand);
    uint32_t n = 0;
    for (uint32_t i = first; i < first + count; ++i) {
      if (!visible[i]) continue;
      const DrawItem& d = items[i];
      out[n++] = {d.index_count, 1, d.first_index, d.vertex_offset, d.drawable};
    }
    counts[lists.CountOffset(0, count_index) / 4] = n;
  };
  const uint32_t segments = uint32_t(scene.segments().size());
  for (uint32_t s = 0; s < segments; ++s)
    write(false, scene.segments()[s].first_item, scene.segments()[s].item_count, s);
  for (uint32_t b = 0; b < scene.batches().size(); ++b)
    write(true, scene.batches()[b].first_item, scene.batches()[b].item_count, segments + b);
  uint32_t* stats = counts + lists.CountOffset(0, segments + uint32_t(scene.batches().size())) / 4;
  std::fill(stats, stats + gpu::kCullStatCount, 0u);
  stats[gpu::kCullStatInFrustum] = in_frustum;
}

absl::Status Renderer::Impl::EnsureRowBuffer(size_t entries) {
  if (entries <= row_capacity) return absl::OkStatus();
  const uint32_t cap = uint32_t(std::max<size_t>(entries, size_t(row_capacity) * 2));
  if (absl::Status s = MakeBuffer(*ctx, VkDeviceSize(cap) * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                  vk::MemoryUsage::kUpload, "row_lights", &row_lights);
      !s.ok())
    return s;
  row_capacity = cap;
  return absl::OkStatus();
}

absl::Status Renderer::Impl::EnsureLightBuffers(uint32_t lights, uint32_t tiles) {
  lights = std::max(lights, 1u);
  tiles = std::max(tiles, 1u);
  if (lights > light_capacity) {
    const uint32_t cap = std::max(lights, light_capacity * 2);
    if (absl::Status s = MakeBuffer(*ctx, VkDeviceSize(cap) * sizeof(gpu::GpuLight),
                                    VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUsage::kUpload,
                                    "local_lights", &local_lights);
        !s.ok())
      return s;
    if (absl::Status s = MakeBuffer(*ctx, VkDeviceSize(cap) * sizeof(gpu::GpuLightBounds),
                                    VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUsage::kUpload,
                                    "light_bounds", &light_bounds);
        !s.ok())
      return s;
    light_capacity = cap;
  }
  if (tiles > tile_capacity) {
    if (absl::Status s =
            MakeBuffer(*ctx, VkDeviceSize(tiles) * 4,
                       VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                       vk::MemoryUsage::kDeviceLocal, "tile_counts", &tile_counts);
        !s.ok())
      return s;
    if (absl::Status s =
            MakeBuffer(*ctx, VkDeviceSize(tiles) * gpu::kMaxLightsPerTile * 4,
                       VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                       vk::MemoryUsage::kDeviceLocal, "tile_lights", &tile_lights);
        !s.ok())
      return s;
    if (absl::Status s =
            MakeBuffer(*ctx, VkDeviceSize(tiles) * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                       vk::MemoryUsage::kReadback, "tile_counts_readback", &tile_counts_readback);
        !s.ok())
      return s;
    tile_capacity = tiles;
  }
  return absl::OkStatus();
}

absl::Status Renderer::Impl::EnsureTargets(uint32_t width, uint32_t height) {
  if (targets.width == width && targets.height == height) return absl::OkStatus();
  vkDeviceWaitIdle(ctx->device());
  DestroyHizViews();
  targets = FrameTargets{};
  FrameTargets t;
  t.width = width;
  t.height = height;
  vk::ImageDesc desc;
  desc.width = width;
  desc.height = height;
  desc.format = kDepthFormat;
  // Sampled by the light-culling pass; copied out for tests (FrameCapture).
  desc.usage = VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT |
               VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
  absl::StatusOr<vk::Image> depth = vk::Image::Create(*ctx, desc, "depth");
  if (!depth.ok()) return depth.status();
  desc.format = kHdrFormat;
  desc.usage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT |
               VK_IMAGE_USAGE_TRANSFER_SRC_BIT;  // FrameCapture::hdr
  absl::StatusOr<vk::Image> hdr = vk::Image::Create(*ctx, desc, "hdr_color");
  if (!hdr.ok()) return hdr.status();
  desc.format = kLdrFormat;
  desc.usage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT |
               VK_IMAGE_USAGE_SAMPLED_BIT;  // fxaa reads it
  absl::StatusOr<vk::Image> ldr = vk::Image::Create(*ctx, desc, "ldr_color");
  if (!ldr.ok()) return ldr.status();
  absl::StatusOr<vk::Buffer> readback =
      vk::Buffer::Create(*ctx, uint64_t(width) * height * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                         vk::MemoryUsage::kReadback, "readback");
  if (!readback.ok()) return readback.status();
  // The depth pyramid: a power of two at or below half the frame size, down to 1x1.
  t.hiz_width = std::max(1u, std::bit_floor(width) / kHizLevel0Divisor);
  t.hiz_height = std::max(1u, std::bit_floor(height) / kHizLevel0Divisor);
  desc.width = t.hiz_width;
  desc.height = t.hiz_height;
  desc.format = kHizFormat;
  desc.mip_levels = uint32_t(std::bit_width(std::max(t.hiz_width, t.hiz_height)));
  desc.usage = VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_SAMPLED_BIT;
  absl::StatusOr<vk::Image> hiz = vk::Image::Create(*ctx, desc, "hiz");
  if (!hiz.ok()) return hiz.status();
  if (absl::Status st = CreateLevelViews(ctx->device(), *hiz, "hiz", t.hiz_levels); !st.ok())
    return st;
  t.hiz = std::move(*hiz);
  t.depth = std::move(*depth);
  t.hdr = std::move(*hdr);
  t.ldr = std::move(*ldr);
  t.readback = std::move(*readback);
  targets = std::move(t);
  return absl::OkStatus();
}

absl::Status Renderer::Impl::EnsureAaTargets(const Settings& s) {
  auto make = [&](vk::Image& image, VkFormat format, uint32_t samples, VkImageUsageFlags usage,
                  const char* name) -> absl::Status {
    if (image && image.desc().samples == static_cast<VkSampleCountFlagBits>(samples))
      return absl::OkStatus();
    vkDeviceWaitIdle(ctx->device());
    vk::ImageDesc desc;
    desc.width = targets.width;
    desc.height = targets.height;
    desc.format = format;
    desc.samples = static_cast<VkSampleCountFlagBits>(samples);
    desc.usage = usage;
    absl::StatusOr<vk::Image> img = vk::Image::Create(*ctx, desc, name);
    if (!img.ok()) return img.status();
    image = std::move(*img);
    return absl::OkStatus();
  };
  constexpr VkImageUsageFlags kColor = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT;
  constexpr VkImageUsageFlags kSampled = VK_IMAGE_USAGE_SAMPLED_BIT;
  constexpr VkImageUsageFlags kDepth = VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT;
  constexpr VkImageUsageFlags kCopy = VK_IMAGE_USAGE_TRANSFER_SRC_BIT;  // FrameCapture::hdr
  const uint32_t n = s.samples;
  absl::Status st;
  switch (s.aa) {
    case AaMode::kMsaa:
      if (st.ok()) st = make(targets.depth_ms, kDepthFormat, n, kDepth, "depth_ms");
      if (st.ok()) st = make(targets.hdr_ms, kHdrFormat, n, kColor, "hdr_ms");
      break;
    case AaMode::kVisMlaa:
      if (st.ok()) st = make(targets.depth_ms, kDepthFormat, n, kDepth, "depth_ms");
      if (st.ok()) st = make(targets.vis_ms, kIdFormat, n, kColor | kSampled, "visibility");
      if (st.ok()) st = make(targets.vis_id, kIdFormat, 1, kColor | kSampled, "vis_id");
      if (st.ok())
        st = make(targets.vis_coverage, kIdFormat, 1, kColor | kSampled, "vis_coverage");
      if (st.ok())
        st = make(targets.material_depth, kMaterialDepthFormat, 1, kDepth, "material_depth");
      if (st.ok()) st = make(targets.post_hdr, kHdrFormat, 1, kColor | kSampled | kCopy, "post_hdr");
      break;
    case AaMode::kTaa:
      st = make(targets.post_hdr, kHdrFormat, 1, kColor | kSampled | kCopy, "post_hdr");
      break;
    case AaMode::kFxaa:
      st = make(targets.fxaa, kLdrFormat, 1, kColor | VK_IMAGE_USAGE_TRANSFER_SRC_BIT, "fxaa");
      break;
    case AaMode::kNone:
      break;
  }
  targets.samples = (s.aa == AaMode::kMsaa || s.aa == AaMode::kVisMlaa) ? n : 1;
  return st;
}

absl::StatusOr<Renderer::Impl::TaaHistory*> Renderer::Impl::Taa(const GpuScene& scene,
                                                                uint64_t view) {
  constexpr size_t kMaxTaaViews = 8;
  const std::pair<uint64_t, uint64_t> key{scene.serial(), view};
  auto it = taa_history.find(key);
  if (it != taa_history.end() && it->second.images[0].desc().width == targets.width &&
      it->second.images[0].desc().height == targets.height) {
    it->second.last_used = ++frame_counter;
    return &it->second;
  }
  if (it != taa_history.end()) {
    taa_history.erase(it);
  } else if (taa_history.size() >= kMaxTaaViews) {
    DropLeastRecentlyUsed(taa_history);
  }
  TaaHistory h;
  for (vk::Image& image : h.images) {
    vk::ImageDesc desc;
    desc.width = targets.width;
    desc.height = targets.height;
    desc.format = kHdrFormat;
    desc.usage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT;
    absl::StatusOr<vk::Image> img = vk::Image::Create(*ctx, desc, "taa_history");
    if (!img.ok()) return img.status();
    image = std::move(*img);
  }
  h.last_used = ++frame_counter;
  return &taa_history.emplace(key, std::move(h)).first->second;
}

void Renderer::Impl::BeginOneTime() {
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  VK_CHECK(vkResetCommandBuffer(cmd, 0));
  VK_CHECK(vkBeginCommandBuffer(cmd, &bi));
}

absl::Status Renderer::Impl::EndCopiesAndWait() {
  vk::CmdMemoryBarrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                       VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_READ_BIT);
  VK_CHECK(vkEndCommandBuffer(cmd));
  VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cmd;
  VK_RETURN_IF_ERROR(vkQueueSubmit(ctx->queue(), 1, &si, fence), "vkQueueSubmit");
  VK_RETURN_IF_ERROR(vkWaitForFences(ctx->device(), 1, &fence, VK_TRUE, UINT64_MAX), "fence");
  VK_CHECK(vkResetFences(ctx->device(), 1, &fence));
  return absl::OkStatus();
}

// After a frame (tests): draws every drawable, unculled, into an id target against the
// frame's depth, so the ids on top are the truly visible drawables.
absl::Status Renderer::Impl::CaptureIds(const GpuScene& scene, VkDescriptorSet scene_set,
                                        FrameCapture* capture) {
  if (!id_pipeline.handle()) {
    absl::StatusOr<vk::Pipeline> p = CreateIdPipeline(*ctx, scene_layout);
    if (!p.ok()) return p.status();
    id_pipeline = std::move(*p);
  }
  vk::ImageDesc desc;
  desc.width = targets.width;
  desc.height = targets.height;
  desc.format = kIdFormat;
  desc.usage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
  absl::StatusOr<vk::Image> ids = vk::Image::Create(*ctx, desc, "drawable_ids");
  if (!ids.ok()) return ids.status();
  const VkDeviceSize bytes = VkDeviceSize(targets.width) * targets.height * 4;
  absl::StatusOr<vk::Buffer> host = vk::Buffer::Create(
      *ctx, bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryUsage::kReadback, "ids_readback");
  if (!host.ok()) return host.status();
  BeginOneTime();
  const AccessInfo color = ToVulkan(Access::kColorWrite), src = ToVulkan(Access::kTransferSrc);
  const AccessInfo depth_test = ToVulkan(Access::kDepthTest);
  VkImageMemoryBarrier2 to_color = vk::MakeImageBarrier(
      *ids, {VK_PIPELINE_STAGE_2_NONE, VK_ACCESS_2_NONE, VK_IMAGE_LAYOUT_UNDEFINED, color.stage,
             color.access, color.layout});
  VkImageMemoryBarrier2 depth_ready = vk::MakeImageBarrier(
      targets.depth, {depth_test.stage, depth_test.access, depth_test.layout, depth_test.stage,
                      depth_test.access, depth_test.layout});
  VkImageMemoryBarrier2 before[] = {to_color, depth_ready};
  vk::CmdBarrier(cmd, before, 2);
  VkRenderingAttachmentInfo c{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
  c.imageView = ids->view();
  c.imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
  c.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
  c.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
  c.clearValue.color.uint32[0] = 0;
  VkRenderingAttachmentInfo d{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
  d.imageView = targets.depth.view();
  d.imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
  d.loadOp = VK_ATTACHMENT_LOAD_OP_LOAD;
  d.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
  PassStats unused;
  PassContext pc;
  pc.cmd = cmd;
  pc.targets = &targets;
  pc.scene = &scene;
  pc.scene_pipeline_layout = scene_layout.pipeline_layout;
  pc.scene_set = scene_set;
  pc.stats = &unused;
  BeginRendering(pc, &c, &d);
  BeginSceneDraw(pc, id_pipeline.handle());
  RecordAllDirect(pc);
  vkCmdEndRendering(cmd);
  VkImageMemoryBarrier2 to_src = vk::MakeImageBarrier(
      *ids, {color.stage, color.access, color.layout, src.stage, src.access, src.layout});
  vk::CmdBarrier(cmd, &to_src, 1);
  VkBufferImageCopy region{};
  region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  region.imageExtent = {targets.width, targets.height, 1};
  vkCmdCopyImageToBuffer(cmd, ids->handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, host->handle(),
                         1, &region);
  if (absl::Status st = EndCopiesAndWait(); !st.ok()) return st;
  host->InvalidateForRead();
  const auto* p = static_cast<const uint32_t*>(host->mapped());
  capture->ids.assign(p, p + size_t(targets.width) * targets.height);
  return absl::OkStatus();
}

// After a frame: copies the prepass depth and the tile lists to the host (tests only).
absl::Status Renderer::Impl::Capture(FrameCapture* capture, uint32_t tiles, const vk::Image& hdr,
                                     const vk::Image* exposure) {
  const VkDeviceSize depth_bytes = VkDeviceSize(targets.width) * targets.height * 4;
  const VkDeviceSize count_bytes = VkDeviceSize(tiles) * 4;
  const VkDeviceSize list_bytes = count_bytes * gpu::kMaxLightsPerTile;
  const VkDeviceSize hdr_bytes = depth_bytes * 2;  // RGBA16F
  // RGBA16F copies want offsets in whole texels: 16-byte aligned.
  const VkDeviceSize hdr_at = (depth_bytes + count_bytes + list_bytes + 15) & ~VkDeviceSize(15);
  const VkDeviceSize exposure_at = hdr_at + hdr_bytes;
  absl::StatusOr<vk::Buffer> host =
      vk::Buffer::Create(*ctx, exposure_at + 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                         vk::MemoryUsage::kReadback, "capture");
  if (!host.ok()) return host.status();
  BeginOneTime();
  const AccessInfo from = ToVulkan(Access::kDepthTest), to = ToVulkan(Access::kTransferSrc);
  const AccessInfo sampled = ToVulkan(Access::kSampled);
  VkImageMemoryBarrier2 b[2] = {
      vk::MakeImageBarrier(targets.depth,
                           {from.stage, from.access, from.layout, to.stage, to.access, to.layout}),
      vk::MakeImageBarrier(hdr, {sampled.stage, sampled.access, sampled.layout, to.stage,
                                 to.access, to.layout})};
  VkMemoryBarrier2 mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER_2};
  mb.srcStageMask = VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT;
  mb.srcAccessMask = VK_ACCESS_2_MEMORY_WRITE_BIT;
  mb.dstStageMask = VK_PIPELINE_STAGE_2_COPY_BIT;
  mb.dstAccessMask = VK_ACCESS_2_TRANSFER_READ_BIT;
  VkDependencyInfo dep{VK_STRUCTURE_TYPE_DEPENDENCY_INFO};
  dep.memoryBarrierCount = 1;
  dep.pMemoryBarriers = &mb;
  dep.imageMemoryBarrierCount = 2;
  dep.pImageMemoryBarriers = b;
  vkCmdPipelineBarrier2(cmd, &dep);
  VkBufferImageCopy region{};
  region.imageSubresource = {VK_IMAGE_ASPECT_DEPTH_BIT, 0, 0, 1};
  region.imageExtent = {targets.width, targets.height, 1};
  vkCmdCopyImageToBuffer(cmd, targets.depth.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                         host->handle(), 1, &region);
  region.bufferOffset = hdr_at;
  region.imageSubresource.aspectMask = VK_IMAGE_ASPECT_COLOR_BIT;
  vkCmdCopyImageToBuffer(cmd, hdr.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, host->handle(),
                         1, &region);
  if (exposure) {  // from the general layout and back
    VkImageMemoryBarrier2 eb = vk::MakeImageBarrier(
        *exposure, {VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, VK_ACCESS_2_MEMORY_WRITE_BIT,
                    VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_2_COPY_BIT,
                    VK_ACCESS_2_TRANSFER_READ_BIT, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL});
    vk::CmdBarrier(cmd, &eb, 1);
    region.bufferOffset = exposure_at;
    region.imageExtent = {1, 1, 1};
    vkCmdCopyImageToBuffer(cmd, exposure->handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                           host->handle(), 1, &region);
    eb = vk::MakeImageBarrier(
        *exposure, {VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_NONE,
                    VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                    VK_ACCESS_2_NONE, VK_IMAGE_LAYOUT_GENERAL});
    vk::CmdBarrier(cmd, &eb, 1);
  }
  if (tiles > 0) {  // the lists exist only when the light-culling pass ran
    const VkBufferCopy counts{0, depth_bytes, count_bytes};
    vkCmdCopyBuffer(cmd, tile_counts.handle(), host->handle(), 1, &counts);
    const VkBufferCopy lists{0, depth_bytes + count_bytes, list_bytes};
    vkCmdCopyBuffer(cmd, tile_lights.handle(), host->handle(), 1, &lists);
  }
  if (absl::Status st = EndCopiesAndWait(); !st.ok()) return st;
  host->InvalidateForRead();
  const auto* bytes = static_cast<const uint8_t*>(host->mapped());
  capture->depth.resize(size_t(targets.width) * targets.height);
  std::memcpy(capture->depth.data(), bytes, depth_bytes);
  capture->tile_counts.resize(tiles);
  std::memcpy(capture->tile_counts.data(), bytes + depth_bytes, count_bytes);
  capture->tile_lights.resize(size_t(tiles) * gpu::kMaxLightsPerTile);
  std::memcpy(capture->tile_lights.data(), bytes + depth_bytes + count_bytes, list_bytes);
  capture->hdr.resize(size_t(targets.width) * targets.height * 4);
  const auto* halves = reinterpret_cast<const uint16_t*>(bytes + hdr_at);
  for (size_t i = 0; i < capture->hdr.size(); ++i) capture->hdr[i] = glm::unpackHalf1x16(halves[i]);
  capture->exposure_log2 = std::numeric_limits<float>::quiet_NaN();
  if (exposure) std::memcpy(&capture->exposure_log2, bytes + exposure_at, 4);
  return absl::OkStatus();
}

absl::StatusOr<bool> Renderer::Impl::EnsureIbl(const SkyParams& sky) {
  if (!ibl) {
    absl::StatusOr<std::unique_ptr<IblMaps>> maps = IblMaps::Create(*ctx);
    if (!maps.ok()) return maps.status();
    ibl = std::move(*maps);
  }
  const uint64_t hash = HashBytes(&sky, sizeof(sky));
  if (ibl->baked() && hash == ibl_sky_hash) return false;
  vkDeviceWaitIdle(ctx->device());  // earlier frames may still sample the maps
  BeginOneTime();
  ibl->RecordBake(cmd, sky);
  if (absl::Status st = EndCopiesAndWait(); !st.ok()) {
    ibl.reset();  // what it holds is unknown: made and baked afresh next time
    return st;
  }
  ibl_sky_hash = hash;
  return true;
}

VkDescriptorSet Renderer::Impl::WriteSceneSet(const GpuScene& scene, bool shadows, bool ssao,
                                              bool with_ibl) {
  VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  ai.descriptorPool = frame_pool;
  ai.descriptorSetCount = 1;
  ai.pSetLayouts = &scene_layout.set_layout;
  VkDescriptorSet set;
  VK_CHECK(vkAllocateDescriptorSets(ctx->device(), &ai, &set));
  const VkDescriptorBufferInfo buffers[] = {
      {frame_ubo.handle(), 0, VK_WHOLE_SIZE},
      {lights_ubo.handle(), 0, VK_WHOLE_SIZE},
      {scene.drawables().handle(), 0, VK_WHOLE_SIZE},
      {scene.materials().handle(), 0, VK_WHOLE_SIZE},
      {local_lights.handle(), 0, VK_WHOLE_SIZE},
      {tile_counts.handle(), 0, VK_WHOLE_SIZE},
      {tile_lights.handle(), 0, VK_WHOLE_SIZE},
  };
  const VkDescriptorType types[] = {
      VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER,
      VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
      VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
      VK_DESCRIPTOR_TYPE_STORAGE_BUFFER};
  std::vector<VkWriteDescriptorSet> writes;
  for (uint32_t i = 0; i < 7; ++i) {
    VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    w.dstSet = set;
    w.dstBinding = i;
    w.descriptorCount = 1;
    w.descriptorType = types[i];
    w.pBufferInfo = &buffers[i];
    writes.push_back(w);
  }
  const VkDescriptorBufferInfo shadow_info{shadow_ubo.handle(), 0, VK_WHOLE_SIZE};
  const vk::Image& atlas = shadows && shadow_atlas ? shadow_atlas : shadow_placeholder;
  const VkDescriptorImageInfo images[] = {
      {shadow_sampler.handle(), atlas.view(), VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL},
      {linear_sampler.handle(), (ssao ? targets.ao : ao_placeholder).view(),
       VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL}};
  VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
  w.dstSet = set;
  w.descriptorCount = 1;
  w.dstBinding = gpu::kBindingShadows;
  w.descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
  w.pBufferInfo = &shadow_info;
  writes.push_back(w);
  w.pBufferInfo = nullptr;
  w.descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
  w.dstBinding = gpu::kBindingShadowAtlas;
  w.pImageInfo = &images[0];
  writes.push_back(w);
  w.dstBinding = gpu::kBindingAo;
  w.pImageInfo = &images[1];
  writes.push_back(w);
  const bool on = with_ibl && ibl;
  const VkSampler ibl_sampler = on ? ibl->sampler() : linear_sampler.handle();
  const VkDescriptorImageInfo ibl_images[] = {
      {ibl_sampler, (on ? ibl->irradiance() : cube_placeholder).view(),
       VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL},
      {ibl_sampler, (on ? ibl->specular() : cube_placeholder).view(),
       VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL},
      {ibl_sampler, (on ? ibl->brdf_lut() : ao_placeholder).view(),
       VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL},
      {ibl_sampler, (on ? ibl->environment() : cube_placeholder).view(),
       VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL}};
  const uint32_t ibl_bindings[] = {gpu::kBindingIrradiance, gpu::kBindingSpecular,
                                   gpu::kBindingBrdfLut, gpu::kBindingEnvironment};
  for (int i = 0; i < 4; ++i) {
    w.dstBinding = ibl_bindings[i];
    w.pImageInfo = &ibl_images[i];
    writes.push_back(w);
  }
  vkUpdateDescriptorSets(ctx->device(), static_cast<uint32_t>(writes.size()), writes.data(), 0,
                         nullptr);
  return set;
}

Renderer::Renderer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Renderer::~Renderer() = default;

absl::StatusOr<std::unique_ptr<Renderer>> Renderer::Create(const RendererOptions& options) {
  auto impl = std::make_unique<Impl>();
  absl::StatusOr<std::unique_ptr<vk::Context>> ctx =
      vk::Context::Create({options.device_name, options.validation});
  if (!ctx.ok()) return ctx.status();
  impl->ctx = std::move(*ctx);
  if (absl::Status st = impl->Init(); !st.ok()) return st;
  return std::unique_ptr<Renderer>(new Renderer(std::move(impl)));
}

const DeviceInfo& Renderer::device_info() const { return impl_->ctx->info(); }

DeviceCaps Renderer::caps() const {
  const DeviceInfo& info = impl_->ctx->info();
  return {info.max_samples, info.max_image_dimension, info.sample_counts,
          info.visibility_buffer};
}

absl::StatusOr<SceneHandle> Renderer::LoadScene(const GltfSource& source) {
  absl::StatusOr<CpuScene> cpu = ImportGltf(source);
  if (!cpu.ok()) return cpu.status();
  return LoadScene(*cpu);
}

absl::StatusOr<SceneHandle> Renderer::LoadScene(const CpuScene& cpu) {
  std::lock_guard lock(impl_->mutex);
  absl::StatusOr<std::unique_ptr<GpuScene>> gpu =
      GpuScene::Upload(*impl_->ctx, cpu, impl_->scene_layout.material_set_layout);
  if (!gpu.ok()) return gpu.status();
  std::shared_ptr<Scene> scene(new Scene());
  scene->info_ = {cpu.name,    cpu.counts,   cpu.bounds,
                  cpu.cameras, cpu.warnings, (*gpu)->device_bytes()};
  scene->device_ = impl_->ctx;
  scene->gpu_ = std::move(*gpu);
  return SceneHandle(std::move(scene));
}

uint64_t Renderer::EstimateDeviceBytes(const CpuScene& scene) const {
  const vk::Context& ctx = *impl_->ctx;
  return tessera::EstimateDeviceBytes(
      scene, std::min<uint32_t>(kMaxTextureSide, ctx.info().max_image_dimension),
      ctx.limits().minUniformBufferOffsetAlignment);
}

uint64_t Renderer::DeviceMemoryBytes() { return vk::AllocatedDeviceBytes(); }

void Renderer::ForgetView(const Scene& scene, uint64_t view) {
  std::lock_guard lock(impl_->mutex);
  // Frames are synchronous (each Render waits for its fence), so nothing in flight uses them.
  impl_->taa_history.erase({scene.gpu_->serial(), view});
  impl_->exposure_state.erase({scene.gpu_->serial(), view});
  scene.gpu_->views().erase(view);
}

absl::StatusOr<Frame> Renderer::Render(const Scene& scene, const Camera& camera,
                                       const Settings& settings) {
  return Render(scene, camera, settings, nullptr);
}

absl::StatusOr<Frame> Renderer::Render(const Scene& scene, const Camera& camera,
                                       const Settings& settings, FrameCapture* capture) {
  return Render(scene, camera, settings, 0, capture);
}

absl::StatusOr<Frame> Renderer::Render(const Scene& scene, const Camera& camera,
                                       const Settings& settings, uint64_t view,
                                       FrameCapture* capture) {
  absl::StatusOr<ResolvedSettings> resolved = ResolveSettings(settings, caps());
  if (!resolved.ok()) return resolved.status();
  if (absl::Status st = ValidateCamera(camera); !st.ok()) return st;

  std::lock_guard lock(impl_->mutex);
  Impl& m = *impl_;
  const GpuScene& gs = *scene.gpu_;
  Frame frame;
  frame.settings = std::move(*resolved);
  const Settings& s = frame.settings.effective;
  if (absl::Status st = m.EnsureTargets(s.width, s.height); !st.ok()) return st;
  // vis_mlaa: a visibility id holds the drawable and the triangle; a scene whose largest
  // drawable has more triangles than the id leaves room for is drawn with msaa instead.
  const uint32_t triangle_bits = VisTriangleBits(uint32_t(gs.draws().size()));
  if (s.aa == AaMode::kVisMlaa) {
    const uint32_t most = gs.max_draw_triangles();
    if (most > (uint64_t(1) << triangle_bits)) {
      frame.settings.notes.push_back(
          {"aa", absl::StrCat("not applied: vis_mlaa ids hold ", triangle_bits,
                              " bits of triangle with ", gs.draws().size(),
                              " drawables, and a drawable has ", most,
                              " triangles; rendered with msaa")});
      frame.settings.effective.aa = AaMode::kMsaa;
      if (s.debug_view == DebugView::kAaMask) {
        frame.settings.notes.push_back({"debug_view", "not applied: aa_mask needs vis_mlaa"});
        frame.settings.effective.debug_view = DebugView::kNone;
      }
    }
  }
  if (absl::Status st = m.EnsureAaTargets(s); !st.ok()) return st;

  auto t_record = Clock::now();
  // Uniforms.
  const float aspect = float(s.width) / float(s.height);
  gpu::FrameUniforms fu{};
  fu.view = ViewMatrix(camera);
  fu.proj = ProjectionMatrix(camera, aspect);
  const glm::mat4 unjittered_view_proj = fu.proj * fu.view;
  // taa: this view's history, and this frame's jitter of the projection (sub-pixel).
  TaaFrame taa;
  if (s.aa == AaMode::kTaa) {
    absl::StatusOr<Impl::TaaHistory*> h = m.Taa(gs, view);
    if (!h.ok()) return h.status();
    Impl::TaaHistory& history = **h;
    const bool valid = history.written[history.current];
    const bool still = valid && history.view_proj == unjittered_view_proj;
    // A still camera averages every frame so far (converging on the jittered supersample); a
    // moving one keeps at least a tenth of each new frame.
    history.frames = !valid ? 0 : still ? std::min(history.frames + 1, 15u)
                                        : std::min(history.frames, 9u);
    taa.current_weight = 1.0f / float(history.frames + 1);
    taa.history_valid = valid;
    taa.reproject = history.view_proj * glm::inverse(unjittered_view_proj);
    taa.history_read = &history.images[history.current];
    taa.history_write = &history.images[history.current ^ 1];
    const glm::vec2 jitter = TaaJitter(history.jitter_index++);
    fu.proj[2][0] += 2.0f * jitter.x / float(s.width);
    fu.proj[2][1] += 2.0f * jitter.y / float(s.height);
    history.current ^= 1;
    history.written[history.current] = true;
    history.view_proj = unjittered_view_proj;
  }
  fu.view_proj = fu.proj * fu.view;
  fu.inv_view_proj = glm::inverse(fu.view_proj);
  fu.camera_position = glm::vec4(CameraPosition(camera), 1.0f);
  fu.ambient_sky = glm::vec4(0.40f, 0.52f, 0.75f, s.ibl ? 1.0f : 0.0f);
  fu.ambient_ground = glm::vec4(0.24f, 0.21f, 0.18f, 0.0f);
  // Lights: directional ones are global (uniform buffer); point and spot lights, the scene's and
  // the synthetic ones, are local and culled per tile. A scene without lights gets a sun.
  std::vector<Light> global, local;
  if (s.scene_lights) {
    // Point and spot lights without a range reach everywhere: they are global too.
    for (const Light& l : gs.lights())
      (l.type == LightType::kDirectional || l.range <= 0.0f ? global : local).push_back(l);
  }
  if (global.empty() && local.empty()) global.push_back(DefaultSun());
  if (global.size() > gpu::kMaxLights) {
    frame.settings.notes.push_back(
        {"scene_lights", absl::StrCat("only the first ", gpu::kMaxLights, " of ", global.size(),
                                      " directional or unbounded lights are shaded")});
    global.resize(gpu::kMaxLights);
  }
  if (s.synthetic_lights > 0) {
    std::vector<Light> synthetic = MakeSyntheticLights(
        scene.info().bounds, {s.synthetic_lights, s.light_seed, s.light_radius_min,
                              s.light_radius_max, s.lights_animated, s.light_time});
    local.insert(local.end(), synthetic.begin(), synthetic.end());
  }
  if (local.size() > gpu::kMaxLocalLights) {
    frame.settings.notes.push_back(
        {"synthetic_lights", absl::StrCat("only the first ", gpu::kMaxLocalLights, " of ",
                                          local.size(), " point and spot lights are shaded")});
    local.resize(gpu::kMaxLocalLights);
  }
  const TileGrid grid{s.width, s.height, s.tile_size};
  // Tile lists take tiles x 1 KiB; past 128 MiB (lavapipe's storage-buffer range) the frame
  // shades every light instead, and says so.
  constexpr uint64_t kMaxTileListBytes = 128ull << 20;
  bool tiled = s.light_culling && !local.empty();
  if (tiled && uint64_t(grid.tiles()) * gpu::kMaxLightsPerTile * 4 > kMaxTileListBytes) {
    frame.settings.notes.push_back(
        {"light_culling", absl::StrCat("not applied: ", grid.tiles(), " tiles of ", s.tile_size,
                                       " px need more than 128 MiB of light lists; every light "
                                       "is shaded at every pixel (use a larger tile_size)")});
    frame.settings.effective.light_culling = false;
    tiled = false;
  }
  if (absl::Status st = m.EnsureLightBuffers(uint32_t(local.size()), tiled ? grid.tiles() : 1);
      !st.ok())
    return st;
  auto* gl = static_cast<gpu::GpuLight*>(m.lights_ubo.mapped());
  for (size_t i = 0; i < global.size(); ++i) gl[i] = ToGpu(global[i]);
  auto* ll = static_cast<gpu::GpuLight*>(m.local_lights.mapped());
  for (size_t i = 0; i < local.size(); ++i) ll[i] = ToGpu(local[i]);
  // Shadows and ssao: what the shading passes read besides the lights.
  auto& su = *static_cast<gpu::ShadowUniforms*>(m.shadow_ubo.mapped());
  su.counts = glm::uvec4(0u);
  ShadowFrame shadow_frame;
  if (s.shadows) {
    if (absl::Status st = m.PrepareShadows(gs, camera, aspect, view, s, fu.proj * fu.view, global,
                                           local, gl, ll, frame, &shadow_frame);
        !st.ok())
      return st;
  }
  SsaoFrame ssao;
  {
    const uint32_t div = s.ssao_half_res ? 2 : 1;
    if (s.ssao) {
      if (absl::Status st =
              m.EnsureAo(std::max(1u, s.width / div), std::max(1u, s.height / div));
          !st.ok())
        return st;
      const Aabb& b = gs.bounds();
      const float diagonal = b.empty() ? 1.0f : glm::length(b.max - b.min);
      const float radius = s.ssao_radius > 0.0f ? s.ssao_radius : 0.015f * diagonal;
      ssao.proj = glm::vec4(fu.proj[0][0], fu.proj[1][1], fu.proj[2][2], fu.proj[3][2]);
      ssao.params = glm::vec4(radius, s.ssao_strength, 0.01f * radius, 0.0f);
      su.counts.w |= gpu::kSsaoOn;
    }
  }
  // IBL: the procedural sky with the first directional light's sun, baked when it changed.
  if (s.ibl) {
    glm::vec3 sun_dir(0.0f), sun_color(0.0f);
    for (const Light& l : global) {
      if (l.type != LightType::kDirectional) continue;
      sun_dir = -l.direction;
      // The glow's scale: the sun's colour at a quarter of its intensity, bounded so a
      // physically scaled sun (lux) does not flood the sky.
      sun_color = l.color * std::clamp(l.intensity * 0.25f, 0.0f, 1.0f);
      break;
    }
    absl::StatusOr<bool> baked = m.EnsureIbl(DefaultSky(sun_dir, sun_color));
    if (!baked.ok()) return baked.status();
    frame.stats.ibl_bakes = *baked ? 1 : 0;
  }
  // Exposure: fixed, or auto with this view's adapted state; bloom's chains.
  ExposureFrame exposure;
  exposure.params = glm::vec4(std::exp2(s.exposure_ev), 0.0f, kExposureKey, 0.0f);
  exposure.view = m.ao_placeholder.view();  // never read without auto exposure
  Impl::ExposureState* exposure_state = nullptr;
  if (s.exposure_mode == ExposureMode::kAuto) {
    absl::StatusOr<Impl::ExposureState*> e = m.Exposure(gs, view);
    if (!e.ok()) return e.status();
    exposure_state = *e;
    exposure.params.y = 1.0f;
    exposure.state = &exposure_state->image;
    exposure.state_valid = exposure_state->written;
    exposure.rate = kExposureAdaptRate;
    exposure.view = exposure_state->image.view();
    exposure.layout = VK_IMAGE_LAYOUT_GENERAL;
  }
  if (s.bloom) {
    if (absl::Status st = m.EnsureBloom(); !st.ok()) return st;
  }
  if (tiled) {  // what the light-culling pass reads: each light projected once, binned by row
    std::vector<gpu::GpuLightBounds> bounds(local.size());
    for (size_t i = 0; i < local.size(); ++i)
      bounds[i] = BoundLight(local[i], fu.view, fu.proj, camera.znear, grid);
    std::memcpy(m.light_bounds.mapped(), bounds.data(), bounds.size() * sizeof(bounds[0]));
    const std::vector<uint32_t> rows = BinLightsByRow(bounds, grid.tiles_y());
    if (absl::Status st = m.EnsureRowBuffer(rows.size()); !st.ok()) return st;
    std::memcpy(m.row_lights.mapped(), rows.data(), rows.size() * sizeof(uint32_t));
  }
  fu.counts =
      glm::uvec4(uint32_t(global.size()), static_cast<uint32_t>(s.debug_view), s.width, s.height);
  fu.params = glm::vec4(0.0f, camera.znear, camera.zfar, 0.0f);
  fu.lighting = glm::uvec4(uint32_t(local.size()), s.tile_size, grid.tiles_x(),
                           (tiled ? 1u : 0u) | (s.tile_depth_mask ? 2u : 0u));
  fu.depth_params = glm::vec4(fu.proj[2][2], fu.proj[3][2], float(grid.tiles_y()), 0.0f);
  const uint32_t frame_samples = m.targets.samples;
  fu.aa = glm::uvec4(triangle_bits, frame_samples, 0u, 0u);
  std::memcpy(m.frame_ubo.mapped(), &fu, sizeof(fu));
  frame.stats.lights = uint32_t(global.size() + local.size());
  frame.stats.local_lights = uint32_t(local.size());
  frame.stats.drawables = uint32_t(gs.draws().size());

  // Geometry culling: the draw lists of every segment and batch of the scene, written by the
  // CPU (none, cpu_frustum) or by the culling passes (gpu_frustum, gpu_occlusion).
  const uint32_t item_count = uint32_t(gs.draws().size());
  const uint32_t segment_count = uint32_t(gs.segments().size());
  const uint32_t list_count = segment_count + uint32_t(gs.batches().size());
  if (absl::Status st = m.EnsureCullBuffers(item_count, list_count); !st.ok()) return st;
  DrawLists draws;
  draws.commands = m.draw_commands.handle();
  draws.counts = m.draw_counts.handle();
  draws.items = std::max(item_count, 1u);
  draws.count_stride = list_count + gpu::kCullStatCount;
  draws.phases = s.culling == CullingMode::kGpuOcclusion ? 2 : 1;
  {  // Blended segments back to front (ties on the drawable, so frames are reproducible).
    std::vector<std::pair<float, uint32_t>> blend;
    for (uint32_t i = 0; i < segment_count; ++i) {
      const DrawSegment& seg = gs.segments()[i];
      if (seg.group != AlphaMode::kBlend) continue;
      const DrawItem& d = gs.draws()[seg.first_item];
      blend.emplace_back(-(fu.view * glm::vec4(d.world_bounds.center(), 1.0f)).z, i);
    }
    std::sort(blend.begin(), blend.end(), [&](const auto& a, const auto& b) {
      return a.first != b.first ? a.first > b.first
                                : gs.draws()[gs.segments()[a.second].first_item].drawable <
                                      gs.draws()[gs.segments()[b.second].first_item].drawable;
    });
    for (const auto& [depth, seg] : blend) draws.blend_order.push_back(seg);
  }
  const Frustum frustum = FrustumFromViewProj(fu.view_proj);
  const bool gpu_culling =
      s.culling == CullingMode::kGpuFrustum || s.culling == CullingMode::kGpuOcclusion;
  CullBuffers cull_buffers;
  cull_buffers.uniforms = m.cull_uniforms.handle();
  cull_buffers.uniform_stride = m.cull_uniform_stride;
  cull_buffers.bases = m.cull_bases.handle();
  cull_buffers.vis_prev = cull_buffers.vis_next = m.no_visibility.handle();
  GpuScene::ViewVisibility* visibility = nullptr;
  if (s.culling == CullingMode::kGpuOcclusion) {
    absl::StatusOr<GpuScene::ViewVisibility*> v = m.Visibility(gs, view);
    if (!v.ok()) return v.status();
    visibility = *v;
    cull_buffers.vis_prev = visibility->bits[visibility->prev].handle();
    cull_buffers.vis_next = visibility->bits[visibility->prev ^ 1].handle();
  }
  if (gpu_culling) {
    for (uint32_t phase = 0; phase < draws.phases; ++phase) {
      gpu::CullUniforms cu{};
      cu.view_proj = fu.view_proj;
      for (int i = 0; i < 6; ++i) cu.planes[i] = frustum[i];
      const uint32_t kind = s.culling == CullingMode::kGpuFrustum ? gpu::kCullPhaseFrustum
                            : phase == 0                         ? gpu::kCullPhaseEarly
                                                                 : gpu::kCullPhaseLate;
      cu.counts = glm::uvec4(item_count, segment_count, list_count - segment_count, kind);
      cu.offsets = glm::uvec4(2 * phase * draws.items, phase * draws.count_stride, 0u, 0u);
      cu.hiz = glm::uvec4(m.targets.hiz_width, m.targets.hiz_height,
                          uint32_t(m.targets.hiz_levels.size()), 0u);
      cu.frame = glm::uvec4(s.width, s.height, 0u, 0u);
      std::memcpy(static_cast<uint8_t*>(m.cull_uniforms.mapped()) + phase * m.cull_uniform_stride,
                  &cu, sizeof(cu));
    }
  } else {
    m.WriteCpuLists(gs, draws, s.culling == CullingMode::kCpuFrustum ? &frustum : nullptr);
  }
  const std::vector<PassId> pass_ids =
      SelectPasses(frame.settings.effective, {!draws.blend_order.empty(), uint32_t(local.size())});
  const std::vector<std::vector<Transition>> plan = PlanTransitions(pass_ids, s.aa, s.ssao, s.bloom);
  for (PassId id : pass_ids) {
    if (absl::Status st = m.passes[static_cast<size_t>(id)]->Prepare(*m.ctx, s); !st.ok())
      return st;
  }
  // vis_mlaa: per material, the pixels its drawables in the frustum can cover.
  VisFrame vis;
  vis.triangle_bits = triangle_bits;
  if (s.aa == AaMode::kVisMlaa)
    vis.materials = MaterialRects(gs, frustum, fu.view_proj, s.width, s.height);

  VK_CHECK(vkResetDescriptorPool(m.ctx->device(), m.frame_pool, 0));
  const VkDescriptorSet scene_set = m.WriteSceneSet(gs, s.shadows, s.ssao, s.ibl);
  // Lavapipe records a timestamp when its rasterizer threads reach it in their tiles, so a
  // pass rasterized in one batch reads ~0 ms and its work lands before the next pass's start
  // stamp (the frame total stays right). On CPU devices each pass is therefore submitted on its
  // own and timed by the wall clock, which is the device's clock there.
  const bool per_pass_submit = m.ctx->info().type == "cpu";
  frame.timing = per_pass_submit ? TimingSource::kPassWallClock : TimingSource::kGpuTimestamps;
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  VK_CHECK(vkResetCommandBuffer(m.cmd, 0));
  VK_CHECK(vkBeginCommandBuffer(m.cmd, &bi));
  vkCmdResetQueryPool(m.cmd, m.queries, 0, kMaxTimestamps);
  if (m.stat_queries)
    vkCmdResetQueryPool(m.cmd, m.stat_queries, 0, static_cast<uint32_t>(PassId::kCount));
  // Ends, submits and waits for what is recorded so far; returns the wall time of the wait.
  auto submit_and_wait = [&]() -> absl::StatusOr<double> {
    VK_CHECK(vkEndCommandBuffer(m.cmd));
    const auto t0 = Clock::now();
    VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    si.commandBufferCount = 1;
    si.pCommandBuffers = &m.cmd;
    VK_RETURN_IF_ERROR(vkQueueSubmit(m.ctx->queue(), 1, &si, m.fence), "vkQueueSubmit");
    VK_RETURN_IF_ERROR(vkWaitForFences(m.ctx->device(), 1, &m.fence, VK_TRUE, UINT64_MAX),
                       "vkWaitForFences");
    VK_CHECK(vkResetFences(m.ctx->device(), 1, &m.fence));
    return MsSince(t0);
  };

  PassStats pass_stats;
  PassContext pc;
  pc.cmd = m.cmd;
  pc.vk = m.ctx.get();
  pc.targets = &m.targets;
  pc.scene = &gs;
  pc.draws = &draws;
  pc.settings = &s;
  pc.scene_pipeline_layout = m.scene_layout.pipeline_layout;
  pc.scene_set = scene_set;
  pc.frame_pool = m.frame_pool;
  pc.stats = &pass_stats;
  LightCullBuffers light_buffers;
  light_buffers.frame_ubo = m.frame_ubo.handle();
  light_buffers.bounds = m.light_bounds.handle();
  light_buffers.tile_counts = m.tile_counts.handle();
  light_buffers.tile_lights = m.tile_lights.handle();
  light_buffers.counts_readback = m.tile_counts_readback.handle();
  light_buffers.row_lights = m.row_lights.handle();
  light_buffers.tiles = grid.tiles();
  pc.light_buffers = &light_buffers;
  pc.cull = &cull_buffers;
  pc.vis = &vis;
  pc.taa = &taa;
  pc.shadows = &shadow_frame;
  pc.shadow_atlas_view = s.shadows ? &m.shadow_atlas : &m.shadow_placeholder;
  pc.ao_view = s.ssao ? &m.targets.ao : &m.ao_placeholder;
  pc.ssao = &ssao;
  pc.exposure = &exposure;
  pc.samples = frame_samples;
  std::vector<double> pass_wall_ms;
  double record_ms = 0.0;
  auto t_chunk = t_record;
  for (size_t i = 0; i < pass_ids.size(); ++i) {
    std::vector<VkImageMemoryBarrier2> barriers;
    for (const Transition& t : plan[i]) {
      const AccessInfo from = ToVulkan(t.from), to = ToVulkan(t.to);
      barriers.push_back(vk::MakeImageBarrier(
          m.targets.Get(t.resource),
          {from.stage, from.access, from.layout, to.stage, to.access, to.layout}));
    }
    vk::CmdBarrier(m.cmd, barriers.data(), uint32_t(barriers.size()));
    vkCmdWriteTimestamp2(m.cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, m.queries, uint32_t(2 * i));
    const bool stats_query = m.stat_queries && IsGeometryPass(pass_ids[i]);
    if (stats_query) vkCmdBeginQuery(m.cmd, m.stat_queries, uint32_t(pass_ids[i]), 0);
    m.passes[static_cast<size_t>(pass_ids[i])]->Record(pc);
    if (stats_query) vkCmdEndQuery(m.cmd, m.stat_queries, uint32_t(pass_ids[i]));
    vkCmdWriteTimestamp2(m.cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, m.queries,
                         uint32_t(2 * i + 1));
    if (per_pass_submit && i + 1 < pass_ids.size()) {
      record_ms += MsSince(t_chunk);
      absl::StatusOr<double> wall = submit_and_wait();
      if (!wall.ok()) return wall.status();
      pass_wall_ms.push_back(*wall);
      t_chunk = Clock::now();
      VK_CHECK(vkResetCommandBuffer(m.cmd, 0));
      VK_CHECK(vkBeginCommandBuffer(m.cmd, &bi));
    }
  }
  record_ms += MsSince(t_chunk);
  absl::StatusOr<double> wall = submit_and_wait();
  if (!wall.ok()) return wall.status();
  pass_wall_ms.push_back(*wall);
  frame.cpu.record_ms = record_ms;
  frame.cpu.submit_wait_ms = 0.0;
  for (double w : pass_wall_ms) frame.cpu.submit_wait_ms += w;

  std::vector<uint64_t> stamps(2 * pass_ids.size());
  VK_RETURN_IF_ERROR(
      vkGetQueryPoolResults(m.ctx->device(), m.queries, 0, uint32_t(stamps.size()),
                            stamps.size() * sizeof(uint64_t), stamps.data(), sizeof(uint64_t),
                            VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT),
      "timestamps");
  const uint32_t bits = m.ctx->info().timestamp_valid_bits;
  const uint64_t mask = bits >= 64 ? ~0ull : ((1ull << bits) - 1);
  const double ns = m.ctx->info().timestamp_period_ns;
  auto stamp_ms = [&](size_t a, size_t b) {
    return double((stamps[b] - stamps[a]) & mask) * ns * 1e-6;
  };
  for (size_t i = 0; i < pass_ids.size(); ++i) {
    frame.passes.push_back({std::string(PassName(pass_ids[i])),
                            per_pass_submit ? pass_wall_ms[i] : stamp_ms(2 * i, 2 * i + 1),
                            stamp_ms(2 * i, 2 * i + 1)});
  }
  frame.gpu_total_ms = per_pass_submit ? frame.cpu.submit_wait_ms : stamp_ms(0, stamps.size() - 1);
  if (visibility) visibility->prev ^= 1;  // this frame's bits are the next frame's history
  if (s.shadows) m.shadow_atlas_written = true;  // the faces listed were rendered
  if (exposure_state && std::find(pass_ids.begin(), pass_ids.end(), PassId::kExposure) !=
                            pass_ids.end())
    exposure_state->written = true;

  m.CountDrawn(gs, draws, pass_ids, frame.stats, capture ? &capture->drawn : nullptr);
  frame.stats.indirect_draws = pass_stats.indirect_draws;
  if (m.stat_queries) {
    frame.stats.pipeline_statistics = true;
    for (PassId id : pass_ids) {
      if (!IsGeometryPass(id)) continue;
      uint64_t values[3] = {};
      VK_RETURN_IF_ERROR(vkGetQueryPoolResults(m.ctx->device(), m.stat_queries, uint32_t(id), 1,
                                               sizeof(values), values, sizeof(values),
                                               VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT),
                         "pipeline statistics");
      frame.stats.primitives_in += values[0];
      frame.stats.primitives_clipped += values[1];
      frame.stats.fragment_invocations += values[2];
    }
  }
  if (tiled) {
    m.tile_counts_readback.InvalidateForRead();
    const auto* counts = static_cast<const uint32_t*>(m.tile_counts_readback.mapped());
    const TileStats ts = ComputeTileStats(std::vector<uint32_t>(counts, counts + grid.tiles()));
    frame.stats.tile_lights_avg = ts.average;
    frame.stats.tile_lights_p50 = ts.p50;
    frame.stats.tile_lights_p95 = ts.p95;
    frame.stats.tile_lights_max = ts.max;
    frame.stats.tile_overflows = ts.overflows;
  }
  if (capture) {
    if (capture->want_ids) {
      if (absl::Status st = m.CaptureIds(gs, scene_set, capture); !st.ok()) return st;
    }
    if (absl::Status st = m.Capture(capture, tiled ? grid.tiles() : 0, PostColor(pc),
                                    exposure_state ? &exposure_state->image : nullptr);
        !st.ok())
      return st;
    capture->local_lights = std::move(local);
    capture->view = fu.view;
    capture->proj = fu.proj;
  }

  const auto t_readback = Clock::now();
  m.targets.readback.InvalidateForRead();
  frame.image.width = s.width;
  frame.image.height = s.height;
  frame.image.pixels.resize(size_t(s.width) * s.height * 4);
  std::memcpy(frame.image.pixels.data(), m.targets.readback.mapped(), frame.image.pixels.size());
  frame.cpu.readback_ms = MsSince(t_readback);
  return frame;
}

uint64_t Renderer::validation_message_count() const {
  return impl_->ctx->validation_message_count();
}
std::vector<std::string> Renderer::validation_messages() const {
  return impl_->ctx->validation_messages();
}

absl::StatusOr<std::vector<uint8_t>> EncodeFrame(Frame& frame, ImageFormat format) {
  const auto t0 = Clock::now();
  absl::StatusOr<std::vector<uint8_t>> bytes =
      format == ImageFormat::kPng
          ? EncodePng(frame.image)
          : EncodeJpeg(frame.image, int(frame.settings.effective.jpeg_quality),
                       frame.settings.effective.jpeg_444 ? ChromaSubsampling::k444
                                                         : ChromaSubsampling::k420);
  frame.cpu.encode_ms = MsSince(t0);
  return bytes;
}

}  // namespace tessera
