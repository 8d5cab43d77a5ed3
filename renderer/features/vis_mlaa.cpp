// vis_mlaa, the visibility-buffer geometric anti-aliasing (docs: README "Anti-aliasing"):
//  - visibility: opaque and alpha-mask geometry into a multisampled R32_UINT target, each
//    sample the id of its drawable and triangle, plus multisampled depth (resolved to the
//    frame's single-sampled depth for light culling, the depth pyramid and transparency). The
//    visibility pipeline (vis_shade.cpp) uses the same pass at one sample, straight into the
//    frame's depth and ids;
//  - vis_resolve: per pixel, groups the samples by surface and picks the surface to shade, a
//    triangle of it, and its coverage mask and mean sample position.
// Then the visibility pipeline's classification and compute shading (vis_shade.cpp) shade each
// pixel's surface once, at that mean position, and the geometric AA pass (post.cpp) blends the
// partly covered pixels.
#include <algorithm>
#include <bit>

#include "absl/strings/str_cat.h"
#include "common/status_macros.h"
#include "renderer/features/features.h"
#include "renderer/features/pass.h"
#include "renderer/renderer_impl.h"
#include "renderer/vk/pipeline.h"
#include "renderer/vk/vk_check.h"
#include "shaders/common/gpu_types.h"

namespace tessera {

namespace {


class VisibilityPass final : public Pass {
 public:
  VisibilityPass(PassId id, const SceneLayout& layout) : id_(id), layout_(layout) {}
  PassId id() const override { return id_; }

  absl::Status Prepare(const vk::Context& ctx, const Settings& s) override {
    if (s.aa != AaMode::kVisMlaa && !ShadesVisibility(s)) return absl::OkStatus();
    return pipelines_.Ensure(Samples(s, s.samples),
                             [&](uint32_t samples) { return Create(ctx, samples); });
  }
  // vis_mlaa's sample count, or 1 for the visibility pipeline.
  static uint32_t Samples(const Settings& s, uint32_t samples) {
    return s.aa == AaMode::kVisMlaa ? samples : 1;
  }

  void Record(PassContext& ctx) override {
    const bool late = id_ == PassId::kVisibilityLate;
    const uint32_t phase = late ? 1 : 0;
    const uint32_t samples = Samples(*ctx.settings, ctx.samples);
    const Pipelines& p = pipelines_.at(samples);
    VkRenderingAttachmentInfo color{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    color.imageView = samples > 1 ? ctx.targets->vis_ms.view() : ctx.targets->vis_id.view();
    color.imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
    color.loadOp = late ? VK_ATTACHMENT_LOAD_OP_LOAD : VK_ATTACHMENT_LOAD_OP_CLEAR;
    color.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    color.clearValue.color.uint32[0] = 0;  // no surface
    VkRenderingAttachmentInfo depth{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    depth.imageView = samples > 1 ? ctx.targets->depth_ms.view() : ctx.targets->depth.view();
    depth.imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
    depth.loadOp = late ? VK_ATTACHMENT_LOAD_OP_LOAD : VK_ATTACHMENT_LOAD_OP_CLEAR;
    depth.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    depth.clearValue.depthStencil = {0.0f, 0};  // reverse Z: far is 0
    if (samples > 1) ResolveDepthInto(ctx, depth);
    BeginRendering(ctx, &color, &depth);
    RecordDepthGeometry(ctx, p.opaque.handle(), p.mask.handle(), phase);
    vkCmdEndRendering(ctx.cmd);
  }

 private:
  struct Pipelines {
    vk::Pipeline opaque, mask;
  };
  absl::StatusOr<Pipelines> Create(const vk::Context& ctx, uint32_t samples) const {
    vk::GraphicsPipelineDesc d;
    d.name = "visibility.opaque";
    d.vertex_shader = "vis.vert";
    d.fragment_shader = "vis.frag";
    d.layout = layout_.pipeline_layout;
    d.attribute_mask = 1u << gpu::kAttrPosition;
    d.color_formats = {kIdFormat};
    d.depth_format = kDepthFormat;
    d.depth_test = true;
    d.depth_write = true;
    d.depth_compare = VK_COMPARE_OP_GREATER;
    d.samples = static_cast<VkSampleCountFlagBits>(samples);
    ASSIGN_OR_RETURN(vk::Pipeline opaque, vk::CreateGraphicsPipeline(ctx, d));
    d.name = "visibility.mask";
    d.vertex_shader = "id.vert";
    d.fragment_shader = "vis_mask.frag";
    d.attribute_mask =
        (1u << gpu::kAttrPosition) | (1u << gpu::kAttrUv0) | (1u << gpu::kAttrUv1);
    absl::StatusOr<vk::Pipeline> mask = vk::CreateGraphicsPipeline(ctx, d);
    if (!mask.ok()) return mask.status();
    return Pipelines{std::move(opaque), std::move(*mask)};
  }

  PassId id_;
  SceneLayout layout_;
  PerSampleCount<Pipelines> pipelines_;
};

// The resolve pass's layout: the scene's sets 0 and 1 plus a set 2 of its own (gpu::kVisSet):
// the visibility samples and the scene's index and vertex buffers.
class VisLayout {
 public:
  static absl::StatusOr<VisLayout> Create(const vk::Context& ctx, const SceneLayout& scene) {
    VisLayout l;
    l.device_ = ctx.device();
    const VkDescriptorSetLayoutBinding b[] = {
        {gpu::kVisBindingSamples, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
         VK_SHADER_STAGE_FRAGMENT_BIT, nullptr},
        {gpu::kVisBindingIndices, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1,
         VK_SHADER_STAGE_FRAGMENT_BIT, nullptr},
        {gpu::kVisBindingVertices, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1,
         VK_SHADER_STAGE_FRAGMENT_BIT, nullptr}};
    VkDescriptorSetLayoutCreateInfo li{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    li.bindingCount = uint32_t(std::size(b));
    li.pBindings = b;
    VK_RETURN_IF_ERROR(
        vkCreateDescriptorSetLayout(l.device_, &li, nullptr, l.set_layout_.Replace(l.device_)),
        "vis set layout");
    const VkDescriptorSetLayout sets[] = {scene.set_layout, scene.material_set_layout,
                                          l.set_layout_.get()};
    VkPipelineLayoutCreateInfo pli{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    pli.setLayoutCount = 3;
    pli.pSetLayouts = sets;
    VK_RETURN_IF_ERROR(
        vkCreatePipelineLayout(l.device_, &pli, nullptr, l.layout_.Replace(l.device_)),
        "vis pipeline layout");
    return l;
  }
  VkPipelineLayout pipeline_layout() const { return layout_.get(); }

  // Set 2 for this frame: the samples, and the scene's index and vertex buffers.
  VkDescriptorSet Write(const PassContext& ctx, const VkDescriptorImageInfo& samples) {
    const VkDescriptorSet set = AllocateFrameSet(ctx, set_layout_.get());
    VkWriteDescriptorSet w[3];
    for (VkWriteDescriptorSet& x : w) {
      x = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
      x.dstSet = set;
      x.descriptorCount = 1;
      x.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    }
    w[0].dstBinding = gpu::kVisBindingSamples;
    w[0].descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
    w[0].pImageInfo = &samples;
    const VkDescriptorBufferInfo buffers[] = {
        {ctx.scene->indices().handle(), 0, VK_WHOLE_SIZE},
        {ctx.scene->vertices().handle(), 0, VK_WHOLE_SIZE}};
    for (uint32_t i = 0; i < 2; ++i) {
      w[1 + i].dstBinding = gpu::kVisBindingIndices + i;
      w[1 + i].pBufferInfo = &buffers[i];
    }
    vkUpdateDescriptorSets(device_, 3, w, 0, nullptr);
    return set;
  }

 private:
  VkDevice device_ = VK_NULL_HANDLE;
  vk::UniqueDescriptorSetLayout set_layout_;
  vk::UniquePipelineLayout layout_;
};

class VisResolvePass final : public Pass {
 public:
  VisResolvePass(VisLayout layout, vk::Pipeline pipeline, vk::Sampler sampler)
      : layout_(std::move(layout)), pipeline_(std::move(pipeline)), sampler_(std::move(sampler)) {}
  PassId id() const override { return PassId::kVisResolve; }

  void Record(PassContext& ctx) override {
    const VkDescriptorSet set =
        layout_.Write(ctx, {sampler_.handle(), ctx.targets->vis_ms.view(),
                            VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL});
    VkRenderingAttachmentInfo colors[2];
    const VkImageView views[2] = {ctx.targets->vis_id.view(), ctx.targets->vis_coverage.view()};
    for (int i = 0; i < 2; ++i) {
      colors[i] = {VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
      colors[i].imageView = views[i];
      colors[i].imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
      colors[i].loadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;  // every pixel is written
      colors[i].storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    }
    BeginRendering(ctx, colors, 2, nullptr);
    vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline_.handle());
    const VkPipelineLayout layout = layout_.pipeline_layout();
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout, 0, 1, &ctx.scene_set,
                            0, nullptr);
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout, gpu::kVisSet, 1, &set,
                            0, nullptr);
    vkCmdSetCullMode(ctx.cmd, VK_CULL_MODE_NONE);
    vkCmdDraw(ctx.cmd, 3, 1, 0, 0);
    vkCmdEndRendering(ctx.cmd);
  }

 private:
  VisLayout layout_;
  vk::Pipeline pipeline_;
  vk::Sampler sampler_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateVisibilityPass(const vk::Context& ctx,
                                                           const SceneLayout& layout, PassId id) {
  (void)ctx;
  return std::make_unique<VisibilityPass>(id, layout);
}

absl::StatusOr<std::unique_ptr<Pass>> CreateVisResolvePass(const vk::Context& ctx,
                                                           const SceneLayout& scene) {
  ASSIGN_OR_RETURN(VisLayout layout, VisLayout::Create(ctx, scene));
  vk::GraphicsPipelineDesc d;
  d.name = "vis_resolve";
  d.vertex_shader = "fullscreen.vert";
  d.fragment_shader = "vis_resolve.frag";
  d.layout = layout.pipeline_layout();
  d.scene_vertex_input = false;
  d.color_formats = {kIdFormat, kIdFormat};
  absl::StatusOr<vk::Pipeline> pipeline = vk::CreateGraphicsPipeline(ctx, d);
  if (!pipeline.ok()) return pipeline.status();
  absl::StatusOr<vk::Sampler> sampler = CreateClampSampler(ctx, false, "vis_resolve");
  if (!sampler.ok()) return sampler.status();
  return std::make_unique<VisResolvePass>(std::move(layout), std::move(*pipeline),
                                          std::move(*sampler));
}

void AddVisibilityPass(GraphBuilder& b, bool late) {
  b.Pass(late ? PassId::kVisibilityLate : PassId::kVisibility)
      .Use(Resource::kDrawLists, Access::kIndirectRead);
  if (b.settings().aa == AaMode::kVisMlaa) {
    b.Use(Resource::kDepthMs, Access::kDepthWrite)
        .Use(Resource::kVisMs, Access::kColorWrite)
        .Use(Resource::kDepth, Access::kDepthResolve);
  } else {  // the visibility pipeline: one sample, straight into the frame's depth
    b.Use(Resource::kDepth, Access::kDepthWrite).Use(Resource::kVisId, Access::kColorWrite);
  }
}

void SetupVisMlaa(GraphBuilder& b) {
  if (b.settings().aa != AaMode::kVisMlaa) return;
  using R = Resource;
  using A = Access;
  b.Pass(PassId::kVisResolve)
      .Use(R::kVisMs, A::kSampled)
      .Use(R::kVisId, A::kColorWrite)
      .Use(R::kVisCoverage, A::kColorWrite);
  // The shading of the resolved ids: SetupVisibilityShading (vis_shade.cpp).
}

void SetupGeometricAa(GraphBuilder& b) {
  if (b.settings().aa != AaMode::kVisMlaa) return;
  using R = Resource;
  using A = Access;
  b.Pass(PassId::kGeometricAa)
      .Use(R::kHdrColor, A::kSampled)
      .Use(R::kVisCoverage, A::kSampled)
      .Use(R::kVisId, A::kSampled)
      .Use(R::kPostHdr, A::kColorWrite);
}


namespace {

// vis_mlaa: the bits of a visibility id that hold the triangle. 12 bits of drawable + 1 and 20
// of triangle while the drawables fit; past 4095 drawables the drawable takes the bits it needs.
uint32_t VisTriangleBits(uint32_t drawables) {
  const uint32_t drawable_bits = std::max(12u, uint32_t(std::bit_width(drawables)));
  return 32 - drawable_bits;
}

// The materials of the opaque and alpha-mask drawables in the frustum, ascending: the only
// ones a visibility id can show.
std::vector<uint32_t> MaterialsInFrustum(const GpuScene& gs, const Frustum& frustum) {
  std::vector<uint32_t> out;
  for (const DrawItem& d : gs.draws()) {
    if (d.alpha == AlphaMode::kBlend || !AabbIntersectsFrustum(d.world_bounds, frustum)) continue;
    out.push_back(d.material);
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace

uint32_t Renderer::Impl::CheckVisibilityIds(const GpuScene& gs, ResolvedSettings& settings) {
  // A visibility id holds the drawable and the triangle; a scene whose largest drawable has
  // more triangles than the id leaves room for is drawn without one: vis_mlaa with msaa, the
  // visibility pipeline forward.
  const uint32_t triangle_bits = VisTriangleBits(uint32_t(gs.draws().size()));
  Settings& s = settings.effective;
  const uint32_t most = gs.max_draw_triangles();
  const bool vis_mlaa = s.aa == AaMode::kVisMlaa;
  if (most <= (uint64_t(1) << triangle_bits) || (!vis_mlaa && !ShadesVisibility(s)))
    return triangle_bits;
  settings.notes.push_back(
      {vis_mlaa ? "aa" : "pipeline",
       absl::StrCat("not applied: visibility ids hold ", triangle_bits, " bits of triangle with ",
                    gs.draws().size(), " drawables, and a drawable has ", most, " triangles; ",
                    vis_mlaa ? "rendered with msaa" : "shaded forward")});
  if (!vis_mlaa) {
    s.pipeline = Pipeline::kForward;
    return triangle_bits;
  }
  s.aa = AaMode::kMsaa;
  if (s.debug_view == DebugView::kAaMask) {
    settings.notes.push_back({"debug_view", "not applied: aa_mask needs vis_mlaa"});
    s.debug_view = DebugView::kNone;
  }
  return triangle_bits;
}

void Renderer::Impl::PrepareVis(FrameData& f) {
  // The materials the shading dispatches for (the others have no pixels).
  if (f.s.aa != AaMode::kVisMlaa && !ShadesVisibility(f.s)) return;
  f.vis.materials = MaterialsInFrustum(f.gs, FrustumFromViewProj(f.fu.view_proj));
}

}  // namespace tessera
