// Depth prepass: depth of opaque and alpha-mask geometry. Opaque draws use a pipeline with no
// fragment shader (the cheapest path on a CPU rasterizer); alpha-mask draws test the base
// colour alpha so cut-out holes stay open for the shading pass that follows.
#include "renderer/passes/pass.h"
#include "renderer/vk/pipeline.h"

namespace tessera {

namespace {

class DepthPrepass final : public Pass {
 public:
  DepthPrepass(vk::Pipeline opaque, vk::Pipeline mask)
      : opaque_(std::move(opaque)), mask_(std::move(mask)) {}
  PassId id() const override { return PassId::kDepthPrepass; }

  void Record(PassContext& ctx) override {
    VkRenderingAttachmentInfo depth{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    depth.imageView = ctx.targets->depth.view();
    depth.imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
    depth.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
    depth.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    depth.clearValue.depthStencil = {0.0f, 0};  // reverse Z: far is 0
    BeginRendering(ctx, nullptr, &depth);
    if (!ctx.draws->opaque.empty()) {
      BeginSceneDraw(ctx, opaque_.handle());
      RecordDraws(ctx, ctx.draws->opaque, /*textured=*/false);
    }
    if (!ctx.draws->mask.empty()) {
      BeginSceneDraw(ctx, mask_.handle());
      RecordDraws(ctx, ctx.draws->mask);
    }
    vkCmdEndRendering(ctx.cmd);
  }

 private:
  vk::Pipeline opaque_;
  vk::Pipeline mask_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateDepthPrepass(const vk::Context& ctx,
                                                         const SceneLayout& layout) {
  vk::GraphicsPipelineDesc d;
  d.name = "depth_prepass.opaque";
  d.vertex_shader = "depth.vert";
  d.layout = layout.pipeline_layout;
  d.depth_format = kDepthFormat;
  d.depth_test = true;
  d.depth_write = true;
  d.depth_compare = VK_COMPARE_OP_GREATER;
  absl::StatusOr<vk::Pipeline> opaque = vk::CreateGraphicsPipeline(ctx, d);
  if (!opaque.ok()) return opaque.status();
  d.name = "depth_prepass.mask";
  d.vertex_shader = "forward.vert";
  d.fragment_shader = "depth_mask.frag";
  absl::StatusOr<vk::Pipeline> mask = vk::CreateGraphicsPipeline(ctx, d);
  if (!mask.ok()) return mask.status();
  return std::make_unique<DepthPrepass>(std::move(*opaque), std::move(*mask));
}

}  // namespace tessera
