// Forward PBR shading (glTF metallic-roughness BRDF) in two passes that share one shader:
//  - forward: opaque and alpha-mask geometry, depth-tested GREATER_OR_EQUAL against the
//    prepass depth with writes off, so each visible pixel is shaded once;
//    Then the sky fills the pixels no surface covered (a full-screen triangle at the far plane);
//  - transparent: blended materials sorted back to front, over the opaque result.
// Draws are indirect: one vkCmdDrawIndexedIndirectCount per segment (render group x cull mode x
// material; see DrawPlan) and culling phase. The material is a descriptor set per segment
// because lavapipe cannot index samplers dynamically (shaders/common/gpu_types.h).
#include "renderer/passes/pass.h"
#include "renderer/vk/pipeline.h"

namespace tessera {

namespace {

// Linear HDR background behind the scene.
constexpr VkClearColorValue kBackground{{0.030f, 0.034f, 0.042f, 1.0f}};

class ForwardPass final : public Pass {
 public:
  ForwardPass(PassId id, vk::Pipeline pipeline, vk::Pipeline sky)
      : id_(id), pipeline_(std::move(pipeline)), sky_(std::move(sky)) {}
  PassId id() const override { return id_; }

  void Record(PassContext& ctx) override {
    const bool transparent = id_ == PassId::kTransparent;
    VkRenderingAttachmentInfo color{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    color.imageView = ctx.targets->hdr.view();
    color.imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
    color.loadOp = transparent ? VK_ATTACHMENT_LOAD_OP_LOAD : VK_ATTACHMENT_LOAD_OP_CLEAR;
    color.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    color.clearValue.color = kBackground;
    VkRenderingAttachmentInfo depth{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    depth.imageView = ctx.targets->depth.view();
    depth.imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
    depth.loadOp = VK_ATTACHMENT_LOAD_OP_LOAD;
    depth.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    BeginRendering(ctx, &color, &depth);
    BeginSceneDraw(ctx, pipeline_.handle());
    const uint32_t phases = ctx.draws->phases;
    if (transparent) {
      RecordSegments(ctx, AlphaMode::kBlend, 0, phases);
    } else {
      RecordSegments(ctx, AlphaMode::kOpaque, 0, phases);
      RecordSegments(ctx, AlphaMode::kMask, 0, phases);
      // Debug views keep the plain background, so their values read cleanly.
      if (ctx.settings->debug_view == DebugView::kNone) {
        vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, sky_.handle());
        vkCmdSetCullMode(ctx.cmd, VK_CULL_MODE_NONE);
        vkCmdDraw(ctx.cmd, 3, 1, 0, 0);
      }
    }
    vkCmdEndRendering(ctx.cmd);
  }

 private:
  PassId id_;
  vk::Pipeline pipeline_;
  vk::Pipeline sky_;  // forward only
};

absl::StatusOr<std::unique_ptr<Pass>> Create(const vk::Context& ctx, const SceneLayout& layout,
                                             PassId id) {
  const bool transparent = id == PassId::kTransparent;
  vk::GraphicsPipelineDesc d;
  d.name = transparent ? "transparent" : "forward";
  d.vertex_shader = "forward.vert";
  d.fragment_shader = "forward.frag";
  d.layout = layout.pipeline_layout;
  d.color_formats = {kHdrFormat};
  d.depth_format = kDepthFormat;
  d.depth_test = true;
  d.depth_write = false;
  d.depth_compare = VK_COMPARE_OP_GREATER_OR_EQUAL;
  d.blend = transparent ? vk::BlendMode::kAlpha : vk::BlendMode::kNone;
  absl::StatusOr<vk::Pipeline> pipeline = vk::CreateGraphicsPipeline(ctx, d);
  if (!pipeline.ok()) return pipeline.status();
  vk::Pipeline sky;
  if (!transparent) {
    // Far plane is depth 0: GREATER_OR_EQUAL passes only where the prepass left the clear value.
    d.name = "sky";
    d.vertex_shader = "fullscreen.vert";
    d.fragment_shader = "sky.frag";
    d.scene_vertex_input = false;
    d.blend = vk::BlendMode::kNone;
    absl::StatusOr<vk::Pipeline> s = vk::CreateGraphicsPipeline(ctx, d);
    if (!s.ok()) return s.status();
    sky = std::move(*s);
  }
  return std::make_unique<ForwardPass>(id, std::move(*pipeline), std::move(sky));
}

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateForwardPass(const vk::Context& ctx,
                                                        const SceneLayout& layout) {
  return Create(ctx, layout, PassId::kForward);
}

absl::StatusOr<std::unique_ptr<Pass>> CreateTransparentPass(const vk::Context& ctx,
                                                            const SceneLayout& layout) {
  return Create(ctx, layout, PassId::kTransparent);
}

}  // namespace tessera
