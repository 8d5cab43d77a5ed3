// Geometry culling on the GPU (shaders/cull.comp): one dispatch tests the scene's cull items
// against the view and writes the indirect draw lists and counts the geometry passes consume.
//  - kCull: gpu_frustum (everything in the frustum), or the first gpu_occlusion phase (what
//    the view saw last frame and is still in the frustum);
//  - kCullLate: the second gpu_occlusion phase, against the depth pyramid of the first phase's
//    depth; records this frame's visibility bits.
#include <algorithm>
#include <cstring>

#include "common/status_macros.h"
#include "renderer/features/features.h"
#include "renderer/features/pass.h"
#include "renderer/renderer_impl.h"
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
    SetWriter(device_, set)
        .Buffer(gpu::kCullBindingUniforms, cb.uniforms, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                cb.uniform_stride * phase, sizeof(gpu::CullUniforms))
        .Buffer(gpu::kCullBindingItems, ctx.scene->cull_items().handle())
        .Buffer(gpu::kCullBindingDrawables, ctx.scene->drawables().handle())
        .Buffer(gpu::kCullBindingCommands, lists.commands)
        .Buffer(gpu::kCullBindingCounts, lists.counts)
        .Buffer(gpu::kCullBindingBases, cb.bases)
        .Buffer(gpu::kCullBindingVisPrev, cb.vis_prev)
        .Buffer(gpu::kCullBindingVisNext, cb.vis_next)
        .Sampled(gpu::kCullBindingHiz, sampler_.handle(), ctx.targets->hiz.view())
        .Update();

    // The graph ordered the lists and visibility bits after their earlier uses (SetupCulling);
    // the clears below come before this pass's dispatch.
    const uint32_t lists_per_phase = uint32_t(ctx.scene->segments().size() +
                                              ctx.scene->batches().size());
    vkCmdFillBuffer(ctx.cmd, lists.counts, lists.CountOffset(phase, lists_per_phase),
                    gpu::kCullStatCount * sizeof(uint32_t), 0);
    if (!ctx.vk->info().draw_indirect_count) {  // the draws run the lists' whole capacity
      vkCmdFillBuffer(ctx.cmd, lists.commands, lists.CommandOffset(phase, false, 0),
                      lists.CommandOffset(phase + 1, false, 0) -
                          lists.CommandOffset(phase, false, 0),
                      0);
    }
    if (phase == 1) vkCmdFillBuffer(ctx.cmd, cb.vis_next, 0, VK_WHOLE_SIZE, 0);
    vk::CmdMemoryBarrier(ctx.cmd, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                  VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                  VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);

    vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_.handle());
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout_.pipeline_layout(), 0,
                            1, &set, 0, nullptr);
    vkCmdDispatch(ctx.cmd, 1, 1, 1);  // one workgroup: the lists come out in item order
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
  bindings[gpu::kCullBindingHiz].descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
  absl::StatusOr<PassLayout> layout = PassLayout::Create(ctx, bindings, {}, "cull layout");
  if (!layout.ok()) return layout.status();
  const char* name = id == PassId::kCullLate ? "cull_late" : "cull";
  absl::StatusOr<vk::Pipeline> pipeline =
      vk::CreateComputePipeline(ctx, name,
                                ctx.info().subgroup_arithmetic ? "cull.comp" : "cull_shared_scan.comp",
                                layout->pipeline_layout());
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

void SetupCulling(GraphBuilder& b) {
  const CullingMode c = b.settings().culling;
  const bool gpu = c == CullingMode::kGpuFrustum || c == CullingMode::kGpuOcclusion;
  // Every frame draws from the lists: the host writes them before the frame (none,
  // cpu_frustum) or the cull passes do; the host reads them after it (what the frame drew).
  b.Import(Resource::kDrawLists, gpu ? Access::kNone : Access::kHostWrite, Access::kHostRead);
  if (!gpu) return;
  // gpu_occlusion: the first phase reads what the view saw last frame (the late cull wrote it,
  // or the host zeroed a new view's bits).
  if (c == CullingMode::kGpuOcclusion)
    b.Import(Resource::kVisibilityBits, Access::kComputeWrite, Access::kComputeWrite);
  // The first phase does not read the pyramid, but its pipeline binds it.
  b.Pass(PassId::kCull)
      .UseIfPresent(Resource::kPosedGeometry, Access::kGeometryRead)
      .Use(Resource::kHiz, Access::kComputeRead)
      .Use(Resource::kDrawLists, Access::kComputeWrite)
      .UseIfPresent(Resource::kVisibilityBits, Access::kComputeRead);
}

void SetupOcclusion(GraphBuilder& b) {
  // Two-phase occlusion culling: what was visible last frame was drawn by the first phase; its
  // depth becomes the pyramid every other drawable is tested against, and what passes is
  // drawn now.
  if (b.settings().culling != CullingMode::kGpuOcclusion) return;
  b.Pass(PassId::kHizBuild)
      .Use(Resource::kDepth, Access::kComputeRead)
      .Use(Resource::kHiz, Access::kComputeWrite);
  b.Pass(PassId::kCullLate)
      .UseIfPresent(Resource::kPosedGeometry, Access::kGeometryRead)
      .Use(Resource::kHiz, Access::kComputeRead)
      .Use(Resource::kDrawLists, Access::kComputeWrite)
      .Use(Resource::kVisibilityBits, Access::kComputeWrite);
  AddDepthPass(b, /*late=*/true);
}

// What a frame drew, from the lists it executed (counts clamped to the list sizes, as the
// draws clamp them to maxDrawCount): drawables, draws and triangles per pass, and the drawn
// drawables when `drawn_out` is set.
void Renderer::Impl::CountDrawn(const GpuScene& gs, const DrawLists& draws,
                                const std::vector<PassId>& pass_ids, FrameStats& stats,
                                std::vector<uint32_t>* drawn_out) const {
  const uint32_t item_count = uint32_t(gs.draws().size());
  const uint32_t segment_count = uint32_t(gs.segments().size());
  const uint32_t list_count = segment_count + uint32_t(gs.batches().size());
  const auto* commands = static_cast<const DrawCommand*>(draw_commands.mapped());
  const auto* counts = static_cast<const uint32_t*>(draw_counts.mapped());
  struct ListSums {
    uint64_t triangles = 0;
    uint32_t draws = 0;
  };
  auto sum_list = [&](uint32_t phase, bool batch, uint32_t first, uint32_t capacity,
                      uint32_t count_index, std::vector<uint32_t>* drawn) {
    ListSums r;
    const uint32_t n = std::min(counts[draws.CountOffset(phase, count_index) / 4], capacity);
    const DrawCommand* c = commands + draws.CommandOffset(phase, batch, first) / sizeof(DrawCommand);
    for (uint32_t k = 0; k < n; ++k) {
      r.triangles += c[k].indexed.indexCount / 3;
      if (drawn) drawn->push_back(c[k].indexed.firstInstance);
    }
    r.draws = n;
    return r;
  };
  // Per phase and group: the segments' sums; per phase: the opaque batches'.
  ListSums group_sums[2][3] = {};
  ListSums batch_sums[2] = {};
  std::vector<uint32_t> drawn;
  uint32_t late = 0;
  for (uint32_t p = 0; p < draws.phases; ++p) {
    for (uint32_t i = 0; i < segment_count; ++i) {
      const DrawSegment& seg = gs.segments()[i];
      const ListSums r = sum_list(p, false, seg.first_item, seg.item_count, i, &drawn);
      ListSums& g = group_sums[p][static_cast<uint32_t>(seg.group)];
      g.triangles += r.triangles;
      g.draws += r.draws;
      if (p == 1) late += r.draws;
    }
    for (uint32_t b = 0; b < gs.batches().size(); ++b) {
      const DrawBatch& batch = gs.batches()[b];
      const ListSums r =
          sum_list(p, true, batch.first_item, batch.item_count, segment_count + b, nullptr);
      batch_sums[p].triangles += r.triangles;
      batch_sums[p].draws += r.draws;
    }
  }
  const uint32_t* stats0 = counts + draws.CountOffset(0, list_count) / 4;
  stats.drawables_in_frustum = stats0[gpu::kCullStatInFrustum];
  stats.drawables_drawn = uint32_t(drawn.size());
  stats.drawables_culled = item_count - uint32_t(drawn.size());
  stats.drawables_late = late;
  if (draws.phases == 2) {
    stats.drawables_stale = counts[draws.CountOffset(1, list_count) / 4 + gpu::kCullStatStale];
  }
  auto add = [&](const ListSums& r) {
    stats.triangles_submitted += r.triangles;
    stats.draws += r.draws;
  };
  for (PassId id : pass_ids) {
    const uint32_t o = static_cast<uint32_t>(AlphaMode::kOpaque);
    const uint32_t k = static_cast<uint32_t>(AlphaMode::kMask);
    const uint32_t b = static_cast<uint32_t>(AlphaMode::kBlend);
    // The depth prepass and the visibility pass (vis_mlaa's, the visibility pipeline's) draw
    // the opaque batches and the alpha-mask segments of their phase.
    if (id == PassId::kDepthPrepass || id == PassId::kDepthPrepassLate ||
        id == PassId::kVisibility || id == PassId::kVisibilityLate) {
      const uint32_t p = id == PassId::kDepthPrepassLate || id == PassId::kVisibilityLate ? 1 : 0;
      add(batch_sums[p]);
      add(group_sums[p][k]);
    } else if (id == PassId::kForward || id == PassId::kTransparent) {
      for (uint32_t p = 0; p < draws.phases; ++p) {
        if (id == PassId::kForward) {
          add(group_sums[p][o]);
          add(group_sums[p][k]);
        } else {
          add(group_sums[p][b]);
        }
      }
    }
  }
  if (drawn_out) {
    std::sort(drawn.begin(), drawn.end());
    *drawn_out = std::move(drawn);
  }
}

void Renderer::Impl::WriteCpuLists(const GpuScene& scene, const DrawLists& lists,
                                       const Frustum* frustum) {
  const std::vector<DrawItem>& items = scene.draws();
  std::vector<uint8_t> visible(items.size(), 1);
  uint32_t in_frustum = 0;
  for (size_t i = 0; i < items.size(); ++i) {
    if (frustum) visible[i] = AabbIntersectsFrustum(items[i].world_bounds, *frustum) ? 1 : 0;
    in_frustum += visible[i];
  }
  auto* commands = static_cast<DrawCommand*>(draw_commands.mapped());
  auto* counts = static_cast<uint32_t*>(draw_counts.mapped());
  auto write = [&](bool batch, uint32_t first, uint32_t count, uint32_t count_index) {
    DrawCommand* out = commands + lists.CommandOffset(0, batch, first) / sizeof(DrawCommand);
    uint32_t n = 0;
    for (uint32_t i = first; i < first + count; ++i) {
      if (!visible[i]) continue;
      const DrawItem& d = items[i];
      out[n++] = {{d.index_count, 1, d.first_index, d.vertex_offset, d.drawable},
                  {d.index_count, 1, d.first_index, d.drawable}};
    }
    counts[lists.CountOffset(0, count_index) / 4] = n;
    // Without drawIndirectCount the draws run the whole list: the rest draws nothing.
    std::fill(out + n, out + count, DrawCommand{});
  };
  const uint32_t segments = uint32_t(scene.segments().size());
  for (uint32_t s = 0; s < segments; ++s)
    write(false, scene.segments()[s].first_item, scene.segments()[s].item_count, s);
  for (uint32_t b = 0; b < scene.batches().size(); ++b)
    write(true, scene.batches()[b].first_item, scene.batches()[b].item_count, segments + b);
  uint32_t* stats = counts + lists.CountOffset(0, segments + uint32_t(scene.batches().size())) / 4;
  std::fill(stats, stats + gpu::kCullStatCount, 0u);
  stats[gpu::kCullStatInFrustum] = in_frustum;
}


absl::Status Renderer::Impl::PrepareDraws(FrameData& f) {
  // Geometry culling: the draw lists of every segment and batch of the scene, written by the
  // CPU (none, cpu_frustum) or by the culling passes (gpu_frustum, gpu_occlusion).
  const GpuScene& gs = f.gs;
  const Settings& s = f.s;
  const uint32_t item_count = uint32_t(gs.draws().size());
  const uint32_t segment_count = uint32_t(gs.segments().size());
  const uint32_t list_count = segment_count + uint32_t(gs.batches().size());
  RETURN_IF_ERROR(EnsureCullBuffers(item_count, list_count));
  DrawLists& draws = f.draws;
  draws.commands = draw_commands.handle();
  draws.counts = draw_counts.handle();
  draws.items = std::max(item_count, 1u);
  draws.count_stride = list_count + gpu::kCullStatCount;
  draws.phases = s.culling == CullingMode::kGpuOcclusion ? 2 : 1;
  {  // Blended segments back to front (ties on the drawable, so frames are reproducible).
    std::vector<std::pair<float, uint32_t>> blend;
    for (uint32_t i = 0; i < segment_count; ++i) {
      const DrawSegment& seg = gs.segments()[i];
      if (seg.group != AlphaMode::kBlend) continue;
      const DrawItem& d = gs.draws()[seg.first_item];
      blend.emplace_back(-(f.fu.view * glm::vec4(d.world_bounds.center(), 1.0f)).z, i);
    }
    std::sort(blend.begin(), blend.end(), [&](const auto& a, const auto& b) {
      return a.first != b.first ? a.first > b.first
                                : gs.draws()[gs.segments()[a.second].first_item].drawable <
                                      gs.draws()[gs.segments()[b.second].first_item].drawable;
    });
    for (const auto& [depth, seg] : blend) draws.blend_order.push_back(seg);
  }
  const Frustum frustum = FrustumFromViewProj(f.fu.view_proj);
  CullBuffers& cull = f.cull;
  cull.uniforms = cull_uniforms.handle();
  cull.uniform_stride = cull_uniform_stride;
  cull.bases = cull_bases.handle();
  cull.vis_prev = cull.vis_next = no_visibility.handle();
  if (s.culling == CullingMode::kGpuOcclusion) {
    ASSIGN_OR_RETURN(f.visibility, Visibility(gs, f.view));
    cull.vis_prev = f.visibility->bits[f.visibility->prev].handle();
    cull.vis_next = f.visibility->bits[f.visibility->prev ^ 1].handle();
  }
  if (s.culling != CullingMode::kGpuFrustum && s.culling != CullingMode::kGpuOcclusion) {
    WriteCpuLists(gs, draws, s.culling == CullingMode::kCpuFrustum ? &frustum : nullptr);
    return absl::OkStatus();
  }
  for (uint32_t phase = 0; phase < draws.phases; ++phase) {
    gpu::CullUniforms cu{};
    cu.view_proj = f.fu.view_proj;
    for (int i = 0; i < 6; ++i) cu.planes[i] = frustum[i];
    const uint32_t kind = s.culling == CullingMode::kGpuFrustum ? gpu::kCullPhaseFrustum
                          : phase == 0                         ? gpu::kCullPhaseEarly
                                                               : gpu::kCullPhaseLate;
    cu.counts = glm::uvec4(item_count, segment_count, list_count - segment_count, kind);
    cu.offsets = glm::uvec4(2 * phase * draws.items, phase * draws.count_stride, 0u, 0u);
    cu.hiz = glm::uvec4(targets.hiz_width, targets.hiz_height,
                        uint32_t(targets.hiz_levels.size()), 0u);
    cu.frame = glm::uvec4(s.width, s.height, 0u, 0u);
    std::memcpy(static_cast<uint8_t*>(cull_uniforms.mapped()) + phase * cull_uniform_stride, &cu,
                sizeof(cu));
  }
  return absl::OkStatus();
}

}  // namespace tessera
