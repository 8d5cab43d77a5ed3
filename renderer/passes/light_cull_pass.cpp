// Light culling (forward+): one compute dispatch builds every tile's light list from the
// prepass depth and the per-light bounds the CPU prepared; a buffer barrier then hands the
// lists to the fragment shaders, and the counts are copied out for the frame's statistics.
#include "renderer/passes/pass.h"
#include "renderer/vk/pipeline.h"
#include "renderer/vk/vk_check.h"
#include "shaders/common/gpu_types.h"

namespace tessera {

namespace {

class LightCullPass final : public Pass {
 public:
  LightCullPass(VkDevice device, PassLayout layout, vk::Pipeline pipeline, vk::Sampler sampler)
      : device_(device),
        layout_(std::move(layout)),
        pipeline_(std::move(pipeline)),
        sampler_(std::move(sampler)) {}
  PassId id() const override { return PassId::kLightCull; }

  void Record(PassContext& ctx) override {
    const LightCullBuffers& lb = *ctx.light_buffers;
    const VkDescriptorSet set = layout_.Allocate(ctx);
    const VkDescriptorBufferInfo frame{lb.frame_ubo, 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo bounds{lb.bounds, 0, VK_WHOLE_SIZE};
    const VkDescriptorImageInfo depth{sampler_.handle(), ctx.targets->depth.view(),
                                      VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    const VkDescriptorBufferInfo counts{lb.tile_counts, 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo lists{lb.tile_lights, 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo rows{lb.row_lights, 0, VK_WHOLE_SIZE};
    VkWriteDescriptorSet w[6];
    for (uint32_t i = 0; i < 6; ++i) {
      w[i] = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
      w[i].dstSet = set;
      w[i].dstBinding = i;
      w[i].descriptorCount = 1;
      w[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    }
    w[gpu::kCullBindingFrame].descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
    w[gpu::kCullBindingFrame].pBufferInfo = &frame;
    w[gpu::kCullBindingLightBounds].pBufferInfo = &bounds;
    w[gpu::kCullBindingDepth].descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
    w[gpu::kCullBindingDepth].pImageInfo = &depth;
    w[gpu::kCullBindingTileCounts].pBufferInfo = &counts;
    w[gpu::kCullBindingTileLights].pBufferInfo = &lists;
    w[gpu::kCullBindingRowLights].pBufferInfo = &rows;
    vkUpdateDescriptorSets(device_, 6, w, 0, nullptr);

    // The previous frame's shading read these buffers: finish before they are rewritten.
    VkBufferMemoryBarrier2 before[2];
    for (int i = 0; i < 2; ++i) {
      before[i] = {VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER_2};
      before[i].srcStageMask =
          VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_2_COPY_BIT;
      before[i].srcAccessMask = VK_ACCESS_2_NONE;
      before[i].dstStageMask = VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;
      before[i].dstAccessMask = VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT;
      before[i].srcQueueFamilyIndex = before[i].dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
      before[i].size = VK_WHOLE_SIZE;
    }
    before[0].buffer = lb.tile_counts;
    before[1].buffer = lb.tile_lights;
    vk::CmdBarrier(ctx.cmd, nullptr, 0, before, 2);

    vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_.handle());
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout_.pipeline_layout(), 0,
                            1, &set, 0, nullptr);
    vkCmdDispatch(ctx.cmd, (lb.tiles + gpu::kLightCullGroupSize - 1) / gpu::kLightCullGroupSize, 1,
                  1);

    // Lists and counts -> the fragment shaders; counts -> the copy for the statistics.
    VkBufferMemoryBarrier2 after[2];
    for (int i = 0; i < 2; ++i) {
      after[i] = {VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER_2};
      after[i].srcStageMask = VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;
      after[i].srcAccessMask = VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT;
      after[i].dstStageMask =
          VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_2_COPY_BIT;
      after[i].dstAccessMask = VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_TRANSFER_READ_BIT;
      after[i].srcQueueFamilyIndex = after[i].dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
      after[i].size = VK_WHOLE_SIZE;
    }
    after[0].buffer = lb.tile_counts;
    after[1].buffer = lb.tile_lights;
    vk::CmdBarrier(ctx.cmd, nullptr, 0, after, 2);
    const VkBufferCopy copy{0, 0, VkDeviceSize(lb.tiles) * sizeof(uint32_t)};
    vkCmdCopyBuffer(ctx.cmd, lb.tile_counts, lb.counts_readback, 1, &copy);
    VkBufferMemoryBarrier2 host{VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER_2};
    host.srcStageMask = VK_PIPELINE_STAGE_2_COPY_BIT;
    host.srcAccessMask = VK_ACCESS_2_TRANSFER_WRITE_BIT;
    host.dstStageMask = VK_PIPELINE_STAGE_2_HOST_BIT;
    host.dstAccessMask = VK_ACCESS_2_HOST_READ_BIT;
    host.srcQueueFamilyIndex = host.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    host.buffer = lb.counts_readback;
    host.size = VK_WHOLE_SIZE;
    vk::CmdBarrier(ctx.cmd, nullptr, 0, &host, 1);
  }

 private:
  VkDevice device_;
  PassLayout layout_;
  vk::Pipeline pipeline_;
  vk::Sampler sampler_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateLightCullPass(const vk::Context& ctx) {
  const std::vector<VkDescriptorSetLayoutBinding> bindings = {
      {gpu::kCullBindingFrame, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1, VK_SHADER_STAGE_COMPUTE_BIT,
       nullptr},
      {gpu::kCullBindingLightBounds, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1,
       VK_SHADER_STAGE_COMPUTE_BIT, nullptr},
      {gpu::kCullBindingDepth, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
       VK_SHADER_STAGE_COMPUTE_BIT, nullptr},
      {gpu::kCullBindingTileCounts, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1,
       VK_SHADER_STAGE_COMPUTE_BIT, nullptr},
      {gpu::kCullBindingTileLights, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1,
       VK_SHADER_STAGE_COMPUTE_BIT, nullptr},
      {gpu::kCullBindingRowLights, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1,
       VK_SHADER_STAGE_COMPUTE_BIT, nullptr},
  };
  absl::StatusOr<PassLayout> layout = PassLayout::Create(ctx, bindings, {}, "light cull layout");
  if (!layout.ok()) return layout.status();
  absl::StatusOr<vk::Pipeline> pipeline = vk::CreateComputePipeline(
      ctx, "light_cull", "light_cull.comp", layout->pipeline_layout());
  VkSamplerCreateInfo si{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
  si.magFilter = si.minFilter = VK_FILTER_NEAREST;
  si.addressModeU = si.addressModeV = si.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
  absl::StatusOr<vk::Sampler> sampler = vk::Sampler::Create(ctx, si, "light_cull.depth_sampler");
  if (!pipeline.ok()) return pipeline.status();
  if (!sampler.ok()) return sampler.status();
  return std::make_unique<LightCullPass>(ctx.device(), std::move(*layout), std::move(*pipeline),
                                         std::move(*sampler));
}

}  // namespace tessera
