#pragma once
// Renderer::Impl: what the renderer keeps between frames, and FrameData: what one frame
// prepares for its passes. Private to the renderer's own files (renderer.cpp is the front end,
// frame_resources.cpp the targets and buffers, frame_capture.cpp the test captures, and each
// feature in renderer/features/ prepares its own part of the frame).
#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "renderer/features/pass.h"
#include "renderer/graph/executor.h"
#include "renderer/graph/frame_graph.h"
#include "renderer/graph/readback_ring.h"
#include "renderer/graph/target_pool.h"
#include "renderer/ibl.h"
#include "renderer/ibl_maps.h"
#include "renderer/light_culling.h"
#include "renderer/renderer.h"
#include "renderer/scene/gpu_scene.h"
#include "renderer/shadows.h"
#include "renderer/vk/context.h"
#include "renderer/vk/handle.h"
#include "renderer/vk/resources.h"
#include "shaders/common/gpu_types.h"

namespace tessera {

// Views whose visibility bits a scene keeps for gpu_occlusion (least recently used dropped).
inline constexpr size_t kMaxViews = 64;

// Replaces `*out` with a new buffer (the old one is idle: every frame waits for its fence).
absl::Status MakeBuffer(const vk::Context& ctx, VkDeviceSize size, VkBufferUsageFlags usage,
                        vk::MemoryUsage memory, const char* name, vk::Buffer* out);

// Per-view state kept in a map (`last_used` in each value): drops the least recently used.
template <typename Map>
void DropLeastRecentlyUsed(Map& map) {
  if (map.empty()) return;
  map.erase(std::min_element(map.begin(), map.end(), [](const auto& a, const auto& b) {
    return a.second.last_used < b.second.last_used;
  }));
}

// taa: a view's history (kept by the renderer per scene and view).
struct TaaHistory {
  vk::Image images[2];
  bool written[2] = {false, false};
  uint32_t current = 0;  // the image last written
  uint32_t frames = 0;   // frames blended into it since the last reset (capped)
  uint32_t jitter_index = 0;
  glm::mat4 view_proj{0.0f};  // unjittered, of the last frame
  // Animated scenes: the pose the view's last frame with moving geometry showed
  // (features/motion.cpp): its SceneAnimator::pose_key, world matrix per SceneAnimator drawable,
  // and deformed vertices.
  bool kept_pose = false;
  uint64_t pose_key = 0;
  std::vector<glm::mat4> world;
  vk::Buffer vertices;
  // Forgets what the images and the kept pose hold (a frame that claimed them failed).
  void Reset() {
    written[0] = written[1] = false;
    frames = 0;
    kept_pose = false;
  }
};

// What one frame prepares before its passes record: uniforms, lights, the draw lists and each
// feature's parameters. Filled by the Prepare* steps in order.
struct FrameData {
  FrameData(const GpuScene& gs, const SceneInfo& info, const Camera& camera, const Settings& s,
            uint64_t view)
      : gs(gs), info(info), camera(camera), s(s), view(view) {}
  const GpuScene& gs;
  const SceneInfo& info;
  const Camera& camera;
  const Settings& s;  // the effective settings
  uint64_t view;
  float aspect = 1.0f;
  gpu::FrameUniforms fu{};
  glm::mat4 unjittered_view_proj{1.0f};
  // Lights: directional (and unbounded) ones are global, point and spot lights local.
  std::vector<Light> global, local;
  TileGrid grid{};
  bool tiled = false;  // forward+ tile lists this frame
  TaaFrame taa;
  TaaHistory* taa_history = nullptr;  // taa: the view's, which PrepareCamera advanced
  ShadowFrame shadows;
  SsaoFrame ssao;
  ExposureFrame exposure;
  bool* exposure_written = nullptr;  // auto exposure: set once the exposure pass ran
  DrawLists draws;
  CullBuffers cull;
  GpuScene::ViewVisibility* visibility = nullptr;  // gpu_occlusion: the view's bits
  LightCullBuffers light_buffers;
  VisFrame vis;
  ShadeBuffers shade;
  PassStats pass_stats;
  VkDescriptorSet scene_set = VK_NULL_HANDLE;
};

struct Renderer::Impl {
  std::shared_ptr<vk::Context> ctx;  // shared with the scenes, which may outlive the renderer
  std::mutex mutex;                  // the queue and everything below
  std::atomic<bool> device_lost{false};
  std::atomic<bool> simulate_loss{false};  // test hooks (Renderer::...ForTesting)
  std::atomic<uint32_t> stall_ms{0};
  std::atomic<int64_t> frames_until_loss{-1};  // TESSERA_TEST_DEVICE_LOST_AFTER_FRAMES
  // Command buffer, fence, timestamps, statistics and submission (declared after ctx: destroyed
  // before it).
  std::unique_ptr<GraphExecutor> executor;
  vk::UniqueDescriptorSetLayout scene_set_layout;
  vk::UniqueDescriptorSetLayout material_set_layout;
  vk::UniqueDescriptorSetLayout bucket_set_layout;
  vk::UniquePipelineLayout scene_pipeline_layout;
  SceneLayout scene_layout;  // the three handles above, as the passes take them
  std::array<std::unique_ptr<Pass>, static_cast<size_t>(PassId::kCount)> passes;
  vk::UniqueDescriptorPool frame_pool;
  vk::Buffer frame_ubo;
  vk::Buffer lights_ubo;
  // Forward+: local lights and their bounds (grown to the largest count seen), tile lists
  // (sized for the tile grid).
  vk::Buffer local_lights;
  vk::Buffer light_bounds;
  vk::Buffer tile_counts;
  vk::Buffer tile_lights;
  vk::Buffer tile_counts_readback;
  // local_lights and tile_lights as texel buffers (gpu::kBindingLocalLightTexels), remade with
  // them.
  vk::UniqueBufferView local_light_texels, tile_light_texels;
  vk::Buffer row_lights;  // lights binned by tile row (light_cull.comp)
  uint32_t row_capacity = 0;
  // light_binning gpu: the bounds and row lists the GPU writes (device-local).
  vk::Buffer gpu_light_bounds;
  vk::Buffer gpu_row_lights;
  uint32_t gpu_bounds_capacity = 0;
  uint64_t gpu_row_capacity = 0;
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
  // The visibility pipeline (grown to the most materials and pixels drawn): per material a
  // GpuShadeEntry and its host copy, and the pixel lists.
  vk::Buffer shade_entries;
  vk::Buffer shade_entries_readback;
  vk::Buffer shade_pixels;
  uint32_t shade_material_capacity = 0;
  uint64_t shade_pixel_capacity = 0;
  vk::Buffer edge_colors;  // vis_mlaa's runner-ups and geometric AA (ShadeBuffers)
  vk::Buffer runner_ups;
  uint64_t edge_color_capacity = 0;  // entries of each
  vk::Pipeline id_pipeline;  // FrameCapture::want_ids, made on first use
  uint64_t frame_counter = 0;
  // Pixel memory given back by RecyclePixels, newest last (its own mutex: encoder threads give
  // it back while a frame renders under `mutex`).
  std::mutex spare_mutex;
  std::vector<std::vector<uint8_t>> spare_pixels;
  TargetPool target_pool;  // every transient target, by (resource, size, samples, mips)
  FrameTargets targets;    // this frame's, from the pool
  const vk::Buffer* readback = nullptr;  // this frame's readback buffer, from the pool or ring
  // RendererOptions::lent_buffers: the buffers frames are lent from, and this frame's (null when
  // none is free or lending is off: the frame reads back into the pool's and is copied out).
  ReadbackRing readback_ring;
  std::shared_ptr<ReadbackBuffer> lent_readback;
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
  // Auto exposure: a view's adapted average (ExposureFrame::state).
  struct ExposureState {
    vk::Image image;
    bool written = false;
  };
  // Everything a (scene, view) keeps between its frames, in one least-recently-used cache
  // (gpu_occlusion's visibility bits are the scene's: GpuScene::views).
  struct ViewState {
    std::unique_ptr<TaaHistory> taa;          // two frame-sized images: at most kMaxTaaViews
    std::unique_ptr<ExposureState> exposure;  // 1x1
    uint64_t last_used = 0;
  };
  std::map<std::pair<uint64_t, uint64_t>, ViewState> view_states;
  // IBL: the maps (made when ibl first runs), the hash of the sky they hold, and a 1x1 cube
  // bound while ibl is off.
  std::unique_ptr<IblMaps> ibl;
  uint64_t ibl_sky_hash = 0;
  vk::Image cube_placeholder;

  ~Impl() {
    if (ctx) vkDeviceWaitIdle(ctx->device());  // then every member is idle when destroyed
  }

  // renderer_init.cpp
  absl::Status Init();
  absl::Status InitLayouts();
  absl::Status InitPasses();
  absl::Status InitShadows();

  // frame_resources.cpp: targets and buffers, (re)made when a frame needs them.
  // This frame's targets from the pool (the ones its settings use), then a trim of the pool.
  // `moving`: an animated scene with drawables that move or deform (taa's motion target).
  absl::Status AcquireTargets(const Settings& s, bool moving);
  absl::Status EnsureShadowAtlas(uint32_t size);
  absl::Status EnsureLightBuffers(uint32_t lights, uint32_t tiles);
  absl::Status EnsureRowBuffer(size_t entries);
  absl::Status EnsureCullBuffers(uint32_t items, uint32_t lists);
  // Per-view state (least recently used dropped): the view's entry, its taa history, its exposure
  // state, its occlusion bits.
  ViewState& View(const GpuScene& scene, uint64_t view);
  absl::StatusOr<TaaHistory*> Taa(const GpuScene& scene, uint64_t view);
  absl::StatusOr<ExposureState*> Exposure(const GpuScene& scene, uint64_t view);
  absl::StatusOr<GpuScene::ViewVisibility*> Visibility(const GpuScene& scene, uint64_t view);
  // The frame's set 0; binds the shadow atlas when `shadows` (else the 1x1 stand-in).
  VkDescriptorSet WriteSceneSet(const GpuScene& scene, bool shadows, bool ssao, bool ibl);
  // Each planned pass builds what it lacks for settings `s` and scene `gs` (Pass::Prepare, then
  // Pass::PrepareScene): before a frame, and with the default settings when a scene is loaded.
  absl::Status PreparePasses(const FramePlan& plan, const Settings& s, const GpuScene& gs,
                             const FrameFeatures& features);
  // Whether `lights` local lights and the light lists of `tiles` tiles fit the device's texel
  // buffers (FrameFeatures::light_texels).
  bool LightTexelsFit(uint64_t lights, uint64_t tiles) const;
  // The long-lived images this frame imports into its graph (FrameTargets::shadow_atlas ...).
  void ImportTargets(const FrameData& f);
  // What the passes record with.
  PassContext MakePassContext(FrameData& f);
  void ReadBack(Frame& frame);
  // Pixel memory of `bytes` for a copied-out frame: a given-back buffer that fits, else new.
  std::vector<uint8_t> TakeSparePixels(size_t bytes);

  // The features' per-frame preparation, in the order Render calls them.
  // vis_mlaa.cpp: falls back to msaa when the scene's ids do not fit (with a note).
  // Returns the bits of an id that hold the triangle.
  uint32_t CheckVisibilityIds(const GpuScene& gs, ResolvedSettings& settings);
  absl::Status PrepareCamera(FrameData& f);  // post.cpp: uniforms, taa history and jitter
  // motion.cpp (from PrepareCamera): taa's object motion and the view's kept pose.
  absl::Status PrepareMotion(FrameData& f, TaaHistory& history, bool history_valid);
  absl::Status PrepareLights(FrameData& f, Frame& frame);  // forward_plus.cpp
  // forward_plus.cpp: the scene's lights as PrepareLights starts from them (`scene_lights` off:
  // none): directional and unbounded ones global, the others local (IsLocalLight), and a sun
  // (DefaultSun) where that leaves no light at all. The scene-load warm-up counts them too.
  static void SplitSceneLights(const std::vector<Light>& lights, bool scene_lights,
                               std::vector<Light>& global, std::vector<Light>& local);
  absl::Status PrepareShadows(FrameData& f, Frame& frame);  // shadows.cpp
  absl::Status PrepareSsao(FrameData& f);                  // ssao.cpp
  absl::Status PrepareIbl(FrameData& f, Frame& frame);     // ibl.cpp
  absl::StatusOr<bool> EnsureIbl(const SkyParams& sky);    // bakes `sky` unless held
  absl::Status PrepareExposure(FrameData& f);              // exposure.cpp
  absl::Status WriteLightBins(FrameData& f);               // forward_plus.cpp
  absl::Status EnsureGpuBinBuffers(uint32_t lights, uint64_t row_entries);  // forward_plus.cpp
  void WriteFrameUniforms(FrameData& f, Frame& frame);     // forward_plus.cpp
  absl::Status PrepareDraws(FrameData& f);                 // culling.cpp
  // vis_shade.cpp: the materials in view, the entries and pixel lists.
  absl::Status PrepareShade(FrameData& f);
  // culling.cpp: none / cpu_frustum: the CPU writes phase 0's lists.
  void WriteCpuLists(const GpuScene& scene, const DrawLists& lists, const Frustum* frustum);
  // culling.cpp: what the frame drew, from the lists it executed.
  void CountDrawn(const GpuScene& gs, const DrawLists& draws, const std::vector<PassId>& pass_ids,
                  FrameStats& stats, std::vector<uint32_t>* drawn_out) const;
  // After the passes ran: statistics and the per-view state the frame advanced.
  absl::Status FinishFrame(FrameData& f, const FramePlan& plan, GraphExecutor::Result run,
                           Frame& frame, FrameCapture* capture);

  // frame_capture.cpp (tests): copies the depth, the light lists, the tonemap's input, auto
  // exposure's state and taa's object motion; with want_ids also every drawable's id against the
  // frame's depth.
  absl::Status CaptureFrame(FrameData& f, const FramePlan& plan, const PassContext& pc,
                            FrameCapture* capture);
  absl::Status Capture(FrameCapture* capture, const LightCullBuffers* lights,
                       const vk::Image& hdr, Access hdr_access, Access depth_access,
                       const vk::Image* exposure, const vk::Image* motion, Access motion_access);
  absl::Status CaptureIds(const GpuScene& scene, VkDescriptorSet scene_set, Access depth_access,
                          FrameCapture* capture);
};

}  // namespace tessera
