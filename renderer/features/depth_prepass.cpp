// Depth prepass: depth of opaque and alpha-mask geometry. Opaque draws use a pipeline with no
// fragment shader (the cheapest path on a CPU rasterizer) and need no material, so the whole
// opaque group is one indirect draw per cull mode; alpha-mask draws test the base colour alpha
// so cut-out holes stay open for the shading pass that follows (one indirect draw per
// material). With gpu_occlusion the pass runs twice: kDepthPrepass draws the first phase's
// lists into a cleared depth, kDepthPrepassLate adds the second phase's. With msaa it draws
// into the multisampled depth and resolves it into the frame's depth.
#include "common/status_macros.h"
#include "renderer/features/features.h"
#include "renderer/features/pass.h"
#include "renderer/vk/pipeline.h"

namespace tessera {

namespace {

struct PrepassPipelines {
  vk::Pipeline opaque, mask;
};

absl::StatusOr<PrepassPipelines> CreatePipelines(const vk::Context& ctx,
                                                 const SceneLayout& layout, uint32_t samples) {
  vk::GraphicsPipelineDesc d;
  d.name = "depth_prepass.opaque";
  d.vertex_shader = "depth.vert";
  d.layout = layout.pipeline_layout;
  d.depth_format = kDepthFormat;
  d.depth_test = true;
  d.depth_write = true;
  d.depth_compare = VK_COMPARE_OP_GREATER;
  d.samples = static_cast<VkSampleCountFlagBits>(samples);
  ASSIGN_OR_RETURN(vk::Pipeline opaque, vk::CreateGraphicsPipeline(ctx, d));
  d.name = "depth_prepass.mask";
  d.vertex_shader = "forward.vert";
  d.fragment_shader = "depth_mask.frag";
  absl::StatusOr<vk::Pipeline> mask = vk::CreateGraphicsPipeline(ctx, d);
  if (!mask.ok()) return mask.status();
  return PrepassPipelines{std::move(opaque), std::move(*mask)};
}

class DepthPrepass final : public Pass {
 public:
  DepthPrepass(PassId id, const SceneLayout& layout) : id_(id), layout_(layout) {}
  PassId id() const override { return id_; }

  absl::Status Prepare(const vk::Context& ctx, const Settings& s) override {
    return pipelines_.Ensure(s.aa == AaMode::kMsaa ? s.samples : 1, [&](uint32_t samples) {
      return CreatePipelines(ctx, layout_, samples);
    });
  }

  void Record(PassContext& ctx) override {
    const uint32_t samples = ForwardSamples(ctx);
    const PrepassPipelines& p = pipelines_.at(samples);
    VkRenderingAttachmentInfo depth{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    depth.imageView = samples > 1 ? ctx.targets->depth_ms.view() : ctx.targets->depth.view();
    depth.imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
    const bool late = id_ == PassId::kDepthPrepassLate;
    const uint32_t phase = late ? 1 : 0;
    depth.loadOp = late ? VK_ATTACHMENT_LOAD_OP_LOAD : VK_ATTACHMENT_LOAD_OP_CLEAR;
    depth.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    depth.clearValue.depthStencil = {0.0f, 0};  // reverse Z: far is 0
    if (samples > 1) ResolveDepthInto(ctx, depth);  // light culling, the pyramid read it
    BeginRendering(ctx, nullptr, &depth);
    RecordDepthGeometry(ctx, p.opaque.handle(), p.mask.handle(), phase);
    vkCmdEndRendering(ctx.cmd);
  }

 private:
  PassId id_;
  SceneLayout layout_;
  PerSampleCount<PrepassPipelines> pipelines_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateDepthPrepass(const vk::Context& ctx,
                                                         const SceneLayout& layout, PassId id) {
  auto pass = std::make_unique<DepthPrepass>(id, layout);
  if (absl::Status st = pass->Prepare(ctx, Settings{}); !st.ok()) return st;  // 1x, always used
  return pass;
}

absl::StatusOr<vk::Pipeline> CreateIdPipeline(const vk::Context& ctx, const SceneLayout& layout) {
  vk::GraphicsPipelineDesc d;
  d.name = "drawable_ids";
  d.vertex_shader = "id.vert";
  d.fragment_shader = "id.frag";
  d.layout = layout.pipeline_layout;
  d.color_formats = {kIdFormat};
  d.attribute_mask = gpu::kAlphaMaskAttributes;
  d.depth_format = kDepthFormat;
  d.depth_test = true;
  d.depth_write = false;
  d.depth_compare = VK_COMPARE_OP_GREATER_OR_EQUAL;
  return vk::CreateGraphicsPipeline(ctx, d);
}

void AddDepthPass(GraphBuilder& b, bool late) {
  // vis_mlaa's and the visibility pipeline's visibility pass is their depth pass.
  if (DrawsVisibility(b.settings())) {
    AddVisibilityPass(b, late);
    return;
  }
  b.Pass(late ? PassId::kDepthPrepassLate : PassId::kDepthPrepass)
      .Use(Resource::kDrawLists, Access::kIndirectRead)
      .UseIfPresent(Resource::kPosedGeometry, Access::kGeometryRead);
  if (b.settings().aa == AaMode::kMsaa) {
    b.Use(Resource::kDepthMs, Access::kDepthWrite).Use(Resource::kDepth, Access::kDepthResolve);
  } else {
    b.Use(Resource::kDepth, Access::kDepthWrite);
  }
}

void SetupDepth(GraphBuilder& b) { AddDepthPass(b, /*late=*/false); }

}  // namespace tessera
