// vis_mlaa, the visibility-buffer geometric anti-aliasing (docs: README "Anti-aliasing"):
//  - visibility: opaque and alpha-mask geometry into a multisampled R32_UINT target, each
//    sample the id of its drawable and triangle, plus multisampled depth (resolved to the
//    frame's single-sampled depth for light culling, the depth pyramid and transparency);
//  - vis_resolve: per pixel, groups the samples by surface and picks the surface to shade, its
//    coverage mask and mean sample position, and marks its material in a depth target;
//  - vis_shade: one full-screen triangle per material on screen (scissored to the rectangle its
//    drawables can cover) at that material's depth, EQUAL-tested, so each pixel is shaded once
//    with its material bound as in the forward path; then the sky where no surface won.
// The geometric AA pass that follows is a post pass (post_pass.cpp).
#include <bit>
#include <map>

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

// The layout of the resolve and shading passes: the scene's sets 0 and 1 plus a set 2 of
// their own (gpu::kVisSet), and a push constant for the shading pass's material depth.
class VisLayout {
 public:
  static absl::StatusOr<VisLayout> Create(const vk::Context& ctx, const SceneLayout& scene,
                                          bool resolve) {
    VisLayout l;
    l.device_ = ctx.device();
    std::vector<VkDescriptorSetLayoutBinding> b;
    if (resolve) {
      b.push_back({gpu::kVisBindingSamples, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
                   VK_SHADER_STAGE_FRAGMENT_BIT, nullptr});
    } else {
      b.push_back({gpu::kVisBindingId, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
                   VK_SHADER_STAGE_FRAGMENT_BIT, nullptr});
      b.push_back({gpu::kVisBindingCoverage, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
                   VK_SHADER_STAGE_FRAGMENT_BIT, nullptr});
      b.push_back({gpu::kVisBindingShadeSamples, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
                   VK_SHADER_STAGE_FRAGMENT_BIT, nullptr});
    }
    b.push_back({gpu::kVisBindingIndices, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1,
                 VK_SHADER_STAGE_FRAGMENT_BIT, nullptr});
    b.push_back({gpu::kVisBindingVertices, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1,
                 VK_SHADER_STAGE_FRAGMENT_BIT, nullptr});
    VkDescriptorSetLayoutCreateInfo li{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    li.bindingCount = uint32_t(b.size());
    li.pBindings = b.data();
    VK_RETURN_IF_ERROR(
        vkCreateDescriptorSetLayout(l.device_, &li, nullptr, l.set_layout_.Replace(l.device_)),
        "vis set layout");
    const VkDescriptorSetLayout sets[] = {scene.set_layout, scene.material_set_layout,
                                          l.set_layout_.get()};
    const VkPushConstantRange push{VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(gpu::VisShadePush)};
    VkPipelineLayoutCreateInfo pli{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    pli.setLayoutCount = 3;
    pli.pSetLayouts = sets;
    pli.pushConstantRangeCount = resolve ? 0 : 1;
    pli.pPushConstantRanges = &push;
    VK_RETURN_IF_ERROR(
        vkCreatePipelineLayout(l.device_, &pli, nullptr, l.layout_.Replace(l.device_)),
        "vis pipeline layout");
    return l;
  }
  VkPipelineLayout pipeline_layout() const { return layout_.get(); }

  // Set 2 for this frame: `images` at their bindings, and the scene's index and vertex buffers.
  VkDescriptorSet Write(const PassContext& ctx,
                        const std::vector<std::pair<uint32_t, VkDescriptorImageInfo>>& images) {
    const VkDescriptorSet set = AllocateFrameSet(ctx, set_layout_.get());
    std::vector<VkWriteDescriptorSet> writes;
    for (const auto& [binding, info] : images) {
      VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
      w.dstSet = set;
      w.dstBinding = binding;
      w.descriptorCount = 1;
      w.descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
      w.pImageInfo = &info;
      writes.push_back(w);
    }
    const VkDescriptorBufferInfo buffers[] = {
        {ctx.scene->indices().handle(), 0, VK_WHOLE_SIZE},
        {ctx.scene->vertices().handle(), 0, VK_WHOLE_SIZE}};
    for (uint32_t i = 0; i < 2; ++i) {
      VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
      w.dstSet = set;
      w.dstBinding = gpu::kVisBindingIndices + i;
      w.descriptorCount = 1;
      w.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
      w.pBufferInfo = &buffers[i];
      writes.push_back(w);
    }
    vkUpdateDescriptorSets(device_, uint32_t(writes.size()), writes.data(), 0, nullptr);
    return set;
  }

 private:
  VkDevice device_ = VK_NULL_HANDLE;
  vk::UniqueDescriptorSetLayout set_layout_;
  vk::UniquePipelineLayout layout_;
};

void BindVisSets(const PassContext& ctx, VkPipelineLayout layout, VkDescriptorSet vis_set) {
  vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout, 0, 1, &ctx.scene_set,
                          0, nullptr);
  vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout, gpu::kVisSet, 1,
                          &vis_set, 0, nullptr);
}

class VisResolvePass final : public Pass {
 public:
  VisResolvePass(VisLayout layout, vk::Pipeline pipeline, vk::Sampler sampler)
      : layout_(std::move(layout)), pipeline_(std::move(pipeline)), sampler_(std::move(sampler)) {}
  PassId id() const override { return PassId::kVisResolve; }

  void Record(PassContext& ctx) override {
    const VkDescriptorSet set =
        layout_.Write(ctx, {{gpu::kVisBindingSamples,
                             {sampler_.handle(), ctx.targets->vis_ms.view(),
                              VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL}}});
    VkRenderingAttachmentInfo colors[2];
    const VkImageView views[2] = {ctx.targets->vis_id.view(), ctx.targets->vis_coverage.view()};
    for (int i = 0; i < 2; ++i) {
      colors[i] = {VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
      colors[i].imageView = views[i];
      colors[i].imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
      colors[i].loadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;  // every pixel is written
      colors[i].storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    }
    VkRenderingAttachmentInfo depth{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    depth.imageView = ctx.targets->material_depth.view();
    depth.imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
    depth.loadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
    depth.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    BeginRendering(ctx, colors, 2, &depth);
    vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline_.handle());
    BindVisSets(ctx, layout_.pipeline_layout(), set);
    vkCmdSetCullMode(ctx.cmd, VK_CULL_MODE_NONE);
    vkCmdDraw(ctx.cmd, 3, 1, 0, 0);
    vkCmdEndRendering(ctx.cmd);
  }

 private:
  VisLayout layout_;
  vk::Pipeline pipeline_;
  vk::Sampler sampler_;
};

// Linear HDR background of debug views (as the forward pass's clear).
constexpr VkClearColorValue kDebugBackground{{0.030f, 0.034f, 0.042f, 1.0f}};

class VisShadePass final : public Pass {
 public:
  // `effects`: built with shading.glsl's shadows, SSAO and IBL (specialization constant 0).
  VisShadePass(VisLayout layout, vk::Pipeline pipeline, vk::Pipeline effects, vk::Pipeline sky,
               vk::Sampler sampler)
      : layout_(std::move(layout)),
        pipeline_(std::move(pipeline)),
        effects_(std::move(effects)),
        sky_(std::move(sky)),
        sampler_(std::move(sampler)) {}
  PassId id() const override { return PassId::kVisShade; }

  void Record(PassContext& ctx) override {
    const VkImageLayout read = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
    const VkDescriptorSet set = layout_.Write(
        ctx, {{gpu::kVisBindingId, {sampler_.handle(), ctx.targets->vis_id.view(), read}},
              {gpu::kVisBindingCoverage,
               {sampler_.handle(), ctx.targets->vis_coverage.view(), read}},
              {gpu::kVisBindingShadeSamples, {sampler_.handle(), ctx.targets->vis_ms.view(), read}}});
    VkRenderingAttachmentInfo color{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    color.imageView = ctx.targets->hdr.view();
    color.imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
    color.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;  // debug views keep it where the sky would be
    color.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    color.clearValue.color = kDebugBackground;
    VkRenderingAttachmentInfo depth{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    depth.imageView = ctx.targets->material_depth.view();
    depth.imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
    depth.loadOp = VK_ATTACHMENT_LOAD_OP_LOAD;
    depth.storeOp = VK_ATTACHMENT_STORE_OP_NONE;
    BeginRendering(ctx, &color, &depth);
    const bool effects = ctx.settings->shadows || ctx.settings->ssao || ctx.settings->ibl;
    vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS,
                      (effects ? effects_ : pipeline_).handle());
    BindVisSets(ctx, layout_.pipeline_layout(), set);
    vkCmdSetCullMode(ctx.cmd, VK_CULL_MODE_NONE);
    for (const MaterialRect& m : ctx.vis->materials) {
      if (m.rect.extent.width == 0 || m.rect.extent.height == 0) continue;
      const VkDescriptorSet material = ctx.scene->material_set(m.material);
      vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout_.pipeline_layout(),
                              gpu::kMaterialSet, 1, &material, 0, nullptr);
      const gpu::VisShadePush push{float(m.material + 1) * gpu::kMaterialDepthScale};
      vkCmdPushConstants(ctx.cmd, layout_.pipeline_layout(), VK_SHADER_STAGE_VERTEX_BIT, 0,
                         sizeof(push), &push);
      vkCmdSetScissor(ctx.cmd, 0, 1, &m.rect);
      vkCmdDraw(ctx.cmd, 3, 1, 0, 0);
      ctx.stats->material_draws++;
    }
    if (ctx.settings->debug_view == DebugView::kNone) {  // the sky where no surface won
      const VkRect2D full{{0, 0}, {ctx.targets->width, ctx.targets->height}};
      vkCmdSetScissor(ctx.cmd, 0, 1, &full);
      vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, sky_.handle());
      vkCmdDraw(ctx.cmd, 3, 1, 0, 0);
    }
    vkCmdEndRendering(ctx.cmd);
  }

 private:
  VisLayout layout_;
  vk::Pipeline pipeline_, effects_;
  vk::Pipeline sky_;
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
  ASSIGN_OR_RETURN(VisLayout layout, VisLayout::Create(ctx, scene, /*resolve=*/true));
  vk::GraphicsPipelineDesc d;
  d.name = "vis_resolve";
  d.vertex_shader = "fullscreen.vert";
  d.fragment_shader = "vis_resolve.frag";
  d.layout = layout.pipeline_layout();
  d.scene_vertex_input = false;
  d.color_formats = {kIdFormat, kIdFormat};
  d.depth_format = kMaterialDepthFormat;
  d.depth_test = true;  // a depth write needs the test enabled; ALWAYS passes
  d.depth_write = true;
  d.depth_compare = VK_COMPARE_OP_ALWAYS;
  absl::StatusOr<vk::Pipeline> pipeline = vk::CreateGraphicsPipeline(ctx, d);
  if (!pipeline.ok()) return pipeline.status();
  absl::StatusOr<vk::Sampler> sampler = CreateClampSampler(ctx, false, "vis_resolve");
  if (!sampler.ok()) return sampler.status();
  return std::make_unique<VisResolvePass>(std::move(layout), std::move(*pipeline),
                                          std::move(*sampler));
}

absl::StatusOr<std::unique_ptr<Pass>> CreateVisShadePass(const vk::Context& ctx,
                                                         const SceneLayout& scene) {
  ASSIGN_OR_RETURN(VisLayout layout, VisLayout::Create(ctx, scene, /*resolve=*/false));
  vk::GraphicsPipelineDesc d;
  d.name = "vis_shade";
  d.vertex_shader = "vis_shade.vert";
  d.fragment_shader = "vis_shade.frag";
  d.layout = layout.pipeline_layout();
  d.scene_vertex_input = false;
  d.color_formats = {kHdrFormat};
  d.depth_format = kMaterialDepthFormat;
  d.depth_test = true;
  d.depth_write = false;
  d.depth_compare = VK_COMPARE_OP_EQUAL;
  absl::StatusOr<vk::Pipeline> pipeline = vk::CreateGraphicsPipeline(ctx, d);
  if (!pipeline.ok()) return pipeline.status();
  d.name = "vis_shade.effects";
  d.fragment_constants = {1u};
  absl::StatusOr<vk::Pipeline> effects = vk::CreateGraphicsPipeline(ctx, d);
  if (!effects.ok()) return effects.status();
  d.fragment_constants.clear();
  d.name = "vis_shade.sky";  // full-screen triangle at depth 0: the pixels the sky won
  d.vertex_shader = "fullscreen.vert";
  d.fragment_shader = "sky.frag";
  absl::StatusOr<vk::Pipeline> sky = vk::CreateGraphicsPipeline(ctx, d);
  if (!sky.ok()) return sky.status();
  absl::StatusOr<vk::Sampler> sampler = CreateClampSampler(ctx, false, "vis_shade");
  if (!sampler.ok()) return sampler.status();
  return std::make_unique<VisShadePass>(std::move(layout), std::move(*pipeline),
                                        std::move(*effects), std::move(*sky), std::move(*sampler));
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
      .Use(R::kVisCoverage, A::kColorWrite)
      .Use(R::kMaterialDepth, A::kDepthWrite);
  b.Pass(PassId::kVisShade)
      .Use(R::kVisId, A::kSampled)
      .Use(R::kVisCoverage, A::kSampled)
      .Use(R::kVisMs, A::kSampled)
      .Use(R::kMaterialDepth, A::kDepthTest)
      .Use(R::kHdrColor, A::kColorWrite)
      .UseIfPresent(R::kAo, A::kSampled)
      .UseIfPresent(R::kShadowAtlas, A::kSampled)
      .UseIfPresent(R::kLightLists, A::kSampled);
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

// Per material on screen, the pixel rectangle its drawables in the frustum can cover (their
// projected bounds; the whole frame when a box reaches behind the eye).
std::vector<MaterialRect> MaterialRects(const GpuScene& gs, const Frustum& frustum,
                                        const glm::mat4& view_proj, uint32_t width,
                                        uint32_t height) {
  std::vector<MaterialRect> out;
  std::map<uint32_t, glm::ivec4> rects;  // material -> x0, y0, x1, y1 (exclusive)
  const glm::ivec2 size{int(width), int(height)};
  for (const DrawItem& d : gs.draws()) {
    if (d.alpha == AlphaMode::kBlend || !AabbIntersectsFrustum(d.world_bounds, frustum)) continue;
    glm::vec2 lo(1e30f), hi(-1e30f);
    bool behind = false;
    for (int c = 0; c < 8; ++c) {
      const glm::vec4 clip = view_proj * glm::vec4(d.world_bounds.corner(c), 1.0f);
      if (clip.w <= 1e-6f) {
        behind = true;
        break;
      }
      const glm::vec2 pixel = (glm::vec2(clip) / clip.w * 0.5f + 0.5f) * glm::vec2(size);
      lo = glm::min(lo, pixel);
      hi = glm::max(hi, pixel);
    }
    glm::ivec4 r(0, 0, size.x, size.y);
    if (!behind) {
      r = glm::ivec4(glm::clamp(glm::ivec2(glm::floor(lo)) - 1, glm::ivec2(0), size),
                     glm::clamp(glm::ivec2(glm::ceil(hi)) + 1, glm::ivec2(0), size));
    }
    auto [it, fresh] = rects.emplace(d.material, r);
    if (!fresh) {
      it->second = glm::ivec4(glm::min(glm::ivec2(it->second), glm::ivec2(r)),
                              glm::max(glm::ivec2(it->second.z, it->second.w), glm::ivec2(r.z, r.w)));
    }
  }
  for (const auto& [material, r] : rects) {
    if (r.z <= r.x || r.w <= r.y) continue;
    out.push_back(
        {material, VkRect2D{{r.x, r.y}, {uint32_t(r.z - r.x), uint32_t(r.w - r.y)}}});
  }
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
  // Per material, the pixels its drawables in the frustum can cover (the visibility pipeline
  // shades the materials listed, vis_mlaa their rectangles).
  if (f.s.aa != AaMode::kVisMlaa && !ShadesVisibility(f.s)) return;
  f.vis.materials = MaterialRects(f.gs, FrustumFromViewProj(f.fu.view_proj), f.fu.view_proj,
                                  f.s.width, f.s.height);
}

}  // namespace tessera
