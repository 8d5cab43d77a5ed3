// vis_mlaa, the visibility-buffer geometric anti-aliasing (docs: README "Anti-aliasing"):
//  - visibility: opaque and alpha-mask geometry into a multisampled R32_UINT target, each
//    sample the id of its drawable and triangle, plus multisampled depth (resolved to the
//    frame's single-sampled depth for light culling, the depth pyramid and transparency). The
//    visibility pipeline (vis_shade.cpp) uses the same pass at one sample, straight into the
//    frame's depth and ids; so does vis_mlaa_coverage analytic, into the frame's depth and a
//    one-sample visibility target, its resolve finding the other samples' ids by testing them
//    against the nearby triangles in screen space;
//  - vis_resolve (compute): per pixel, groups the samples by surface and picks the surface to
//    shade, a triangle of it, and its coverage mask and mean sample position; only the edge
//    pixels are grouped, listed by a first pass over the frame; each pixel's surface is counted
//    in its material's entry for the shading's lists (shaders/common/vis_resolve.glsl).
// Then the visibility pipeline's classification and compute shading (vis_shade.cpp) shade each
// pixel's surface once, at that mean position, and the geometric AA pass (post.cpp) blends the
// partly covered pixels.
#include <algorithm>
#include <array>
#include <bit>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "common/status_macros.h"
#include "renderer/features/features.h"
#include "renderer/features/pass.h"
#include "renderer/renderer_impl.h"
#include "renderer/vk/pipeline.h"
#include "renderer/vk/vk_check.h"
#include "shaders/common/gpu_types.h"

namespace tessera {

namespace {

// With DeviceInfo::vertex_pulling the pass draws non-indexed and its vertex shaders read the
// scene's geometry (common/vis_pull.glsl) through a set of their own (`pulled_`), after the
// scene's two.
class VisibilityPass final : public Pass {
 public:
  VisibilityPass(PassId id, const SceneLayout& layout, PassLayout pulled)
      : id_(id), layout_(layout), pulled_(std::move(pulled)) {}
  PassId id() const override { return id_; }

  // A pipeline pair per sample count, and with pulled vertices per way of reading the scene's
  // geometry (vis.glsl's kVisTexels).
  absl::Status PrepareScene(const vk::Context& ctx, const Settings& s, const GpuScene& scene,
                            const FrameFeatures&) override {
    if (!DrawsVisibility(s)) return absl::OkStatus();
    return pipelines_.Ensure(Key(ctx, s, s.samples, scene),
                             [&](uint32_t key) { return Create(ctx, key); });
  }
  // The samples rasterized: vis_mlaa's count, or 1 for the visibility pipeline and for
  // vis_mlaa_coverage analytic.
  static uint32_t Samples(const Settings& s, uint32_t samples) {
    return s.aa == AaMode::kVisMlaa && !VisMlaaAnalytic(s) ? samples : 1;
  }

  // The samples | kVisTexels << 8 | pulled << 9 (only with pulled vertices does the pipeline
  // read the geometry).
  static uint32_t Key(const vk::Context& ctx, const Settings& s, uint32_t samples,
                      const GpuScene& scene) {
    const bool pulled = ctx.info().vertex_pulling;
    return Samples(s, samples) | (pulled ? VisTexels(scene) << 8 | 1u << 9 : 0u);
  }

  void Record(PassContext& ctx) override {
    const bool late = id_ == PassId::kVisibilityLate;
    const uint32_t phase = late ? 1 : 0;
    const uint32_t samples = Samples(*ctx.settings, ctx.samples);
    const Pipelines& p = pipelines_.at(Key(*ctx.vk, *ctx.settings, ctx.samples, *ctx.scene));
    VkRenderingAttachmentInfo color{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    // vis_mlaa's samples go to their own target (the resolve writes vis_id from them).
    color.imageView = ctx.settings->aa == AaMode::kVisMlaa ? ctx.targets->vis_ms.view()
                                                           : ctx.targets->vis_id.view();
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
    PulledGeometry pulled;
    const bool pull = ctx.vk->info().vertex_pulling;
    if (pull) {
      pulled = {pulled_.pipeline_layout(), pulled_.Allocate(ctx)};
      SetWriter(ctx.vk->device(), pulled.set).SceneGeometry(ctx).Update();
    }
    RecordDepthGeometry(ctx, p.opaque.handle(), p.mask.handle(), phase, pull ? &pulled : nullptr);
    vkCmdEndRendering(ctx.cmd);
  }

 private:
  struct Pipelines {
    vk::Pipeline opaque, mask;
  };
  absl::StatusOr<Pipelines> Create(const vk::Context& ctx, uint32_t key) const {
    const bool pulled = (key >> 9) & 1u;
    vk::GraphicsPipelineDesc d;
    d.name = "visibility.opaque";
    d.vertex_shader = pulled ? "vis_pull.vert" : "vis.vert";
    d.fragment_shader = pulled ? "vis_pull.frag" : "vis.frag";
    d.layout = pulled ? pulled_.pipeline_layout() : layout_.pipeline_layout;
    d.drawable_instance_input = pulled;
    if (pulled) d.vertex_constants = {0u, 0u, 0u, (key >> 8) & 1u};  // vis.glsl's constant 3
    d.attribute_mask = 1u << gpu::kAttrPosition;
    d.color_formats = {kIdFormat};
    d.depth_format = kDepthFormat;
    d.depth_test = true;
    d.depth_write = true;
    d.depth_compare = VK_COMPARE_OP_GREATER;
    d.samples = static_cast<VkSampleCountFlagBits>(key & 0xffu);
    ASSIGN_OR_RETURN(vk::Pipeline opaque, vk::CreateGraphicsPipeline(ctx, d));
    d.name = "visibility.mask";
    d.vertex_shader = pulled ? "vis_pull_mask.vert" : "id.vert";
    d.fragment_shader = pulled ? "vis_pull_mask.frag" : "vis_mask.frag";
    d.attribute_mask = gpu::kAlphaMaskAttributes;
    absl::StatusOr<vk::Pipeline> mask = vk::CreateGraphicsPipeline(ctx, d);
    if (!mask.ok()) return mask.status();
    return Pipelines{std::move(opaque), std::move(*mask)};
  }

  PassId id_;
  SceneLayout layout_;
  PassLayout pulled_;
  PerSampleCount<Pipelines> pipelines_;
};

// The resolve pass (compute): the scene's sets 0 and 1 plus a set 2 of its own (gpu::kVisSet):
// the visibility samples, the ids and coverage words it writes, the scene's index and vertex
// buffers, and the shading's entries and pixel lists (its edge list, and each material's pixel
// count, which the resolve makes for the classification).
class VisResolvePass final : public Pass {
 public:
  static absl::StatusOr<std::unique_ptr<VisResolvePass>> Create(const vk::Context& ctx,
                                                                const SceneLayout& scene) {
    auto p = std::unique_ptr<VisResolvePass>(new VisResolvePass);
    p->device_ = ctx.device();
    constexpr VkShaderStageFlags kCompute = VK_SHADER_STAGE_COMPUTE_BIT;
    constexpr VkDescriptorType kImage = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE;
    constexpr VkDescriptorType kBuffer = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    std::vector<VkDescriptorSetLayoutBinding> b = VisibilityBufferBindings();
    b.push_back(LayoutBinding(gpu::kVisBindingSamples, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER,
                              kCompute));
    b.push_back(LayoutBinding(gpu::kResolveBindingId, kImage, kCompute));
    b.push_back(LayoutBinding(gpu::kResolveBindingCoverage, kImage, kCompute));
    b.push_back(LayoutBinding(gpu::kShadeBindingRunnerUps, kBuffer, kCompute));
    b.push_back(LayoutBinding(gpu::kResolveBindingAdjacency, kBuffer, kCompute));
    b.push_back(LayoutBinding(gpu::kResolveBindingSurfaces, kBuffer, kCompute));
    b.push_back(LayoutBinding(gpu::kResolveBindingSurfaceTexels,
                              VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, kCompute));
    ASSIGN_OR_RETURN(p->layout_,
                     PassLayout::Create(ctx, b, {{kCompute, 0, sizeof(gpu::ShadePush)}},
                                        "vis_resolve layout",
                                        {scene.set_layout, scene.material_set_layout}));
    ASSIGN_OR_RETURN(p->sampler_, CreateClampSampler(ctx, false, "vis_resolve"));
    return p;
  }
  PassId id() const override { return PassId::kVisResolve; }

  // A pipeline per sample count (vis_resolve.comp's kSamples) and mode (kMode: each dispatch's
  // shader holds only its own code; one shader for the four cost lavapipe the grouping's
  // arithmetic on every pixel of the uniform pass); one atomic per subgroup and material where
  // the device appends so (DeviceInfo::subgroup_appends), else per pixel
  // (vis_resolve_atomic.comp); and per way of reading the scene's triangles (vis.glsl's
  // kVisTexels).
  absl::Status PrepareScene(const vk::Context& ctx, const Settings& s, const GpuScene& scene,
                            const FrameFeatures&) override {
    if (s.aa != AaMode::kVisMlaa) return absl::OkStatus();
    return pipelines_.Ensure(Key(s.samples, s, scene),
                             [&](uint32_t key) -> absl::StatusOr<ModePipelines> {
      ModePipelines made;
      for (uint32_t mode = 0; mode < made.size(); ++mode) {
        ASSIGN_OR_RETURN(
            made[mode],
            vk::CreateComputePipeline(
                ctx, absl::StrCat("vis_resolve.", absl::Hex(key)),
                ShaderFor(key >> 9, ctx.info().subgroup_appends), layout_.pipeline_layout(),
                {key & 0xffu, mode, 0u, (key >> 8) & 1u}));
      }
      return made;
    });
  }
  // The sample count | kVisTexels << 8 | analytic << 9.
  static uint32_t Key(uint32_t samples, const Settings& s, const GpuScene& scene) {
    return samples | VisTexels(scene) << 8 | uint32_t(VisMlaaAnalytic(s)) << 9;
  }
  static const char* ShaderFor(bool analytic, bool ballot) {
    if (analytic) return ballot ? "vis_resolve_analytic.comp" : "vis_resolve_analytic_atomic.comp";
    return ballot ? "vis_resolve.comp" : "vis_resolve_atomic.comp";
  }

  void Record(PassContext& ctx) override {
    const ShadeBuffers& sb = *ctx.shade;
    const uint32_t edges = sb.edge_entry(), blend = sb.blend_entry();
    const VkDeviceSize entry = VkDeviceSize(edges) * sizeof(gpu::GpuShadeEntry);
    const VkDeviceSize blend_entry = VkDeviceSize(blend) * sizeof(gpu::GpuShadeEntry);
    // Every material's, the sky's, the edge list's and the blend list's entry start at zero: the
    // resolve counts each pixel's surface in its material's (the classification then goes straight
    // to its scan).
    vkCmdFillBuffer(ctx.cmd, sb.entries, 0, blend_entry + sizeof(gpu::GpuShadeEntry), 0);
    vk::CmdMemoryBarrier(ctx.cmd, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT,
                         VK_ACCESS_2_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                         VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
    WriteSet(ctx);
    // params.x: the list kResolveArgs sizes.
    auto push = [&](uint32_t mode, uint32_t list = 0) {
      vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE,
                        pipelines_.at(Key(ctx.samples, *ctx.settings, *ctx.scene))[mode].handle());
      const gpu::ShadePush p{glm::uvec4(list, edges, 0u, 0u)};
      vkCmdPushConstants(ctx.cmd, layout_.pipeline_layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0,
                         sizeof(p), &p);
    };
    push(gpu::kResolveUniform);
    vkCmdDispatch(ctx.cmd, (ctx.targets->width + 7) / 8, (ctx.targets->height + 7) / 8, 1);
    const VkPipelineStageFlags2 compute = VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;
    const VkAccessFlags2 rw = VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT;
    vk::CmdMemoryBarrier(ctx.cmd, compute, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, compute, rw);
    push(gpu::kResolveArgs, edges);
    vkCmdDispatch(ctx.cmd, 1, 1, 1);
    vk::CmdMemoryBarrier(ctx.cmd, compute, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                         compute | VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT,
                         rw | VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT);
    push(gpu::kResolveEdges);
    vkCmdDispatchIndirect(ctx.cmd, sb.entries, entry);
    vk::CmdMemoryBarrier(ctx.cmd, compute, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, compute, rw);
    push(gpu::kResolveArgs, blend);
    vkCmdDispatch(ctx.cmd, 1, 1, 1);
    // The runner-ups look at the ids every edge pixel now has.
    vk::CmdMemoryBarrier(ctx.cmd, compute, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                         compute | VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT,
                         rw | VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT);
    push(gpu::kResolveRunnerUps);
    vkCmdDispatchIndirect(ctx.cmd, sb.entries, blend_entry);
  }

 private:
  VisResolvePass() = default;

  void WriteSet(const PassContext& ctx) {
    const VkDescriptorSet set = layout_.Allocate(ctx);
    SetWriter(device_, set)
        .Sampled(gpu::kVisBindingSamples, sampler_.handle(), ctx.targets->vis_ms.view())
        .Storage(gpu::kResolveBindingId, ctx.targets->vis_id.view())
        .Storage(gpu::kResolveBindingCoverage, ctx.targets->vis_coverage.view())
        .Buffer(gpu::kShadeBindingRunnerUps, ctx.shade->runner_ups)
        .StorageBuffer(gpu::kResolveBindingAdjacency, ctx, ctx.scene->adjacency())
        .StorageBuffer(gpu::kResolveBindingSurfaces, ctx, ctx.scene->surfaces())
        .TexelBuffer(gpu::kResolveBindingSurfaceTexels, ctx.scene->surface_texels())
        .VisibilityBuffers(ctx)
        .Update();
    const VkPipelineLayout layout = layout_.pipeline_layout();
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout, 0, 1, &ctx.scene_set,
                            0, nullptr);
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout, gpu::kVisSet, 1, &set,
                            0, nullptr);
  }

  VkDevice device_ = VK_NULL_HANDLE;
  PassLayout layout_;
  using ModePipelines = std::array<vk::Pipeline, 4>;  // per kResolve* mode
  PerSampleCount<ModePipelines> pipelines_;  // by Key
  vk::Sampler sampler_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateVisibilityPass(const vk::Context& ctx,
                                                           const SceneLayout& layout, PassId id) {
  PassLayout pulled;
  if (ctx.info().vertex_pulling) {
    ASSIGN_OR_RETURN(pulled, PassLayout::Create(ctx, SceneGeometryBindings(VK_SHADER_STAGE_VERTEX_BIT),
                                                {}, "visibility pulled layout",
                                                {layout.set_layout, layout.material_set_layout}));
  }
  return std::make_unique<VisibilityPass>(id, layout, std::move(pulled));
}

absl::StatusOr<std::unique_ptr<Pass>> CreateVisResolvePass(const vk::Context& ctx,
                                                           const SceneLayout& scene) {
  ASSIGN_OR_RETURN(std::unique_ptr<VisResolvePass> pass, VisResolvePass::Create(ctx, scene));
  return pass;
}

void AddVisibilityPass(GraphBuilder& b, bool late) {
  b.Pass(late ? PassId::kVisibilityLate : PassId::kVisibility)
      .Use(Resource::kDrawLists, Access::kIndirectRead)
      .UseIfPresent(Resource::kPosedGeometry, Access::kGeometryRead);
  if (VisMlaaAnalytic(b.settings())) {  // one sample
    b.Use(Resource::kDepth, Access::kDepthWrite).Use(Resource::kVisMs, Access::kColorWrite);
  } else if (b.settings().aa == AaMode::kVisMlaa) {
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
  // The edge list borrows the shading's pixel lists (rewritten whole each frame).
  b.Import(R::kShadeLists, A::kNone, A::kIndirectRead);
  b.Import(R::kEdgeSurfaces, A::kNone, A::kComputeWrite);  // rewritten whole each frame too
  b.Pass(PassId::kVisResolve)
      .UseIfPresent(R::kPosedGeometry, A::kGeometryRead)
      .Use(R::kVisMs, A::kComputeRead)
      .Use(R::kShadeLists, A::kComputeWrite)
      .Use(R::kEdgeSurfaces, A::kComputeWrite)
      .Use(R::kVisId, A::kComputeWrite)
      .Use(R::kVisCoverage, A::kComputeWrite);
  // The shading of the resolved ids: SetupVisibilityShading (vis_shade.cpp).
}

void SetupGeometricAa(GraphBuilder& b) {
  if (b.settings().aa != AaMode::kVisMlaa) return;
  using R = Resource;
  if (b.settings().debug_view == DebugView::kAaMask) {  // every pixel, into the post-AA colour
    const bool compute = FullscreenProgram::Compute(b.settings());
    const Access read = compute ? Access::kComputeRead : Access::kSampled;
    b.Pass(PassId::kGeometricAa)
        .Use(R::kHdrColor, read)
        .Use(R::kVisCoverage, read)
        .Use(R::kVisId, read)
        .Use(R::kPostHdr, compute ? Access::kComputeWrite : Access::kColorWrite);
    return;
  }
  // The edge pixels the resolve listed, in place (compute).
  b.Pass(PassId::kGeometricAa)
      .Use(R::kHdrColor, Access::kComputeWrite)
      .Use(R::kVisCoverage, Access::kComputeRead)
      .Use(R::kVisId, Access::kComputeRead)
      .Use(R::kShadeLists, Access::kIndirectRead)
      .Use(R::kEdgeSurfaces, Access::kComputeWrite);
}


namespace {

// vis_mlaa: the bits of a visibility id that hold the triangle. 12 bits of drawable + 1 and 20
// of triangle while the drawables fit; past 4095 drawables the drawable takes the bits it needs.
uint32_t VisTriangleBits(uint32_t drawables) {
  const uint32_t drawable_bits = std::max(12u, uint32_t(std::bit_width(drawables)));
  return 32 - drawable_bits;
}

}  // namespace

uint32_t Renderer::Impl::CheckVisibilityIds(const GpuScene& gs, ResolvedSettings& settings) {
  // A visibility id holds the drawable and the triangle; a scene whose largest drawable has
  // more triangles than the id leaves room for is drawn without one: vis_mlaa with msaa, the
  // visibility pipeline forward. So is a scene whose triangles the visibility passes cannot
  // read: index or vertex buffer beyond the device's storage buffer range, and not covered by
  // texel views (GpuScene::vis_texels).
  const uint32_t triangle_bits = VisTriangleBits(uint32_t(gs.draws().size()));
  Settings& s = settings.effective;
  const uint32_t most = gs.max_draw_triangles();
  const bool vis_mlaa = s.aa == AaMode::kVisMlaa;
  if (!DrawsVisibility(s)) return triangle_bits;
  // The shading's pixel lists (vis_mlaa: its edge list first, and the runner-up surfaces in the
  // materials' lists: three words a pixel) must fit one storage buffer binding.
  const uint64_t list_bytes = uint64_t(s.width) * s.height * 4 * (vis_mlaa ? 3 : 1);
  const uint64_t range = ctx->limits().maxStorageBufferRange;
  std::string why;
  if (most > (uint64_t(1) << triangle_bits)) {
    why = absl::StrCat("visibility ids hold ", triangle_bits, " bits of triangle with ",
                       gs.draws().size(), " drawables, and a drawable has ", most, " triangles");
  } else if (list_bytes > range) {
    why = absl::StrCat("the ", s.width, "x", s.height, " frame's pixel lists need ", list_bytes,
                       " bytes, more than the device's storage buffer range (", range, ")");
  } else if (!gs.vis_texels() && std::max(gs.indices().size(), gs.vertices().size()) > range) {
    std::vector<std::string> over;
    for (const auto& [what, buffer] :
         {std::pair{"index", &gs.indices()}, std::pair{"vertex", &gs.vertices()}}) {
      if (buffer->size() > range)
        over.push_back(absl::StrCat(what, " buffer (", buffer->size(), " bytes)"));
    }
    const bool both = over.size() == 2;
    why = absl::StrCat("the scene's ", absl::StrJoin(over, " and "), both ? " exceed" : " exceeds",
                       " the device's storage buffer range (", range,
                       ") and its texel buffers do not cover ", both ? "them" : "it");
  } else {
    // vis_mlaa_coverage analytic reads the adjacency (one word per index) as a storage buffer.
    if (VisMlaaAnalytic(s) && gs.adjacency().size() > range) {
      settings.notes.push_back(
          {"vis_mlaa_coverage",
           absl::StrCat("not applied: the scene's triangle adjacency (", gs.adjacency().size(),
                        " bytes) exceeds the device's storage buffer range (", range,
                        "); rendered with raster coverage")});
      s.vis_mlaa_coverage = VisMlaaCoverage::kRaster;
    }
    return triangle_bits;
  }
  settings.notes.push_back({vis_mlaa ? "aa" : "pipeline",
                            absl::StrCat("not applied: ", why, "; ",
                                         vis_mlaa ? "rendered with msaa" : "shaded forward")});
  if (!vis_mlaa) {
    s.pipeline = Pipeline::kForward;
    return triangle_bits;
  }
  s.aa = AaMode::kMsaa;
  s.pipeline = Pipeline::kForward;  // what msaa runs (the effective settings say so)
  if (s.debug_view == DebugView::kAaMask) {
    settings.notes.push_back({"debug_view", "not applied: aa_mask needs vis_mlaa"});
    s.debug_view = DebugView::kNone;
  }
  return triangle_bits;
}

}  // namespace tessera
