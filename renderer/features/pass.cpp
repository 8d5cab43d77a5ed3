// Helpers shared by the passes: beginning a rendering over the frame, and drawing scene items.
#include "renderer/features/pass.h"

#include <algorithm>
#include <cstddef>
#include <utility>

#include "common/status_macros.h"
#include "renderer/vk/context.h"
#include "renderer/vk/vk_check.h"
#include "shaders/common/gpu_types.h"

namespace tessera {

void BeginRendering(const PassContext& ctx, const VkRenderingAttachmentInfo* color,
                    const VkRenderingAttachmentInfo* depth) {
  BeginRendering(ctx, color, color ? 1 : 0, depth);
}

void ResolveDepthInto(const PassContext& ctx, VkRenderingAttachmentInfo& depth) {
  depth.resolveMode = ctx.vk->info().depth_resolve_min ? VK_RESOLVE_MODE_MIN_BIT
                                                       : VK_RESOLVE_MODE_SAMPLE_ZERO_BIT;
  depth.resolveImageView = ctx.targets->depth.view();
  depth.resolveImageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
}

void BeginRendering(const PassContext& ctx, const VkRenderingAttachmentInfo* colors,
                    uint32_t color_count, const VkRenderingAttachmentInfo* depth,
                    VkExtent2D extent) {
  if (extent.width == 0) extent = {ctx.targets->width, ctx.targets->height};
  const VkRect2D full{{0, 0}, extent};
  VkRenderingInfo ri{VK_STRUCTURE_TYPE_RENDERING_INFO};
  ri.renderArea = full;
  ri.layerCount = 1;
  ri.colorAttachmentCount = color_count;
  ri.pColorAttachments = colors;
  ri.pDepthAttachment = depth;
  vkCmdBeginRendering(ctx.cmd, &ri);
  const VkViewport viewport{0.0f, 0.0f, float(full.extent.width), float(full.extent.height),
                            0.0f, 1.0f};
  vkCmdSetViewport(ctx.cmd, 0, 1, &viewport);
  vkCmdSetScissor(ctx.cmd, 0, 1, &full);
}

uint32_t ShadingEffects(const Settings& s) {
  return (s.shadows ? gpu::kShadowsOn : 0u) | (s.ssao ? gpu::kSsaoOn : 0u) |
         (s.ibl ? gpu::kIblOn : 0u);
}

ShadingConstants ShadingConstantsFor(const Settings& s, const FrameFeatures& features,
                                     uint32_t textures) {
  ShadingConstants c;
  // The tile lists' loop only where there are local lights: on lavapipe it cost plain Sponza's
  // shading 10 ms with no light to shade (79-81 -> 69-71 ms without it).
  c.effects = ShadingEffects(s) | (features.local_lights > 0 ? gpu::kLocalLightsOn : 0u);
  // The global lights' loop only where it has lights to shade: with shadows the first global
  // light (the sun) is shaded on its own, so a frame whose one global light is the sun has none
  // left, and lavapipe ran the empty loop's body (Sponza's full stack: shading 164-180 ->
  // 152-167 ms).
  if (features.global_lights > (s.shadows ? 1u : 0u)) c.effects |= gpu::kGlobalLightsOn;
  c.textures = textures;
  c.debug = ShadingDebugView(s);
  c.light_texels = features.light_texels ? 1u : 0u;
  return c;
}

uint32_t ShadingDebugView(const Settings& s) {
  switch (s.debug_view) {
    case DebugView::kNormals: return gpu::kDebugNormals;
    case DebugView::kDepth: return gpu::kDebugDepth;
    case DebugView::kBaseColor: return gpu::kDebugBaseColor;
    case DebugView::kLightHeatmap: return gpu::kDebugLightHeatmap;
    case DebugView::kCascades: return gpu::kDebugCascades;
    default: return gpu::kDebugNone;
  }
}

void BeginSceneDraw(const PassContext& ctx, VkPipeline pipeline, VkPipelineLayout layout) {
  if (pipeline != VK_NULL_HANDLE)
    vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline);
  vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS,
                          layout ? layout : ctx.scene_pipeline_layout, 0, 1, &ctx.scene_set, 0,
                          nullptr);
  const VkBuffer vb = ctx.scene->vertices().handle();
  const VkDeviceSize offset = 0;
  vkCmdBindVertexBuffers(ctx.cmd, 0, 1, &vb, &offset);
  vkCmdBindIndexBuffer(ctx.cmd, ctx.scene->indices().handle(), 0, VK_INDEX_TYPE_UINT32);
}

absl::StatusOr<PassLayout> PassLayout::Create(
    const vk::Context& ctx, const std::vector<VkDescriptorSetLayoutBinding>& bindings,
    const std::vector<VkPushConstantRange>& push, const char* name,
    const std::vector<VkDescriptorSetLayout>& before) {
  PassLayout l;
  l.device_ = ctx.device();
  RETURN_IF_ERROR(ctx.CreateSetLayout(bindings, name, &l.set_layout_));
  std::vector<VkDescriptorSetLayout> sets = before;
  sets.push_back(l.set_layout_.get());
  RETURN_IF_ERROR(ctx.CreatePipelineLayout(sets, push, name, &l.layout_));
  return l;
}

VkDescriptorSet AllocateFrameSet(const PassContext& ctx, VkDescriptorSetLayout layout) {
  VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  ai.descriptorPool = ctx.frame_pool;
  ai.descriptorSetCount = 1;
  ai.pSetLayouts = &layout;
  VkDescriptorSet set;
  VK_CHECK(vkAllocateDescriptorSets(ctx.vk->device(), &ai, &set));
  return set;
}

SetWriter& SetWriter::Sampled(uint32_t binding, VkSampler sampler, VkImageView view,
                              VkImageLayout layout) {
  images_.push_back({sampler, view, layout});
  Write(binding, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER).pImageInfo = &images_.back();
  return *this;
}

VkWriteDescriptorSet& SetWriter::Write(uint32_t binding, VkDescriptorType type) {
  VkWriteDescriptorSet& w = writes_.emplace_back(VkWriteDescriptorSet{
      VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET});
  w.dstSet = set_;
  w.dstBinding = binding;
  w.descriptorCount = 1;
  w.descriptorType = type;
  return w;
}

SetWriter& SetWriter::Storage(uint32_t binding, VkImageView view) {
  Sampled(binding, VK_NULL_HANDLE, view, VK_IMAGE_LAYOUT_GENERAL);
  writes_.back().descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE;
  return *this;
}

SetWriter& SetWriter::Buffer(uint32_t binding, VkBuffer buffer, VkDescriptorType type,
                             VkDeviceSize offset, VkDeviceSize range) {
  buffers_.push_back({buffer, offset, range});
  Write(binding, type).pBufferInfo = &buffers_.back();
  return *this;
}

SetWriter& SetWriter::TexelBuffer(uint32_t binding, VkBufferView view) {
  texel_views_.push_back(view);
  Write(binding, VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER).pTexelBufferView = &texel_views_.back();
  return *this;
}

SetWriter& SetWriter::StorageBuffer(uint32_t binding, const PassContext& ctx,
                                    const vk::Buffer& buffer) {
  return Buffer(binding, buffer.handle(), VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 0,
                std::min<VkDeviceSize>(buffer.size(), ctx.vk->limits().maxStorageBufferRange));
}

SetWriter& SetWriter::SceneGeometry(const PassContext& ctx) {
  const GpuScene& scene = *ctx.scene;
  // The pipelines' shaders hold both paths (vis.glsl), so both are bound whichever they read.
  return StorageBuffer(gpu::kVisBindingIndices, ctx, scene.indices())
      .StorageBuffer(gpu::kVisBindingVertices, ctx, scene.vertices())
      .TexelBuffer(gpu::kVisBindingIndexTexels, scene.index_texels())
      .TexelBuffer(gpu::kVisBindingVertexTexels, scene.vertex_texels())
      .TexelBuffer(gpu::kVisBindingDrawableTexels, scene.drawable_texels());
}

SetWriter& SetWriter::VisibilityBuffers(const PassContext& ctx) {
  return SceneGeometry(ctx)
      .Buffer(gpu::kShadeBindingEntries, ctx.shade->entries)
      .Buffer(gpu::kShadeBindingPixels, ctx.shade->pixels);
}

std::vector<VkDescriptorSetLayoutBinding> SceneGeometryBindings(VkShaderStageFlags stages) {
  constexpr VkDescriptorType kBuffer = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  constexpr VkDescriptorType kTexels = VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;
  return {LayoutBinding(gpu::kVisBindingIndices, kBuffer, stages),
          LayoutBinding(gpu::kVisBindingVertices, kBuffer, stages),
          LayoutBinding(gpu::kVisBindingIndexTexels, kTexels, stages),
          LayoutBinding(gpu::kVisBindingVertexTexels, kTexels, stages),
          LayoutBinding(gpu::kVisBindingDrawableTexels, kTexels, stages)};
}

std::vector<VkDescriptorSetLayoutBinding> VisibilityBufferBindings() {
  constexpr VkShaderStageFlags kCompute = VK_SHADER_STAGE_COMPUTE_BIT;
  std::vector<VkDescriptorSetLayoutBinding> b = SceneGeometryBindings(kCompute);
  b.push_back(LayoutBinding(gpu::kShadeBindingEntries, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, kCompute));
  b.push_back(LayoutBinding(gpu::kShadeBindingPixels, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, kCompute));
  return b;
}

void SetWriter::Update() {
  vkUpdateDescriptorSets(device_, uint32_t(writes_.size()), writes_.data(), 0, nullptr);
}

VkDescriptorSet PassLayout::Allocate(const PassContext& ctx) const {
  return AllocateFrameSet(ctx, set_layout_.get());
}

void DrawState::Apply(const PassContext& ctx, bool double_sided, uint32_t m, bool textured) {
  if (textured && m != material) {
    const VkDescriptorSet set = ctx.scene->material_set(m);
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS,
                            layout ? layout : ctx.scene_pipeline_layout, gpu::kMaterialSet, 1,
                            &set, 0, nullptr);
    material = m;
  }
  const int want = double_sided ? 0 : 1;
  if (want != cull) {
    vkCmdSetCullMode(ctx.cmd, want ? VK_CULL_MODE_BACK_BIT : VK_CULL_MODE_NONE);
    cull = want;
  }
}

namespace {

// `pulled`: the commands' non-indexed half (DrawCommand::pulled).
void DrawIndirect(const PassContext& ctx, uint32_t phase, bool batch, uint32_t first_item,
                  uint32_t capacity, uint32_t count_index, bool pulled) {
  const DrawLists& d = *ctx.draws;
  const VkDeviceSize offset =
      d.CommandOffset(phase, batch, first_item) + (pulled ? offsetof(DrawCommand, pulled) : 0);
  constexpr uint32_t kStride = sizeof(DrawCommand);
  const DeviceInfo& info = ctx.vk->info();
  if (info.draw_indirect_count) {
    const VkDeviceSize count_offset = d.CountOffset(phase, count_index);
    if (pulled)
      vkCmdDrawIndirectCount(ctx.cmd, d.commands, offset, d.counts, count_offset, capacity, kStride);
    else
      vkCmdDrawIndexedIndirectCount(ctx.cmd, d.commands, offset, d.counts, count_offset, capacity,
                                    kStride);
    ctx.stats->indirect_draws++;
    return;
  }
  // No GPU-written count: the list's whole capacity, whose commands past the count are zero
  // (DrawLists) and draw nothing; as few calls as maxDrawIndirectCount allows.
  const uint32_t per_call = std::max(info.max_draw_indirect_count, 1u);
  for (uint32_t done = 0; done < capacity; done += per_call) {
    const VkDeviceSize at = offset + VkDeviceSize(done) * kStride;
    const uint32_t n = std::min(per_call, capacity - done);
    if (pulled)
      vkCmdDrawIndirect(ctx.cmd, d.commands, at, n, kStride);
    else
      vkCmdDrawIndexedIndirect(ctx.cmd, d.commands, at, n, kStride);
    ctx.stats->indirect_draws++;
  }
}

}  // namespace

void RecordSegments(const PassContext& ctx, AlphaMode group, uint32_t phase_begin,
                    uint32_t phase_end, bool textured,
                    absl::FunctionRef<VkPipeline(uint32_t)> pipeline_of,
                    const PulledGeometry* pulled) {
  const std::vector<DrawSegment>& segments = ctx.scene->segments();
  DrawState state;
  if (pulled) state.layout = pulled->layout;
  auto draw = [&](uint32_t s) {
    const DrawSegment& seg = segments[s];
    const VkPipeline pipeline = pipeline_of(seg.material);
    if (pipeline != VK_NULL_HANDLE && pipeline != state.pipeline) {
      vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline);
      state.pipeline = pipeline;
    }
    state.Apply(ctx, seg.double_sided, seg.material, textured);
    for (uint32_t p = phase_begin; p < phase_end; ++p)
      DrawIndirect(ctx, p, false, seg.first_item, seg.item_count, s, pulled != nullptr);
  };
  if (group == AlphaMode::kBlend) {
    for (uint32_t s : ctx.draws->blend_order) draw(s);
    return;
  }
  for (uint32_t s = 0; s < segments.size(); ++s)
    if (segments[s].group == group) draw(s);
}

void RecordAllDirect(const PassContext& ctx) {
  DrawState state;
  for (const DrawItem& item : ctx.scene->draws()) {
    state.Apply(ctx, item.double_sided, item.material, /*textured=*/true);
    vkCmdDrawIndexed(ctx.cmd, item.index_count, 1, item.first_index, item.vertex_offset,
                     item.drawable);
  }
}

void RecordBatches(const PassContext& ctx, uint32_t phase, const PulledGeometry* pulled) {
  const std::vector<DrawBatch>& batches = ctx.scene->batches();
  DrawState state;
  if (pulled) state.layout = pulled->layout;
  const uint32_t segment_count = static_cast<uint32_t>(ctx.scene->segments().size());
  for (uint32_t b = 0; b < batches.size(); ++b) {
    state.Apply(ctx, batches[b].double_sided, 0, /*textured=*/false);
    DrawIndirect(ctx, phase, true, batches[b].first_item, batches[b].item_count,
                 segment_count + b, pulled != nullptr);
  }
}

void RecordDepthGeometry(const PassContext& ctx, VkPipeline opaque, VkPipeline mask,
                         uint32_t phase, const PulledGeometry* pulled) {
  const VkPipelineLayout layout = pulled ? pulled->layout : VK_NULL_HANDLE;
  auto begin = [&](VkPipeline pipeline) {
    BeginSceneDraw(ctx, pipeline, layout);
    if (!pulled) return;
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout, gpu::kVisSet, 1,
                            &pulled->set, 0, nullptr);
    const VkBuffer drawables = ctx.scene->drawables().handle();
    const VkDeviceSize offset = 0;
    vkCmdBindVertexBuffers(ctx.cmd, gpu::kDrawableInputBinding, 1, &drawables, &offset);
  };
  if (!ctx.scene->batches().empty()) {
    begin(opaque);
    RecordBatches(ctx, phase, pulled);
  }
  begin(mask);
  RecordSegments(ctx, AlphaMode::kMask, phase, phase + 1, /*textured=*/true, NoPipelineChange,
                 pulled);
}

}  // namespace tessera
