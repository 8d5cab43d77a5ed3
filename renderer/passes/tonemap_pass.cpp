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
  TonemapPass(const vk::Context& ctx, PassLayout layout, vk::Pipeline pipeline,
              vk::Sampler sampler)
      : device_(ctx.device()),
        layout_(std::move(layout)),
        pipeline_(std::move(pipeline)),
        sampler_(std::move(sampler)) {}
  PassId id() const override { return PassId::kTonemap; }

  void Record(PassContext& ctx) override {
    const VkDescriptorSet set = layout_.Allocate(ctx);
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
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout_.pipeline_layout(),
                            0, 1, &set, 0, nullptr);
    vkCmdSetCullMode(ctx.cmd, VK_CULL_MODE_NONE);
    const TonemapPush push{std::exp2(ctx.settings->exposure_ev),
                           ctx.settings->debug_view != DebugView::kNone ? 1u : 0u};
    vkCmdPushConstants(ctx.cmd, layout_.pipeline_layout(), VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof(push), &push);
    vkCmdDraw(ctx.cmd, 3, 1, 0, 0);  // one full-screen triangle
    vkCmdEndRendering(ctx.cmd);
  }

 private:
  VkDevice device_;
  PassLayout layout_;
  vk::Pipeline pipeline_;
  vk::Sampler sampler_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateTonemapPass(const vk::Context& ctx) {
  absl::StatusOr<PassLayout> layout = PassLayout::Create(
      ctx,
      {{0, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, nullptr}},
      {{VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof(TonemapPush)}}, "tonemap layout");
  if (!layout.ok()) return layout.status();
  vk::GraphicsPipelineDesc d;
  d.name = "tonemap";
  d.vertex_shader = "fullscreen.vert";
  d.fragment_shader = "tonemap.frag";
  d.layout = layout->pipeline_layout();
  d.scene_vertex_input = false;
  d.color_formats = {kLdrFormat};
  absl::StatusOr<vk::Pipeline> pipeline = vk::CreateGraphicsPipeline(ctx, d);
  VkSamplerCreateInfo si{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
  si.magFilter = si.minFilter = VK_FILTER_NEAREST;
  si.addressModeU = si.addressModeV = si.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
  absl::StatusOr<vk::Sampler> sampler = vk::Sampler::Create(ctx, si, "tonemap.sampler");
  if (!pipeline.ok()) return pipeline.status();
  if (!sampler.ok()) return sampler.status();
  return std::make_unique<TonemapPass>(ctx, std::move(*layout), std::move(*pipeline),
                                       std::move(*sampler));
}

}  // namespace tessera
