// The renderer's frame targets, buffers and per-view state: made (or grown) when a frame
// first needs them, kept across frames.
#include <bit>
#include <cstring>

#include "renderer/renderer_impl.h"
#include "renderer/status_macros.h"
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
  absl::StatusOr<vk::Buffer> b = vk::Buffer::Create(ctx, size, usage, memory, name);
  if (!b.ok()) return b.status();
  *out = std::move(*b);
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
  absl::StatusOr<vk::Image> atlas = vk::Image::Create(*ctx, desc, "shadow_atlas");
  if (!atlas.ok()) return atlas.status();
  shadow_atlas = std::move(*atlas);
  shadow_faces = std::make_unique<ShadowAtlas>(size);
  shadow_atlas_written = false;
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
  auto make = [&](uint32_t mips, const char* name, vk::Image* image,
                  vk::MipViews* views) -> absl::Status {
    vk::ImageDesc desc;
    desc.width = width;
    desc.height = height;
    desc.format = kHdrFormat;
    desc.mip_levels = mips;
    desc.usage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT;
    ASSIGN_OR_RETURN(*image, vk::Image::Create(*ctx, desc, name));
    ASSIGN_OR_RETURN(*views, vk::MipViews::Create(*ctx, *image, name));
    return absl::OkStatus();
  };
  absl::Status st =
      make(kBloomLevels, "bloom_down", &targets.bloom_down, &targets.bloom_down_levels);
  if (st.ok()) st = make(kBloomLevels - 1, "bloom_up", &targets.bloom_up, &targets.bloom_up_levels);
  if (!st.ok()) {  // all or nothing: the next frame with bloom tries again
    targets.bloom_down_levels = vk::MipViews();
    targets.bloom_up_levels = vk::MipViews();
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
  ASSIGN_OR_RETURN(t.hiz_levels, vk::MipViews::Create(*ctx, *hiz, "hiz"));
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


VkDescriptorSet Renderer::Impl::WriteSceneSet(const GpuScene& scene, bool shadows, bool ssao,
                                              bool with_ibl) {
  VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  ai.descriptorPool = frame_pool.get();
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
}  // namespace tessera
