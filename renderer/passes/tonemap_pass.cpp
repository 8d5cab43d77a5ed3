// Tonemap: HDR colour -> exposure -> Khronos PBR Neutral tonemapper -> sRGB RGBA8 (the
// attachment's sRGB format does the encoding). PBR Neutral keeps base colours true under
// neutral light, which is what product and sample-model renders are judged by. Debug views
// pass through without tonemapping.
#include <cmath>

#include "renderer/passes/pass.h"
#include "renderer/vk/pipeline.h"
#include "renderer/vk/vk_check.h"

namespace tessera {

namespace {

struct TonemapPush {
  float exposure;        // linear multiplier, 2^exposure_ev
  uint32_t passthrough;  // 1 for debug views
};

class TonemapPass final : public Pass {
 public:
  TonemapPass(const vk::Context& ctx, VkDescriptorSetLayout set_layout, VkPipelineLayout layout,
              vk::Pipeline pipeline, vk::Sampler sampler)
      : device_(ctx.device()),
        set_layout_(set_layout),
        layout_(layout),
        pipeline_(std::move(pipeline)),
        sampler_(std::move(sampler)) {}
  ~TonemapPass() override {
    vkDestroyPipelineLayout(device_, layout_, nullptr);
    vkDestroyDescriptorSetLayout(device_, set_layout_, nullptr);
  }
  PassId id() const override { return PassId::kTonemap; }

  void Record(PassContext& ctx) override {
    VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    ai.descriptorPool = ctx.frame_pool;
    ai.descriptorSetCount = 1;
    ai.pSetLayouts = &set_layout_;
    VkDescriptorSet set;
    VK_CHECK(vkAllocateDescriptorSets(device_, &ai, &set));
    const VkDescriptorImageInfo image{sampler_.handle(), ctx.targets->hdr.view(),
                                      VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    w.dstSet = set;
    w.dstBinding = 0;
    w.descriptorCount = 1;
    w.descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
    w.pImageInfo = &image;
    vkUpdateDescriptorSets(device_, 1, &w, 0, nullptr);

    VkRenderingAttachmentInfo color{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    color.imageView = ctx.targets->ldr.view();
    color.imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
    color.loadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;  // every pixel is written
    color.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    BeginRendering(ctx, &color, nullptr);
    vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline_.handle());
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout_, 0, 1, &set, 0,
                            nullptr);
    vkCmdSetCullMode(ctx.cmd, VK_CULL_MODE_NONE);
    const TonemapPush push{std::exp2(ctx.settings->exposure_ev),
                           ctx.settings->debug_view != DebugView::kNone ? 1u : 0u};
    vkCmdPushConstants(ctx.cmd, layout_, VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof(push), &push);
    vkCmdDraw(ctx.cmd, 3, 1, 0, 0);  // one full-screen triangle
    vkCmdEndRendering(ctx.cmd);
  }

 private:
  VkDevice device_;
  VkDescriptorSetLayout set_layout_;
  VkPipelineLayout layout_;
  vk::Pipeline pipeline_;
  vk::Sampler sampler_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateTonemapPass(const vk::Context& ctx) {
  VkDescriptorSetLayoutBinding binding{0, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
                                       VK_SHADER_STAGE_FRAGMENT_BIT, nullptr};
  VkDescriptorSetLayoutCreateInfo li{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  li.bindingCount = 1;
  li.pBindings = &binding;
  VkDescriptorSetLayout set_layout;
  VK_RETURN_IF_ERROR(vkCreateDescriptorSetLayout(ctx.device(), &li, nullptr, &set_layout),
                     "tonemap set layout");
  const VkPushConstantRange push{VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof(TonemapPush)};
  VkPipelineLayoutCreateInfo pli{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  pli.setLayoutCount = 1;
  pli.pSetLayouts = &set_layout;
  pli.pushConstantRangeCount = 1;
  pli.pPushConstantRanges = &push;
  VkPipelineLayout layout;
  VkResult r = vkCreatePipelineLayout(ctx.device(), &pli, nullptr, &layout);
  if (r != VK_SUCCESS) {
    vkDestroyDescriptorSetLayout(ctx.device(), set_layout, nullptr);
    return vk::VkStatus(r, "tonemap pipeline layout");
  }
  vk::GraphicsPipelineDesc d;
  d.name = "tonemap";
  d.vertex_shader = "fullscreen.vert";
  d.fragment_shader = "tonemap.frag";
  d.layout = layout;
  d.scene_vertex_input = false;
  d.color_formats = {kLdrFormat};
  absl::StatusOr<vk::Pipeline> pipeline = vk::CreateGraphicsPipeline(ctx, d);
  VkSamplerCreateInfo si{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
  si.magFilter = si.minFilter = VK_FILTER_NEAREST;
  si.addressModeU = si.addressModeV = si.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
  absl::StatusOr<vk::Sampler> sampler = vk::Sampler::Create(ctx, si, "tonemap.sampler");
  if (!pipeline.ok() || !sampler.ok()) {
    vkDestroyPipelineLayout(ctx.device(), layout, nullptr);
    vkDestroyDescriptorSetLayout(ctx.device(), set_layout, nullptr);
    return !pipeline.ok() ? pipeline.status() : sampler.status();
  }
  return std::make_unique<TonemapPass>(ctx, set_layout, layout, std::move(*pipeline),
                                       std::move(*sampler));
}

}  // namespace tessera
