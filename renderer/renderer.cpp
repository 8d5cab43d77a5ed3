// The renderer's front end: resolve the settings once, let each feature prepare its part of
// the frame, plan the frame from the features (features/frame.cpp), execute it
// (graph/executor.h), and fill the frame's stats. What the renderer keeps between frames is in
// renderer_impl.h; targets and buffers in frame_resources.cpp; test captures in
// frame_capture.cpp.
#include "renderer/renderer.h"

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <thread>

#include "absl/cleanup/cleanup.h"
#include "absl/strings/escaping.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "common/status_macros.h"
#include "renderer/log.h"
#include "renderer/features/features.h"
#include "renderer/renderer_impl.h"
#include "renderer/vk/vk_check.h"

namespace tessera {

namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

}  // namespace

Scene::~Scene() = default;

Renderer::Renderer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Renderer::~Renderer() = default;

absl::StatusOr<std::unique_ptr<Renderer>> Renderer::Create(const RendererOptions& options) {
  auto impl = std::make_unique<Impl>();
  ASSIGN_OR_RETURN(
      impl->ctx, vk::Context::Create({.device_name = options.device_name,
                                      .validation = options.validation,
                                      .disable_features = options.disable_features,
                                      .max_storage_buffer_range = options.max_storage_buffer_range,
                                      .descriptor_limit_caps = options.descriptor_limit_caps,
                                      .appends = options.appends,
                                      .shading = options.shading}));
  impl->readback_ring = ReadbackRing(options.lent_buffers);
  RETURN_IF_ERROR(impl->Init());
  // After the passes are made: a descriptor limit may have turned this shading off
  // (vk::Context::DisableShadeAllMaterials).
  if (impl->ctx->info().shade_all_materials) {
    Log().info("visibility shading: one dispatch over every pixel, textures indexed per pixel");
  }
  if (const char* n = std::getenv("TESSERA_TEST_DEVICE_LOST_AFTER_FRAMES")) {
    int64_t frames = -1;
    if (!absl::SimpleAtoi(n, &frames) || frames < 0)
      return absl::InvalidArgumentError(absl::StrCat(
          "TESSERA_TEST_DEVICE_LOST_AFTER_FRAMES: '", n, "' is not a frame count"));
    impl->frames_until_loss = frames;
    Log().warn("test hook: the device will be lost after {} frames", frames);
  }
  return std::unique_ptr<Renderer>(new Renderer(std::move(impl)));
}

const DeviceInfo& Renderer::device_info() const { return impl_->ctx->info(); }

DeviceCaps Renderer::caps() const {
  const DeviceInfo& info = impl_->ctx->info();
  return {info.max_samples, info.max_image_dimension, info.sample_counts,
          info.visibility_buffer, info.type == "cpu"};
}

absl::StatusOr<SceneHandle> Renderer::LoadScene(const GltfSource& source) {
  ASSIGN_OR_RETURN(const CpuScene cpu, ImportGltf(source));
  return LoadScene(cpu);
}

absl::StatusOr<SceneHandle> Renderer::LoadScene(const CpuScene& cpu) {
  std::lock_guard lock(impl_->mutex);
  ASSIGN_OR_RETURN(std::unique_ptr<GpuScene> gpu,
                   GpuScene::Upload(*impl_->ctx, cpu, impl_->scene_layout.material_set_layout,
                                    impl_->ctx->info().shade_all_materials
                                        ? impl_->scene_layout.bucket_set_layout
                                        : VK_NULL_HANDLE));
  std::shared_ptr<Scene> scene(new Scene());
  // An animated scene's bounds are its rest pose's: skinned meshes are placed by their joints,
  // not by their nodes (what framing cameras look at).
  Aabb bounds = cpu.bounds;
  if (gpu->animated()) {
    gpu->Pose(-1, 0.0, true);
    bounds = gpu->bounds();
  }
  scene->info_ = {cpu.name,    cpu.counts,   bounds,
                  cpu.cameras, cpu.warnings, gpu->device_bytes(), {}};
  for (const Animation& a : cpu.animations)
    scene->info_.animations.push_back({a.name, a.duration, uint32_t(a.channels.size())});
  // The scene's first frame should not wait for the shading pipelines its materials need (one
  // per set of texture slots they use): build those of the default settings now. A failure
  // here is the first frame's to report (with the settings it asks for), not the load's.
  if (absl::StatusOr<ResolvedSettings> defaults = ResolveSettings(Settings{}, caps());
      defaults.ok()) {
    FrameFeatures features;
    for (const DrawSegment& seg : gpu->segments())
      features.has_transparent = features.has_transparent || seg.group == AlphaMode::kBlend;
    const Settings& d = defaults->effective;
    features.light_texels = impl_->LightTexelsFit(
        gpu->lights().size(), TileGrid{d.width, d.height, d.tile_size}.tiles());
    // The local and global lights as PrepareLights counts them: the shading pipelines differ
    // with and without local lights (kLocalLightsOn) and by the global lights' loop
    // (kGlobalLightsOn).
    std::vector<Light> global, local;
    Impl::SplitSceneLights(gpu->lights(), d.scene_lights, global, local);
    features.local_lights = uint32_t(local.size()) + d.synthetic_lights;
    features.global_lights = uint32_t(global.size());
    const absl::Status warmed =
        impl_->PreparePasses(PlanFrame(d, features), d, *gpu, features);
    if (!warmed.ok())
      Log().warn("scene {}: building its pipelines: {}", cpu.name, warmed.ToString());
  }
  scene->device_ = impl_->ctx;
  scene->gpu_ = std::move(gpu);
  return SceneHandle(std::move(scene));
}

absl::Status Renderer::Impl::PreparePasses(const FramePlan& plan, const Settings& s,
                                           const GpuScene& gs, const FrameFeatures& features) {
  for (const PlannedPass& p : plan.passes) {
    Pass& pass = *passes[static_cast<size_t>(p.id)];
    RETURN_IF_ERROR(pass.Prepare(*ctx, s));
    RETURN_IF_ERROR(pass.PrepareScene(*ctx, s, gs, features));
  }
  return absl::OkStatus();
}

bool Renderer::Impl::LightTexelsFit(uint64_t lights, uint64_t tiles) const {
  const uint64_t max = ctx->info().max_texel_buffer_elements;
  return ctx->info().texel_buffers && lights * gpu::kGpuLightTexels <= max &&
         tiles * gpu::kMaxLightsPerTile <= max;
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
  impl_->view_states.erase({scene.gpu_->serial(), view});
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

absl::StatusOr<int> FindAnimation(const SceneInfo& info, std::string_view animation) {
  if (animation.empty() || animation == "none") return -1;
  for (size_t i = 0; i < info.animations.size(); ++i)
    if (info.animations[i].name == animation) return int(i);
  // Not a name: an index, as decimal digits.
  uint32_t index = 0;
  if (absl::SimpleAtoi(absl::string_view(animation.data(), animation.size()), &index) &&
      std::all_of(animation.begin(), animation.end(), [](char c) { return c >= '0' && c <= '9'; })) {
    if (index < info.animations.size()) return int(index);
    return absl::InvalidArgumentError(absl::StrCat(
        "settings.animation: index ", index, " is out of range: the scene has ",
        info.animations.size(), info.animations.size() == 1 ? " animation" : " animations"));
  }
  // Names from the client and the file, quoted short and escaped: the message stays small.
  auto quoted = [](std::string_view s) {
    size_t n = std::min<size_t>(s.size(), 64);
    while (n > 0 && n < s.size() && (static_cast<unsigned char>(s[n]) & 0xC0) == 0x80) --n;
    return absl::StrCat("'", absl::Utf8SafeCHexEscape(absl::string_view(s.data(), n)),
                        n < s.size() ? "...'" : "'");
  };
  std::string names;
  for (size_t i = 0; i < info.animations.size() && i < 8; ++i)
    absl::StrAppend(&names, i ? ", " : "", quoted(info.animations[i].name));
  if (info.animations.size() > 8) absl::StrAppend(&names, " and ", info.animations.size() - 8, " more");
  return absl::InvalidArgumentError(absl::StrCat(
      "settings.animation: the scene has no animation named ", quoted(animation),
      info.animations.empty() ? " (it has none)" : absl::StrCat(" (it has ", names, ")")));
}

bool IsDeviceLost(const absl::Status& status) {
  // vk::VkStatus's message for VK_ERROR_DEVICE_LOST (no payload: statuses end up in logs and
  // job errors through ToString, which would print it).
  return absl::IsUnavailable(status) &&
         absl::StrContains(status.message(), vk::ResultName(VK_ERROR_DEVICE_LOST));
}

bool Renderer::device_lost() const { return impl_->device_lost.load(); }

void Renderer::SimulateDeviceLossForTesting() { impl_->simulate_loss = true; }

void Renderer::StallNextRenderForTesting(uint32_t ms) { impl_->stall_ms = ms; }

absl::StatusOr<std::vector<Vertex>> Renderer::ReadVerticesForTesting(const Scene& scene,
                                                                     uint64_t first,
                                                                     uint64_t count) {
  std::lock_guard lock(impl_->mutex);
  const vk::Buffer& vertices = scene.gpu_->vertices();
  if (count == 0 || (first + count) * sizeof(Vertex) > vertices.size())
    return absl::OutOfRangeError("ReadVerticesForTesting: past the vertex buffer");
  const VkDeviceSize bytes = count * sizeof(Vertex);
  ASSIGN_OR_RETURN(vk::Buffer out,
                   vk::Buffer::Create(*impl_->ctx, bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                      vk::MemoryUsage::kReadback, "test.vertices"));
  RETURN_IF_ERROR(impl_->ctx->SubmitOnce([&](VkCommandBuffer cmd) {
    vk::CmdMemoryBarrier(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT,
                         VK_ACCESS_2_MEMORY_WRITE_BIT, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT,
                         VK_ACCESS_2_TRANSFER_READ_BIT);
    const VkBufferCopy region{first * sizeof(Vertex), 0, bytes};
    vkCmdCopyBuffer(cmd, vertices.handle(), out.handle(), 1, &region);
    vk::CmdMemoryBarrier(cmd, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                         VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_READ_BIT);
  }));
  out.InvalidateForRead();
  std::vector<Vertex> result(count);
  std::memcpy(result.data(), out.mapped(), bytes);
  return result;
}

absl::StatusOr<Frame> Renderer::Render(const Scene& scene, const Camera& camera,
                                       const Settings& settings, uint64_t view,
                                       FrameCapture* capture) {
  Impl& m = *impl_;
  if (m.device_lost) {
    return vk::VkStatus(VK_ERROR_DEVICE_LOST, "an earlier frame");
  }
  if (const uint32_t ms = m.stall_ms.exchange(0))
    std::this_thread::sleep_for(std::chrono::milliseconds(ms));
  if (m.simulate_loss.exchange(false) || m.frames_until_loss.fetch_sub(1) == 0) {
    m.device_lost = true;
    return vk::VkStatus(VK_ERROR_DEVICE_LOST, "vkQueueSubmit (simulated by a test hook)");
  }
  absl::StatusOr<Frame> frame = RenderFrame(scene, camera, settings, view, capture);
  if (!frame.ok() && IsDeviceLost(frame.status())) {
    m.device_lost = true;
    Log().critical("the GPU device was lost: {}", std::string(frame.status().message()));
  }
  return frame;
}

absl::StatusOr<Frame> Renderer::RenderFrame(const Scene& scene, const Camera& camera,
                                            const Settings& settings, uint64_t view,
                                            FrameCapture* capture) {
  ASSIGN_OR_RETURN(ResolvedSettings resolved, ResolveSettings(settings, caps()));
  RETURN_IF_ERROR(ValidateCamera(camera));
  ASSIGN_OR_RETURN(const int animation, FindAnimation(scene.info(), settings.animation));

  std::lock_guard lock(impl_->mutex);
  Impl& m = *impl_;
  // The scene's pose for this frame (animated scenes; under the lock, so frames of other times
  // take turns). The skinning pass brings the device to it.
  GpuScene& posed = *scene.gpu_;
  posed.Pose(animation, settings.scene_time, settings.loop);
  const GpuScene& gs = posed;
  // A file camera on an animated node: where the pose puts it.
  Camera posed_camera = camera;
  if (camera.scene_camera >= 0 && gs.animator())
    if (std::optional<glm::mat4> world = gs.animator()->CameraWorld(uint32_t(camera.scene_camera)))
      posed_camera.view = glm::inverse(*world);
  Frame frame;
  frame.settings = std::move(resolved);
  if (const SceneAnimator* a = gs.animator()) {
    frame.stats.animated_drawables = uint32_t(a->drawables().size());
    if (gs.pose_pending()) frame.stats.deformed_vertices = a->deformed_vertices();
  }
  const uint32_t triangle_bits = m.CheckVisibilityIds(gs, frame.settings);
  const Settings& s = frame.settings.effective;
  auto made = [&m] { return m.target_pool.created() + m.readback_ring.created(); };
  const uint64_t targets_before = made();
  RETURN_IF_ERROR(m.AcquireTargets(
      s, gs.animator() != nullptr && !gs.animator()->drawables().empty()));
  frame.stats.targets_created = uint32_t(made() - targets_before);

  // Each feature prepares its part of the frame, in order: the camera (and taa's jitter)
  // first, the lights before the shadows that mark them, the draw lists last.
  const auto t_record = Clock::now();
  FrameData f(gs, scene.info(), posed_camera, s, view);
  f.vis.triangle_bits = triangle_bits;
  // PrepareCamera advances the view's TAA history (the image this frame writes, its kept pose); a
  // frame that fails after it leaves the history reset rather than claiming what it never wrote.
  absl::Cleanup rollback = [&f] {
    if (f.taa_history) f.taa_history->Reset();
  };
  RETURN_IF_ERROR(m.PrepareCamera(f));
  RETURN_IF_ERROR(m.PrepareLights(f, frame));
  if (s.shadows) RETURN_IF_ERROR(m.PrepareShadows(f, frame));
  RETURN_IF_ERROR(m.PrepareSsao(f));
  RETURN_IF_ERROR(m.PrepareIbl(f, frame));
  RETURN_IF_ERROR(m.PrepareExposure(f));
  RETURN_IF_ERROR(m.WriteLightBins(f));
  m.WriteFrameUniforms(f, frame);
  RETURN_IF_ERROR(m.PrepareDraws(f));
  RETURN_IF_ERROR(m.PrepareShade(f));

  // The frame's passes, from the features' Setup; each builds what it lacks for the settings.
  FrameFeatures features;
  features.has_transparent = !f.draws.blend_order.empty();
  features.local_lights = uint32_t(f.local.size());
  features.global_lights = uint32_t(f.global.size());
  features.shadow_atlas_valid = !f.shadows.atlas_new;
  features.taa_history_valid = f.taa.history_valid;
  features.exposure_valid = f.exposure.state_valid;
  features.pose_pending = gs.pose_pending();
  features.object_motion = f.taa.motion_pass;
  features.light_texels = m.LightTexelsFit(f.local.size(), f.tiled ? f.grid.tiles() : 1);
  features.count_background = capture != nullptr;
  features.shade_all_materials = m.ctx->info().shade_all_materials;
  const FramePlan plan = PlanFrame(s, features);
  m.ImportTargets(f);
  RETURN_IF_ERROR(m.PreparePasses(plan, s, gs, features));
  VK_CHECK(vkResetDescriptorPool(m.ctx->device(), m.frame_pool.get(), 0));
  f.scene_set = m.WriteSceneSet(gs, s.shadows, s.ssao, s.ibl);
  PassContext pc = m.MakePassContext(f);
  pc.post_color = plan.scene_color;
  pc.features = &features;
  ASSIGN_OR_RETURN(GraphExecutor::Result run,
                   m.executor->Execute(
                       plan, [&](Resource r) -> const vk::Image& { return m.targets.Get(r); },
                       [&](PassId id, VkCommandBuffer cmd) {
                         pc.cmd = cmd;
                         m.passes[static_cast<size_t>(id)]->Record(pc);
                       },
                       t_record, s.pass_timing));
  if (plan.Has(PassId::kSkinning)) posed.PoseRecorded();
  RETURN_IF_ERROR(m.FinishFrame(f, plan, std::move(run), frame, capture));
  std::move(rollback).Cancel();
  if (capture) RETURN_IF_ERROR(m.CaptureFrame(f, plan, pc, capture));
  m.ReadBack(frame);
  return frame;
}

void Renderer::Impl::ImportTargets(const FrameData& f) {
  targets.shadow_atlas = f.shadows.atlas ? vk::ImageRef(*f.shadows.atlas) : vk::ImageRef();
  targets.taa_history = f.taa.history_read ? vk::ImageRef(*f.taa.history_read) : vk::ImageRef();
  targets.taa_history_next =
      f.taa.history_write ? vk::ImageRef(*f.taa.history_write) : vk::ImageRef();
  targets.exposure_state = f.exposure.state ? vk::ImageRef(*f.exposure.state) : vk::ImageRef();
}

PassContext Renderer::Impl::MakePassContext(FrameData& f) {
  PassContext pc;
  pc.vk = ctx.get();
  pc.targets = &targets;
  pc.scene = &f.gs;
  pc.draws = &f.draws;
  pc.settings = &f.s;
  pc.scene_pipeline_layout = scene_layout.pipeline_layout;
  pc.scene_set = f.scene_set;
  pc.frame_pool = frame_pool.get();
  pc.stats = &f.pass_stats;
  pc.light_buffers = &f.light_buffers;
  pc.cull = &f.cull;
  pc.vis = &f.vis;
  pc.shade = &f.shade;
  pc.taa = &f.taa;
  pc.shadows = &f.shadows;
  pc.shadow_atlas_view = f.s.shadows ? &shadow_atlas : &shadow_placeholder;
  pc.ao_view = f.s.ssao ? &targets.ao.get() : &ao_placeholder;
  pc.ssao = &f.ssao;
  pc.exposure = &f.exposure;
  pc.samples = targets.samples;
  return pc;
}

absl::Status Renderer::Impl::FinishFrame(FrameData& f, const FramePlan& plan,
                                         GraphExecutor::Result run, Frame& frame,
                                         FrameCapture* capture) {
  frame.timing = run.timing;
  frame.passes = std::move(run.passes);
  frame.gpu_total_ms = run.gpu_total_ms;
  frame.cpu.record_ms = run.record_ms;
  frame.cpu.submit_wait_ms = run.submit_wait_ms;
  frame.cpu.submissions = run.submissions;
  // The state this frame advanced.
  if (f.visibility) f.visibility->prev ^= 1;  // this frame's bits are the next frame's history
  if (f.s.shadows) shadow_atlas_written = true;  // the faces listed were rendered
  if (f.exposure_written && plan.Has(PassId::kExposure)) *f.exposure_written = true;

  CountDrawn(f.gs, f.draws, plan.ids(), frame.stats, capture ? &capture->drawn : nullptr);
  frame.stats.indirect_draws = f.pass_stats.indirect_draws;
  frame.stats.shading_dispatches = f.pass_stats.material_draws;
  frame.stats.pipeline_statistics = run.pipeline_statistics;
  frame.stats.primitives_in = run.primitives_in;
  frame.stats.primitives_clipped = run.primitives_clipped;
  frame.stats.fragment_invocations = run.fragment_invocations;
  if (plan.Has(PassId::kShade)) {
    shade_entries_readback.InvalidateForRead();
    const auto* entries = static_cast<const gpu::GpuShadeEntry*>(shade_entries_readback.mapped());
    // Each material's pixels are counted in its entry (by the classification, vis_mlaa's resolve
    // or the one-dispatch shading). The classified shading dispatches over each list; the one
    // dispatch covers the frame (recorded), and vis_mlaa's second its blend list.
    const bool classified = plan.Has(PassId::kVisClassify);
    auto invocations = [&](uint32_t entry) {
      const glm::uvec4& d = entries[entry].dispatch;
      return uint64_t(d.x) * d.y * d.z * gpu::kShadeGroupSize;
    };
    frame.stats.shading_invocations = f.pass_stats.shading_invocations;
    for (uint32_t m = 0; m < f.shade.materials; ++m) {
      frame.stats.shaded_pixels += entries[m].dispatch.w;
      if (classified) frame.stats.shading_invocations += invocations(m);
    }
    if (!classified && plan.Has(PassId::kVisResolve))
      frame.stats.shading_invocations += invocations(f.shade.blend_entry());
    if (capture) {
      // No lists where one dispatch shaded every pixel.
      capture->shade_lists.clear();
      for (uint32_t m = 0; classified && m <= f.shade.materials; ++m)
        capture->shade_lists.push_back({entries[m].dispatch.w, entries[m].list.y});
      capture->background_pixels = entries[f.shade.materials].list.z;
    }
    if (plan.Has(PassId::kVisResolve)) {
      frame.stats.edge_pixels = entries[f.shade.edge_entry()].dispatch.w;
      frame.stats.runner_up_pixels = entries[f.shade.edge_entry()].list.x;
      frame.stats.blend_pixels = entries[f.shade.blend_entry()].dispatch.w;
    }
  }
  if (f.tiled) {
    tile_counts_readback.InvalidateForRead();
    const auto* counts = static_cast<const uint32_t*>(tile_counts_readback.mapped());
    const TileStats ts = ComputeTileStats(std::vector<uint32_t>(counts, counts + f.grid.tiles()));
    frame.stats.tile_lights_avg = ts.average;
    frame.stats.tile_lights_p50 = ts.p50;
    frame.stats.tile_lights_p95 = ts.p95;
    frame.stats.tile_lights_max = ts.max;
    frame.stats.tile_overflows = ts.overflows;
  }
  return absl::OkStatus();
}

void Renderer::RecyclePixels(std::vector<uint8_t>&& pixels) {
  std::vector<uint8_t> taken = std::move(pixels);  // the caller's vector is left empty
  if (taken.capacity() == 0) return;
  std::lock_guard lock(impl_->spare_mutex);
  auto& spare = impl_->spare_pixels;
  if (spare.size() >= kSparePixelBuffers) spare.erase(spare.begin());
  spare.push_back(std::move(taken));
}

void Renderer::ReleasePixels(Frame& frame) {
  frame.lent.Release();
  RecyclePixels(std::move(frame.image.pixels));
}

Renderer::LendingStats Renderer::lending() const {
  std::lock_guard lock(impl_->mutex);
  return {impl_->readback_ring.size(), impl_->readback_ring.lent()};
}

LentPixels::LentPixels(std::shared_ptr<ReadbackBuffer> buffer) : buffer_(std::move(buffer)) {}

LentPixels& LentPixels::operator=(LentPixels&& o) noexcept {
  if (this != &o) {
    Release();
    buffer_ = std::move(o.buffer_);
  }
  return *this;
}

std::span<const uint8_t> LentPixels::bytes() const {
  if (!buffer_) return {};
  return {static_cast<const uint8_t*>(buffer_->buffer.mapped()), size_t(buffer_->buffer.size())};
}

void LentPixels::Release() {
  if (!buffer_) return;
  buffer_->lent.store(false, std::memory_order_release);  // the ring may hand it out again
  buffer_.reset();
}

void Renderer::Impl::ReadBack(Frame& frame) {
  const auto t_readback = Clock::now();
  const Settings& s = frame.settings.effective;
  readback->InvalidateForRead();
  frame.image.width = s.width;
  frame.image.height = s.height;
  if (lent_readback) {  // the caller reads the mapped bytes; the ring skips the buffer till then
    lent_readback->lent.store(true, std::memory_order_relaxed);
    frame.lent = LentPixels(std::move(lent_readback));
  } else {
    frame.image.pixels = TakeSparePixels(size_t(s.width) * s.height * 4);
    std::memcpy(frame.image.pixels.data(), readback->mapped(), frame.image.pixels.size());
  }
  frame.cpu.readback_ms = MsSince(t_readback);
}

std::vector<uint8_t> Renderer::Impl::TakeSparePixels(size_t bytes) {
  std::vector<uint8_t> pixels;
  {
    // The newest given-back buffer that holds the frame without wasting more than its size.
    std::lock_guard lock(spare_mutex);
    for (auto it = spare_pixels.rbegin(); it != spare_pixels.rend(); ++it) {
      if (it->capacity() < bytes || it->capacity() > 2 * bytes) continue;
      pixels = std::move(*it);
      spare_pixels.erase(std::next(it).base());
      break;
    }
  }
  pixels.resize(bytes);
  return pixels;
}

uint64_t Renderer::validation_message_count() const {
  return impl_->ctx->validation_message_count();
}
std::vector<std::string> Renderer::validation_messages() const {
  return impl_->ctx->validation_messages();
}

std::string_view ToString(TimingSource source) {
  switch (source) {
    case TimingSource::kGpuTimestamps:
      return "gpu_timestamps";
    case TimingSource::kPassWallClock:
      return "pass_wall_clock";
    case TimingSource::kFrameWallClock:
      return "frame_wall_clock";
  }
  return "invalid";
}

absl::StatusOr<std::vector<uint8_t>> EncodeFrame(Frame& frame, ImageFormat format) {
  const auto t0 = Clock::now();
  absl::StatusOr<std::vector<uint8_t>> bytes =
      format == ImageFormat::kPng
          ? EncodePng(frame.view())
          : EncodeJpeg(frame.view(), int(frame.settings.effective.jpeg_quality),
                       frame.settings.effective.jpeg_444 ? ChromaSubsampling::k444
                                                         : ChromaSubsampling::k420,
                       /*strips=*/0);  // large frames in strips on several threads
  frame.cpu.encode_ms = MsSince(t0);
  return bytes;
}

}  // namespace tessera
