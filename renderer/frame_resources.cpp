// The renderer's frame targets, buffers and per-view state: made (or grown) when a frame
// first needs them, kept across frames.
#include <bit>
#include <cstring>

#include "common/status_macros.h"
#include "renderer/renderer_impl.h"
#include "renderer/vk/vk_check.h"

namespace tessera {

namespace {
// Level 0 of the depth pyramid is the power of two at or below half the frame size: on lavapipe
// the pyramid's cost is per texel (1280x720: 14.3 ms from a 1024x512 level 0, 6.4 ms from 512x256),
// and the occlusion test reads a coarser level for all but tiny drawables anyway.
constexpr uint32_t kHizLevel0Divisor = 2;
}  // namespace

absl::Status MakeBuffer(const vk::Context& ctx, VkDeviceSize size, VkBufferUsageFlags usage,
                        vk::MemoryUsage memory, const char* name, vk::Buffer* out) {
  ASSIGN_OR_RETURN(*out, vk::Buffer::Create(ctx, size, usage, memory, name));
  return absl::OkStatus();
}

// The light a scene without lights gets: a warm sun from above and in front.

absl::Status Renderer::Impl::EnsureShadowAtlas(uint32_t size) {
  if (shadow_atlas && shadow_atlas.desc().width == size) return absl::OkStatus();
  vkDeviceWaitIdle(ctx->device());
  shadow_atlas = vk::Image();
  vk::ImageDesc desc;
  desc.width = desc.height = size;
  desc.format = kShadowFormat;
  desc.usage = VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT;
  ASSIGN_OR_RETURN(shadow_atlas, vk::Image::Create(*ctx, desc, "shadow_atlas"));
  shadow_faces = std::make_unique<ShadowAtlas>(size);
  shadow_atlas_written = false;
  return absl::OkStatus();
}

absl::Status Renderer::Impl::AcquireTargets(const Settings& s, bool moving) {
  const uint64_t frame = ++frame_counter;
  const uint32_t width = s.width, height = s.height;
  FrameTargets t;
  t.width = width;
  t.height = height;
  // One target of the frame from the pool: `resource` at `w` x `h`, `samples`, `mips`, with a
  // sampling view in `sampled_view` when that is not VK_FORMAT_UNDEFINED.
  auto get = [&](Resource resource, VkFormat format, VkImageUsageFlags usage, const char* name,
                 uint32_t w, uint32_t h, uint32_t samples = 1, uint32_t mips = 1,
                 VkFormat sampled_view = VK_FORMAT_UNDEFINED)
      -> absl::StatusOr<const TargetPool::Target*> {
    vk::ImageDesc desc;
    desc.width = w;
    desc.height = h;
    desc.format = format;
    desc.samples = static_cast<VkSampleCountFlagBits>(samples);
    desc.mip_levels = mips;
    desc.usage = usage;
    desc.sampled_view_format = sampled_view;
    return target_pool.Acquire(*ctx, resource, desc, name, mips > 1, frame);
  };
  constexpr VkImageUsageFlags kColor = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT;
  constexpr VkImageUsageFlags kSampled = VK_IMAGE_USAGE_SAMPLED_BIT;
  constexpr VkImageUsageFlags kDepth = VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT;
  constexpr VkImageUsageFlags kCopy = VK_IMAGE_USAGE_TRANSFER_SRC_BIT;  // captures, readback
  constexpr VkImageUsageFlags kStorage = VK_IMAGE_USAGE_STORAGE_BIT;
  using R = Resource;
  // Sampled by light culling, ssao, taa and the pyramid; copied out for tests (FrameCapture).
  ASSIGN_OR_RETURN(auto* depth,
                   get(R::kDepth, kDepthFormat, kDepth | kSampled | kCopy, "depth", width, height));
  t.depth = depth->image;
  // Storage: the visibility pipeline shades it in compute.
  ASSIGN_OR_RETURN(auto* hdr, get(R::kHdrColor, kHdrFormat, kColor | kSampled | kCopy | kStorage,
                                  "hdr_color", width, height));
  t.hdr = hdr->image;
  // Compute post passes write the sRGB bytes into UNORM storage images (an sRGB format is no
  // storage format); FXAA then samples the tonemapped one through an sRGB view, so that
  // filtering blends linear light as the fragment path's sRGB image does. The pool keeps one of
  // each format.
  const bool compute_ldr = FullscreenProgram::Compute(s);
  const bool fxaa = s.aa == AaMode::kFxaa;
  ASSIGN_OR_RETURN(auto* ldr,
                   get(R::kLdrColor, compute_ldr ? kLdrComputeFormat : kLdrFormat,
                       kColor | kSampled | kCopy | (compute_ldr ? kStorage : 0u), "ldr_color",
                       width, height, 1, 1,
                       compute_ldr && fxaa ? kLdrFormat : VK_FORMAT_UNDEFINED));
  t.ldr = ldr->image;
  const uint64_t readback_bytes = uint64_t(width) * height * 4;
  lent_readback = readback_ring.Acquire(ctx, readback_bytes, frame);
  if (lent_readback) {
    readback = &lent_readback->buffer;
  } else {
    ASSIGN_OR_RETURN(readback, target_pool.AcquireBuffer(*ctx, readback_bytes, "readback", frame));
  }
  t.readback = readback->handle();
  if (s.culling == CullingMode::kGpuFrustum || s.culling == CullingMode::kGpuOcclusion) {
    // The depth pyramid: a power of two at or below half the frame size, down to 1x1.
    t.hiz_width = std::max(1u, std::bit_floor(width) / kHizLevel0Divisor);
    t.hiz_height = std::max(1u, std::bit_floor(height) / kHizLevel0Divisor);
    const uint32_t levels = uint32_t(std::bit_width(std::max(t.hiz_width, t.hiz_height)));
    ASSIGN_OR_RETURN(auto* hiz, get(R::kHiz, kHizFormat, VK_IMAGE_USAGE_STORAGE_BIT | kSampled,
                                    "hiz", t.hiz_width, t.hiz_height, 1, levels));
    t.hiz = hiz->image;
    t.hiz_levels = hiz->mips;
  }
  // The AA mode's targets, at its sample count.
  const uint32_t n = s.samples;
  const bool msaa = s.aa == AaMode::kMsaa, vis = s.aa == AaMode::kVisMlaa;
  // vis_mlaa_coverage analytic: one sample rasterized (the frame's depth and a one-sample
  // visibility target), the others found by the resolve.
  const bool analytic = VisMlaaAnalytic(s);
  t.samples = msaa || vis ? n : 1;
  if (msaa || (vis && !analytic)) {
    ASSIGN_OR_RETURN(auto* d, get(R::kDepthMs, kDepthFormat, kDepth, "depth_ms", width, height, n));
    t.depth_ms = d->image;
  }
  if (msaa) {
    ASSIGN_OR_RETURN(auto* c, get(R::kHdrMs, kHdrFormat, kColor, "hdr_ms", width, height, n));
    t.hdr_ms = c->image;
  }
  if (vis) {
    ASSIGN_OR_RETURN(auto* v,
                     get(R::kVisMs, kIdFormat, kColor | kSampled, "visibility", width, height,
                         analytic ? 1 : n));
    t.vis_ms = v->image;
    ASSIGN_OR_RETURN(auto* cov, get(R::kVisCoverage, kIdFormat, kSampled | kStorage,
                                    "vis_coverage", width, height));
    t.vis_coverage = cov->image;
  }
  // The id per pixel: vis_mlaa's resolve writes it (storage), the visibility pipeline's
  // visibility pass draws it (colour); one usage for both, as the pool keeps it across modes.
  if (DrawsVisibility(s)) {
    ASSIGN_OR_RETURN(auto* id, get(R::kVisId, kIdFormat, kColor | kSampled | kStorage, "vis_id",
                                   width, height));
    t.vis_id = id->image;
  }
  // The post-AA colour: TAA's, and vis_mlaa's aa_mask view's (its geometric AA is in place).
  if ((vis && s.debug_view == DebugView::kAaMask) || s.aa == AaMode::kTaa) {
    ASSIGN_OR_RETURN(auto* post, get(R::kPostHdr, kHdrFormat,
                                     kColor | kSampled | kCopy | kStorage, "post_hdr",
                                     width, height));
    t.post_hdr = post->image;
  }
  if (s.aa == AaMode::kTaa && moving) {  // the motion pass's target
    ASSIGN_OR_RETURN(auto* motion,
                     get(R::kMotion, kMotionFormat, kColor | kSampled | kCopy, "motion",
                         width, height));
    t.motion = motion->image;
  }
  if (fxaa) {
    ASSIGN_OR_RETURN(auto* fx, get(R::kFxaaColor, compute_ldr ? kLdrComputeFormat : kLdrFormat,
                                   (compute_ldr ? kStorage : kColor) | kCopy, "fxaa", width,
                                   height));
    t.fxaa = fx->image;
  }
  if (s.ssao) {  // half (or full) resolution
    const uint32_t div = s.ssao_half_res ? 2 : 1;
    const uint32_t w = std::max(1u, width / div), h = std::max(1u, height / div);
    ASSIGN_OR_RETURN(auto* ao, get(R::kAo, kAoFormat, kColor | kSampled | kStorage, "ao", w, h));
    t.ao = ao->image;
    ASSIGN_OR_RETURN(auto* temp,
                     get(R::kAoTemp, kAoFormat, kColor | kSampled | kStorage, "ao_temp", w, h));
    t.ao_temp = temp->image;
  }
  if (s.bloom) {
    // From half the frame's size, at least 2^(kBloomLevels - 1) texels a side so every level
    // exists (a tiny frame's bloom is then magnified).
    constexpr uint32_t kMin = 1u << (kBloomLevels - 1);
    const uint32_t w = std::max(kMin, width / 2), h = std::max(kMin, height / 2);
    ASSIGN_OR_RETURN(auto* down, get(R::kBloomDown, kHdrFormat, kColor | kSampled | kStorage,
                                     "bloom_down", w, h, 1, kBloomLevels));
    t.bloom_down = down->image;
    t.bloom_down_levels = down->mips;
    ASSIGN_OR_RETURN(auto* up, get(R::kBloomUp, kHdrFormat, kColor | kSampled | kStorage,
                                   "bloom_up", w, h, 1, kBloomLevels - 1));
    t.bloom_up = up->image;
    t.bloom_up_levels = up->mips;
  }
  targets = t;
  target_pool.Trim(frame);
  readback_ring.Trim(frame);
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
    RETURN_IF_ERROR(MakeBuffer(*ctx, VkDeviceSize(commands) * sizeof(DrawCommand),
                               kListUsage, vk::MemoryUsage::kUpload, "draw_commands",
                               &draw_commands));
    command_capacity = commands;
  }
  const uint32_t counts = 2 * (lists + gpu::kCullStatCount);
  if (counts > count_capacity) {
    RETURN_IF_ERROR(MakeBuffer(*ctx, VkDeviceSize(counts) * 4, kListUsage, vk::MemoryUsage::kUpload,
                               "draw_counts", &draw_counts));
    count_capacity = counts;
  }
  if (lists > base_capacity) {
    RETURN_IF_ERROR(MakeBuffer(*ctx, VkDeviceSize(lists) * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                               vk::MemoryUsage::kDeviceLocal, "cull_bases", &cull_bases));
    base_capacity = lists;
  }
  return absl::OkStatus();
}

Renderer::Impl::ViewState& Renderer::Impl::View(const GpuScene& scene, uint64_t view) {
  constexpr size_t kMaxViewStates = 64;
  const std::pair<uint64_t, uint64_t> key{scene.serial(), view};
  auto it = view_states.find(key);
  if (it == view_states.end()) {
    if (view_states.size() >= kMaxViewStates) DropLeastRecentlyUsed(view_states);
    it = view_states.emplace(key, ViewState{}).first;
  }
  it->second.last_used = ++frame_counter;
  return it->second;
}

absl::StatusOr<Renderer::Impl::ExposureState*> Renderer::Impl::Exposure(const GpuScene& scene,
                                                                        uint64_t view) {
  ViewState& v = View(scene, view);
  if (v.exposure) return v.exposure.get();
  vk::ImageDesc desc;
  desc.format = kExposureFormat;
  desc.usage = VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_SAMPLED_BIT |
               VK_IMAGE_USAGE_TRANSFER_SRC_BIT;  // FrameCapture::exposure_log2
  auto e = std::make_unique<ExposureState>();
  ASSIGN_OR_RETURN(e->image, vk::Image::Create(*ctx, desc, "exposure_state"));
  v.exposure = std::move(e);
  return v.exposure.get();
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
      RETURN_IF_ERROR(MakeBuffer(
          *ctx, bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
          vk::MemoryUsage::kUpload, "visibility_bits", &b));
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

absl::Status Renderer::Impl::EnsureRowBuffer(size_t entries) {
  if (entries <= row_capacity) return absl::OkStatus();
  const uint32_t cap = uint32_t(std::max<size_t>(entries, size_t(row_capacity) * 2));
  RETURN_IF_ERROR(MakeBuffer(*ctx, VkDeviceSize(cap) * 4,
                             VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                             vk::MemoryUsage::kDynamic, "row_lights", &row_lights));
  row_capacity = cap;
  return absl::OkStatus();
}

absl::Status Renderer::Impl::EnsureLightBuffers(uint32_t lights, uint32_t tiles) {
  lights = std::max(lights, 1u);
  tiles = std::max(tiles, 1u);
  if (lights > light_capacity) {
    const uint32_t cap = std::max(lights, light_capacity * 2);
    local_light_texels.Reset();  // before its buffer goes; made again below
    RETURN_IF_ERROR(MakeBuffer(*ctx, VkDeviceSize(cap) * sizeof(gpu::GpuLight),
                               VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                   VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT,
                               vk::MemoryUsage::kDynamic, "local_lights", &local_lights));
    RETURN_IF_ERROR(MakeBuffer(*ctx, VkDeviceSize(cap) * sizeof(gpu::GpuLightBounds),
                               VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                   VK_BUFFER_USAGE_TRANSFER_SRC_BIT,  // captures
                               vk::MemoryUsage::kUpload, "light_bounds", &light_bounds));
    light_capacity = cap;
  }
  if (tiles > tile_capacity) {
    RETURN_IF_ERROR(
        MakeBuffer(*ctx, VkDeviceSize(tiles) * 4,
                   VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                   vk::MemoryUsage::kDeviceLocal, "tile_counts", &tile_counts));
    tile_light_texels.Reset();
    RETURN_IF_ERROR(MakeBuffer(*ctx, VkDeviceSize(tiles) * gpu::kMaxLightsPerTile * 4,
                               VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                   VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT |
                                   VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                               vk::MemoryUsage::kDeviceLocal, "tile_lights", &tile_lights));
    RETURN_IF_ERROR(MakeBuffer(*ctx, VkDeviceSize(tiles) * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                               vk::MemoryUsage::kReadback, "tile_counts_readback",
                               &tile_counts_readback));
    tile_capacity = tiles;
  }
  // The texel views of whatever buffers are kept (also after a failed remake above, which left
  // the old buffer and capacity).
  if (!local_light_texels) {
    ASSIGN_OR_RETURN(local_light_texels,
                     vk::CreateTexelView(*ctx, local_lights, VK_FORMAT_R32G32B32A32_UINT, 16,
                                         "local_light_texels"));
  }
  if (!tile_light_texels) {
    ASSIGN_OR_RETURN(tile_light_texels, vk::CreateTexelView(*ctx, tile_lights, VK_FORMAT_R32_UINT,
                                                            4, "tile_light_texels"));
  }
  return absl::OkStatus();
}

absl::StatusOr<TaaHistory*> Renderer::Impl::Taa(const GpuScene& scene,
                                                                uint64_t view) {
  constexpr size_t kMaxTaaViews = 8;  // frame-sized images: the views that keep them are few
  ViewState& v = View(scene, view);
  if (v.taa && v.taa->images[0].desc().width == targets.width &&
      v.taa->images[0].desc().height == targets.height)
    return v.taa.get();
  if (!v.taa) {  // past the limit, the least recently used other view's history goes
    size_t with_taa = 0;
    ViewState* oldest = nullptr;
    for (auto& [key, state] : view_states) {
      if (!state.taa) continue;
      ++with_taa;
      if (!oldest || state.last_used < oldest->last_used) oldest = &state;
    }
    if (with_taa >= kMaxTaaViews && oldest) oldest->taa.reset();
  }
  auto h = std::make_unique<TaaHistory>();
  for (vk::Image& image : h->images) {
    vk::ImageDesc desc;
    desc.width = targets.width;
    desc.height = targets.height;
    desc.format = kHdrFormat;
    // Storage: TAA writes it in compute (post_stage compute).
    desc.usage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT |
                 VK_IMAGE_USAGE_STORAGE_BIT;
    ASSIGN_OR_RETURN(image, vk::Image::Create(*ctx, desc, "taa_history"));
  }
  v.taa = std::move(h);
  return v.taa.get();
}


VkDescriptorSet Renderer::Impl::WriteSceneSet(const GpuScene& scene, bool shadows, bool ssao,
                                              bool with_ibl) {
  VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  ai.descriptorPool = frame_pool.get();
  ai.descriptorSetCount = 1;
  ai.pSetLayouts = &scene_layout.set_layout;
  VkDescriptorSet set;
  VK_CHECK(vkAllocateDescriptorSets(ctx->device(), &ai, &set));
  constexpr VkDescriptorType kUniform = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
  const vk::Image& atlas = shadows && shadow_atlas ? shadow_atlas : shadow_placeholder;
  const bool on = with_ibl && ibl;
  const VkSampler ibl_sampler = on ? ibl->sampler() : linear_sampler.handle();
  SetWriter(ctx->device(), set)
      .Buffer(gpu::kBindingFrame, frame_ubo.handle(), kUniform)
      .Buffer(gpu::kBindingLights, lights_ubo.handle(), kUniform)
      .Buffer(gpu::kBindingDrawables, scene.drawables().handle())
      .Buffer(gpu::kBindingMaterials, scene.materials().handle())
      .Buffer(gpu::kBindingLocalLights, local_lights.handle())
      .Buffer(gpu::kBindingTileCounts, tile_counts.handle())
      .Buffer(gpu::kBindingTileLights, tile_lights.handle())
      .Buffer(gpu::kBindingShadows, shadow_ubo.handle(), kUniform)
      .Sampled(gpu::kBindingShadowAtlas, shadow_sampler.handle(), atlas.view())
      .Sampled(gpu::kBindingAo, linear_sampler.handle(),
               (ssao ? targets.ao.get() : ao_placeholder).view())
      .Sampled(gpu::kBindingIrradiance, ibl_sampler,
               (on ? ibl->irradiance() : cube_placeholder).view())
      .Sampled(gpu::kBindingSpecular, ibl_sampler,
               (on ? ibl->specular() : cube_placeholder).view())
      .Sampled(gpu::kBindingBrdfLut, ibl_sampler, (on ? ibl->brdf_lut() : ao_placeholder).view())
      .Sampled(gpu::kBindingEnvironment, ibl_sampler,
               (on ? ibl->environment() : cube_placeholder).view())
      .TexelBuffer(gpu::kBindingLocalLightTexels, local_light_texels.get())
      .TexelBuffer(gpu::kBindingTileLightTexels, tile_light_texels.get())
      .Update();
  return set;
}
}  // namespace tessera
