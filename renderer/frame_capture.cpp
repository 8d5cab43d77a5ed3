// Test captures (FrameCapture): after a frame, copies what the tests check against CPU
// references back to the host. Costs an extra submit and wait; never used by the service.
#include <cstring>
#include <glm/gtc/packing.hpp>
#include <limits>

#include "common/status_macros.h"
#include "renderer/renderer_impl.h"
#include "renderer/vk/vk_check.h"

namespace tessera {

absl::Status Renderer::Impl::CaptureFrame(FrameData& f, const FramePlan& plan,
                                          const PassContext& pc, FrameCapture* capture) {
  const Access depth_access = plan.FinalAccess(Resource::kDepth);
  if (capture->want_ids) RETURN_IF_ERROR(CaptureIds(f.gs, f.scene_set, depth_access, capture));
  // The tonemap's input as the post passes left it; CaptureIds left the depth in the
  // depth-test layout.
  RETURN_IF_ERROR(Capture(capture, f.tiled ? &f.light_buffers : nullptr, PostColor(pc),
                          plan.FinalAccess(plan.scene_color),
                          capture->want_ids ? Access::kDepthTest : depth_access, f.exposure.state,
                          plan.Has(PassId::kMotion) ? &targets.motion.get() : nullptr,
                          plan.FinalAccess(Resource::kMotion)));
  capture->local_lights = f.local;
  capture->view = f.fu.view;
  capture->proj = f.fu.proj;
  return absl::OkStatus();
}

// After a frame (tests): draws every drawable, unculled, into an id target against the
// frame's depth, so the ids on top are the truly visible drawables.
absl::Status Renderer::Impl::CaptureIds(const GpuScene& scene, VkDescriptorSet scene_set,
                                        Access depth_access, FrameCapture* capture) {
  if (!id_pipeline.handle()) {
    ASSIGN_OR_RETURN(vk::Pipeline p, CreateIdPipeline(*ctx, scene_layout));
    id_pipeline = std::move(p);
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
  executor->BeginOneTime();
  const VkCommandBuffer cmd = executor->cmd();
  VkImageMemoryBarrier2 to_color =
      vk::MakeImageBarrier(*ids, Between(Access::kNone, Access::kColorWrite));
  VkImageMemoryBarrier2 depth_ready =
      vk::MakeImageBarrier(targets.depth, Between(depth_access, Access::kDepthTest));
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
  VkImageMemoryBarrier2 to_src =
      vk::MakeImageBarrier(*ids, Between(Access::kColorWrite, Access::kTransferSrc));
  vk::CmdBarrier(cmd, &to_src, 1);
  VkBufferImageCopy region{};
  region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  region.imageExtent = {targets.width, targets.height, 1};
  vkCmdCopyImageToBuffer(cmd, ids->handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, host->handle(),
                         1, &region);
  RETURN_IF_ERROR(executor->SubmitAndWait(/*host_read=*/true));
  host->InvalidateForRead();
  const auto* p = static_cast<const uint32_t*>(host->mapped());
  capture->ids.assign(p, p + size_t(targets.width) * targets.height);
  return absl::OkStatus();
}

// After a frame: copies the prepass depth, the HDR colour, the exposure and, when the light
// culling ran (`lights`), its tile lists, light bounds and row bins to the host (tests only).
absl::Status Renderer::Impl::Capture(FrameCapture* capture, const LightCullBuffers* lights,
                                     const vk::Image& hdr, Access hdr_access,
                                     Access depth_access, const vk::Image* exposure,
                                     const vk::Image* motion, Access motion_access) {
  const uint32_t tiles = lights ? lights->tiles : 0;
  const VkDeviceSize depth_bytes = VkDeviceSize(targets.width) * targets.height * 4;
  const VkDeviceSize count_bytes = VkDeviceSize(tiles) * 4;
  const VkDeviceSize list_bytes = count_bytes * gpu::kMaxLightsPerTile;
  const VkDeviceSize hdr_bytes = depth_bytes * 2;  // RGBA16F
  // RGBA16F copies want offsets in whole texels: 16-byte aligned.
  const VkDeviceSize hdr_at = (depth_bytes + count_bytes + list_bytes + 15) & ~VkDeviceSize(15);
  const VkDeviceSize exposure_at = hdr_at + hdr_bytes;
  const VkDeviceSize bounds_at = exposure_at + 16;
  const VkDeviceSize bounds_bytes =
      lights ? VkDeviceSize(lights->lights) * sizeof(gpu::GpuLightBounds) : 0;
  const VkDeviceSize rows_at = bounds_at + bounds_bytes;
  const VkDeviceSize row_bytes = lights ? VkDeviceSize(lights->row_entries) * 4 : 0;
  const VkDeviceSize motion_at = rows_at + row_bytes;  // RG16F: 4-byte texels
  const VkDeviceSize motion_bytes = motion ? depth_bytes : 0;
  ASSIGN_OR_RETURN(vk::Buffer host, vk::Buffer::Create(*ctx, motion_at + motion_bytes,
                                                       VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                                       vk::MemoryUsage::kReadback, "capture"));
  executor->BeginOneTime();
  const VkCommandBuffer cmd = executor->cmd();
  VkImageMemoryBarrier2 b[2] = {
      vk::MakeImageBarrier(targets.depth, Between(depth_access, Access::kTransferSrc)),
      vk::MakeImageBarrier(hdr, Between(hdr_access, Access::kTransferSrc))};
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
                         host.handle(), 1, &region);
  region.bufferOffset = hdr_at;
  region.imageSubresource.aspectMask = VK_IMAGE_ASPECT_COLOR_BIT;
  vkCmdCopyImageToBuffer(cmd, hdr.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, host.handle(), 1,
                         &region);
  if (exposure) {  // from the general layout and back
    VkImageMemoryBarrier2 eb = vk::MakeImageBarrier(
        *exposure, {VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, VK_ACCESS_2_MEMORY_WRITE_BIT,
                    VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_2_COPY_BIT,
                    VK_ACCESS_2_TRANSFER_READ_BIT, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL});
    vk::CmdBarrier(cmd, &eb, 1);
    region.bufferOffset = exposure_at;
    region.imageExtent = {1, 1, 1};
    vkCmdCopyImageToBuffer(cmd, exposure->handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                           host.handle(), 1, &region);
    eb = vk::MakeImageBarrier(
        *exposure, {VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_NONE,
                    VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                    VK_ACCESS_2_NONE, VK_IMAGE_LAYOUT_GENERAL});
    vk::CmdBarrier(cmd, &eb, 1);
  }
  if (motion) {
    const VkImageMemoryBarrier2 mb =
        vk::MakeImageBarrier(*motion, Between(motion_access, Access::kTransferSrc));
    vk::CmdBarrier(cmd, &mb, 1);
    region.bufferOffset = motion_at;
    region.imageExtent = {targets.width, targets.height, 1};
    vkCmdCopyImageToBuffer(cmd, motion->handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                           host.handle(), 1, &region);
  }
  if (lights) {  // the lists exist only when the light-culling pass ran
    const VkBufferCopy copies[4] = {{0, depth_bytes, count_bytes},
                                    {0, depth_bytes + count_bytes, list_bytes},
                                    {0, bounds_at, bounds_bytes},
                                    {0, rows_at, row_bytes}};
    const VkBuffer sources[4] = {lights->tile_counts, lights->tile_lights, lights->bounds,
                                 lights->row_lights};
    for (int i = 0; i < 4; ++i)
      if (copies[i].size > 0) vkCmdCopyBuffer(cmd, sources[i], host.handle(), 1, &copies[i]);
  }
  RETURN_IF_ERROR(executor->SubmitAndWait(/*host_read=*/true));
  host.InvalidateForRead();
  const auto* bytes = static_cast<const uint8_t*>(host.mapped());
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
  capture->light_bounds.resize(bounds_bytes / sizeof(gpu::GpuLightBounds));
  std::memcpy(capture->light_bounds.data(), bytes + bounds_at, bounds_bytes);
  capture->row_lights.resize(row_bytes / 4);
  std::memcpy(capture->row_lights.data(), bytes + rows_at, row_bytes);
  capture->motion.resize(motion ? size_t(targets.width) * targets.height : 0);
  const auto* motion_halves = reinterpret_cast<const uint16_t*>(bytes + motion_at);
  for (size_t i = 0; i < capture->motion.size(); ++i)
    capture->motion[i] = glm::vec2(glm::unpackHalf1x16(motion_halves[2 * i]),
                                   glm::unpackHalf1x16(motion_halves[2 * i + 1]));
  return absl::OkStatus();
}


}  // namespace tessera
