// Forward PBR shading (glTF metallic-roughness BRDF) in two passes that share one shader:
//  - forward: opaque and alpha-mask geometry, depth-tested GREATER_OR_EQUAL against the
//    prepass depth with writes off, so each visible pixel is shaded once;
//    Then the sky fills the pixels no surface covered (a full-screen triangle at the far plane);
//  - transparent: blended materials sorted back to front, over the opaque result.
// Draws are indirect: one vkCmdDrawIndexedIndirectCount per segment (render group x cull mode x
// material; see DrawPlan) and culling phase. The material is a descriptor set per segment
// because lavapipe cannot index samplers dynamically (shaders/common/gpu_types.h).
#include "absl/strings/str_cat.h"
#include "common/status_macros.h"
#include "renderer/features/features.h"
#include "renderer/features/pass.h"
#include "renderer/vk/pipeline.h"
#include "shaders/common/gpu_types.h"

namespace tessera {

namespace {

// Linear HDR background behind the scene.
constexpr VkClearColorValue kBackground{{0.030f, 0.034f, 0.042f, 1.0f}};

// Shading pipelines per key = samples | ShadingConstants::Key() << kConstantsShift (a pipeline
// per set of texture slots the scene's materials use, GpuScene::texture_sets, and per effects,
// debug view and way of reading the lights).
constexpr uint32_t kConstantsShift = 4;

vk::GraphicsPipelineDesc SceneDesc(const SceneLayout& layout, uint32_t samples) {
  vk::GraphicsPipelineDesc d;
  d.layout = layout.pipeline_layout;
  d.color_formats = {kHdrFormat};
  d.depth_format = kDepthFormat;
  d.depth_test = true;
  d.depth_write = false;
  d.depth_compare = VK_COMPARE_OP_GREATER_OR_EQUAL;
  d.samples = static_cast<VkSampleCountFlagBits>(samples);
  return d;
}

absl::StatusOr<vk::Pipeline> CreateShading(const vk::Context& ctx, const SceneLayout& layout,
                                           PassId id, uint32_t key) {
  const bool transparent = id == PassId::kTransparent;
  vk::GraphicsPipelineDesc d = SceneDesc(layout, key & ((1u << kConstantsShift) - 1));
  d.name = absl::StrCat(transparent ? "transparent" : "forward", ".", absl::Hex(key));
  d.vertex_shader = "forward.vert";
  d.fragment_shader = "forward.frag";
  d.blend = transparent ? vk::BlendMode::kAlpha : vk::BlendMode::kNone;
  d.fragment_constants = ShadingConstants::FromKey(key >> kConstantsShift).Values();
  return vk::CreateGraphicsPipeline(ctx, d);
}

// The sky behind the forward pass. Far plane is depth 0: GREATER_OR_EQUAL passes only where the
// prepass left the clear value.
absl::StatusOr<vk::Pipeline> CreateSky(const vk::Context& ctx, const SceneLayout& layout,
                                       uint32_t samples) {
  vk::GraphicsPipelineDesc d = SceneDesc(layout, samples);
  d.name = "sky";
  d.vertex_shader = "fullscreen.vert";
  d.fragment_shader = "sky.frag";
  d.scene_vertex_input = false;
  return vk::CreateGraphicsPipeline(ctx, d);
}

class ForwardPass final : public Pass {
 public:
  ForwardPass(PassId id, const SceneLayout& layout) : id_(id), layout_(layout) {}
  PassId id() const override { return id_; }

  absl::Status Prepare(const vk::Context& ctx, const Settings& s) override {
    if (id_ == PassId::kTransparent) return absl::OkStatus();
    return sky_.Ensure(Samples(s),
                       [&](uint32_t samples) { return CreateSky(ctx, layout_, samples); });
  }
  // The texture slot sets of the materials this pass draws (blend materials in the transparent
  // pass, the others in forward).
  absl::Status PrepareScene(const vk::Context& ctx, const Settings& s, const GpuScene& scene,
                            const FrameFeatures& features) override {
    for (const DrawSegment& seg : scene.segments()) {
      if (!Draws(seg)) continue;
      RETURN_IF_ERROR(shading_.Ensure(
          Key(Samples(s), ShadingConstantsFor(s, features, scene.material_textures(seg.material))),
          [&](uint32_t key) { return CreateShading(ctx, layout_, id_, key); }));
    }
    return absl::OkStatus();
  }
  bool Draws(const DrawSegment& seg) const {
    return (seg.group == AlphaMode::kBlend) == (id_ == PassId::kTransparent);
  }
  static uint32_t Samples(const Settings& s) { return s.aa == AaMode::kMsaa ? s.samples : 1; }
  static uint32_t Key(uint32_t samples, const ShadingConstants& c) {
    return samples | c.Key() << kConstantsShift;
  }

  void Record(PassContext& ctx) override {
    const bool transparent = id_ == PassId::kTransparent;
    const uint32_t samples = ForwardSamples(ctx);
    const GpuScene& scene = *ctx.scene;
    auto pipeline_of = [&](uint32_t m) {
      return shading_
          .at(Key(samples,
                  ShadingConstantsFor(*ctx.settings, *ctx.features, scene.material_textures(m))))
          .handle();
    };
    const FrameTargets& t = *ctx.targets;
    VkRenderingAttachmentInfo color{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    // vis_mlaa draws blended surfaces over its anti-aliased result (the HDR colour, which its
    // geometric AA changed in place, or the aa_mask view's post-AA colour).
    const VkImageView single = transparent && ctx.settings->aa == AaMode::kVisMlaa
                                   ? PostColor(ctx).view()
                                   : t.hdr.view();
    color.imageView = samples > 1 ? t.hdr_ms.view() : single;
    color.imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
    color.loadOp = transparent ? VK_ATTACHMENT_LOAD_OP_LOAD : VK_ATTACHMENT_LOAD_OP_CLEAR;
    color.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    color.clearValue.color = kBackground;
    if (samples > 1) {  // msaa: the samples stay for the transparent pass; each pass resolves
      color.resolveMode = VK_RESOLVE_MODE_AVERAGE_BIT;
      color.resolveImageView = t.hdr.view();
      color.resolveImageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
    }
    VkRenderingAttachmentInfo depth{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    depth.imageView = samples > 1 ? t.depth_ms.view() : t.depth.view();
    depth.imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
    depth.loadOp = VK_ATTACHMENT_LOAD_OP_LOAD;
    depth.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    BeginRendering(ctx, &color, &depth);
    // The scene's set and buffers; each segment binds its material's pipeline.
    BeginSceneDraw(ctx, VK_NULL_HANDLE);
    const uint32_t phases = ctx.draws->phases;
    if (transparent) {
      RecordSegments(ctx, AlphaMode::kBlend, 0, phases, true, pipeline_of);
    } else {
      RecordSegments(ctx, AlphaMode::kOpaque, 0, phases, true, pipeline_of);
      RecordSegments(ctx, AlphaMode::kMask, 0, phases, true, pipeline_of);
      // Debug views keep the plain background, so their values read cleanly.
      if (ctx.settings->debug_view == DebugView::kNone) {
        vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, sky_.at(samples).handle());
        vkCmdSetCullMode(ctx.cmd, VK_CULL_MODE_NONE);
        vkCmdDraw(ctx.cmd, 3, 1, 0, 0);
      }
    }
    vkCmdEndRendering(ctx.cmd);
  }

 private:
  PassId id_;
  SceneLayout layout_;
  PerSampleCount<vk::Pipeline> shading_;  // by Key
  PerSampleCount<vk::Pipeline> sky_;      // by sample count
};

absl::StatusOr<std::unique_ptr<Pass>> Create(const vk::Context& ctx, const SceneLayout& layout,
                                             PassId id) {
  auto pass = std::make_unique<ForwardPass>(id, layout);
  // The sky at 1x, always used (the shading pipelines follow the scene: PrepareScene).
  if (absl::Status st = pass->Prepare(ctx, Settings{}); !st.ok()) return st;
  return pass;
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

namespace {
// The forward path's targets: multisampled with their resolve for msaa.
void UseForwardTargets(GraphBuilder& b, Resource color) {
  b.Use(Resource::kDrawLists, Access::kIndirectRead);
  if (b.settings().aa == AaMode::kMsaa) {
    b.Use(Resource::kDepthMs, Access::kDepthTest)
        .Use(Resource::kHdrMs, Access::kColorWrite)
        .Use(Resource::kHdrColor, Access::kColorWrite);
  } else {
    b.Use(Resource::kDepth, Access::kDepthTest).Use(color, Access::kColorWrite);
  }
  b.UseIfPresent(Resource::kAo, Access::kSampled)
      .UseIfPresent(Resource::kShadowAtlas, Access::kSampled)
      .UseIfPresent(Resource::kLightLists, Access::kSampled);
}
}  // namespace

void SetupForward(GraphBuilder& b) {
  // vis_mlaa and the visibility pipeline shade their visibility buffers.
  if (DrawsVisibility(b.settings())) return;
  b.Pass(PassId::kForward).UseIfPresent(Resource::kPosedGeometry, Access::kGeometryRead);
  UseForwardTargets(b, Resource::kHdrColor);
}

void SetupTransparent(GraphBuilder& b) {
  // Blended surfaces need the opaque colour underneath and must not write depth; vis_mlaa's
  // go over its anti-aliased result, against the resolved depth.
  if (!b.features().has_transparent) return;
  b.Pass(PassId::kTransparent).UseIfPresent(Resource::kPosedGeometry, Access::kGeometryRead);
  UseForwardTargets(b, b.SceneColor());
}

}  // namespace tessera
