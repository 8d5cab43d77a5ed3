// Geometry culling on the GPU (shaders/cull.comp): one dispatch tests the scene's cull items
// against the view and writes the indirect draw lists and counts the geometry passes consume.
//  - kCull: gpu_frustum (everything in the frustum), or the first gpu_occlusion phase (what
//    the view saw last frame and is still in the frustum);
//  - kCullLate: the second gpu_occlusion phase, against the depth pyramid of the first phase's
//    depth; records this frame's visibility bits.
#include "renderer/passes/pass.h"
#include "renderer/vk/pipeline.h"
#include "renderer/vk/vk_check.h"
#include "shaders/common/gpu_types.h"

namespace tessera {

namespace {

constexpr uint32_t kBindings = 9;

class CullPass final : public Pass {
 public:
  CullPass(PassId id, VkDevice device, PassLayout layout, vk::Pipeline pipeline,
           vk::Sampler sampler)
      : id_(id),
        device_(device),
        layout_(std::move(layout)),
        pipeline_(std::move(pipeline)),
        sampler_(std::move(sampler)) {}
  PassId id() const override { return id_; }

  void Record(PassContext& ctx) override {
    const DrawLists& lists = *ctx.draws;
    const CullBuffers& cb = *ctx.cull;
    const uint32_t phase = id_ == PassId::kCullLate ? 1 : 0;
    const VkDescriptorSet set = layout_.Allocate(ctx);
    const VkDescriptorBufferInfo buffers[kBindings] = {
        {cb.uniforms, cb.uniform_stride * phase, sizeof(gpu::CullUniforms)},
        {ctx.scene->cull_items().handle(), 0, VK_WHOLE_SIZE},
        {ctx.scene->drawables().handle(), 0, VK_WHOLE_SIZE},
        {lists.commands, 0, VK_WHOLE_SIZE},
        {lists.counts, 0, VK_WHOLE_SIZE},
        {cb.bases, 0, VK_WHOLE_SIZE},
        {cb.vis_prev, 0, VK_WHOLE_SIZE},
        {cb.vis_next, 0, VK_WHOLE_SIZE},
        {},
    };
    const VkDescriptorImageInfo hiz{sampler_.handle(), ctx.targets->hiz.view(),
                                    VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    VkWriteDescriptorSet w[kBindings];
    for (uint32_t i = 0; i < kBindings; ++i) {
      w[i] = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
      w[i].dstSet = set;
      w[i].dstBinding = i;
      w[i].descriptorCount = 1;
      w[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
      w[i].pBufferInfo = &buffers[i];
    }
    w[gpu::kCullBindingUniforms].descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
    w[gpu::kCullBindingHiz].descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
    w[gpu::kCullBindingHiz].pBufferInfo = nullptr;
    w[gpu::kCullBindingHiz].pImageInfo = &hiz;
    vkUpdateDescriptorSets(device_, kBindings, w, 0, nullptr);

    // The previous frame drew from these lists and read the statistics on the host; the
    // previous cull wrote the visibility bits.
    vk::CmdMemoryBarrier(ctx.cmd,
                  VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT | VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT |
                      VK_PIPELINE_STAGE_2_HOST_BIT,
                  VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT | VK_ACCESS_2_HOST_WRITE_BIT,
                  VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT,
                  VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT |
                      VK_ACCESS_2_TRANSFER_WRITE_BIT);
    const uint32_t lists_per_phase = uint32_t(ctx.scene->segments().size() +
                                              ctx.scene->batches().size());
    vkCmdFillBuffer(ctx.cmd, lists.counts, lists.CountOffset(phase, lists_per_phase),
                    gpu::kCullStatCount * sizeof(uint32_t), 0);
    if (phase == 1) vkCmdFillBuffer(ctx.cmd, cb.vis_next, 0, VK_WHOLE_SIZE, 0);
    vk::CmdMemoryBarrier(ctx.cmd, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                  VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                  VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);

    vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_.handle());
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout_.pipeline_layout(), 0,
                            1, &set, 0, nullptr);
    vkCmdDispatch(ctx.cmd, 1, 1, 1);  // one workgroup: the lists come out in item order

    // Lists -> the indirect draws; statistics -> the host; visibility bits -> the next cull.
    vk::CmdMemoryBarrier(ctx.cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                  VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                  VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT | VK_PIPELINE_STAGE_2_HOST_BIT |
                      VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                  VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT | VK_ACCESS_2_HOST_READ_BIT |
                      VK_ACCESS_2_SHADER_STORAGE_READ_BIT);
  }

 private:
  PassId id_;
  VkDevice device_;
  PassLayout layout_;
  vk::Pipeline pipeline_;
  vk::Sampler sampler_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateCullPass(const vk::Context& ctx, PassId id) {
  std::vector<VkDescriptorSetLayoutBinding> bindings(kBindings);
  for (uint32_t i = 0; i < kBindings; ++i)
    bindings[i] = {i, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr};
  bindings[gpu::kCullBindingUniforms].descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
  bindings[gpu::kCullBindingHiz].descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
  absl::StatusOr<PassLayout> layout = PassLayout::Create(ctx, bindings, {}, "cull layout");
  if (!layout.ok()) return layout.status();
  const char* name = id == PassId::kCullLate ? "cull_late" : "cull";
  absl::StatusOr<vk::Pipeline> pipeline =
      vk::CreateComputePipeline(ctx, name, "cull.comp", layout->pipeline_layout());
  VkSamplerCreateInfo si{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
  si.magFilter = si.minFilter = VK_FILTER_NEAREST;
  si.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST;
  si.maxLod = VK_LOD_CLAMP_NONE;
  si.addressModeU = si.addressModeV = si.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
  absl::StatusOr<vk::Sampler> sampler = vk::Sampler::Create(ctx, si, "cull.hiz_sampler");
  if (!pipeline.ok()) return pipeline.status();
  if (!sampler.ok()) return sampler.status();
  return std::make_unique<CullPass>(id, ctx.device(), std::move(*layout), std::move(*pipeline),
                                    std::move(*sampler));
}

}  // namespace tessera
