// Helpers shared by the passes: beginning a rendering over the frame, and drawing scene items.
#include "renderer/passes/pass.h"

namespace tessera {

void BeginRendering(const PassContext& ctx, const VkRenderingAttachmentInfo* color,
                    const VkRenderingAttachmentInfo* depth) {
  const VkRect2D full{{0, 0}, {ctx.targets->width, ctx.targets->height}};
  VkRenderingInfo ri{VK_STRUCTURE_TYPE_RENDERING_INFO};
  ri.renderArea = full;
  ri.layerCount = 1;
  ri.colorAttachmentCount = color ? 1 : 0;
  ri.pColorAttachments = color;
  ri.pDepthAttachment = depth;
  vkCmdBeginRendering(ctx.cmd, &ri);
  const VkViewport viewport{0.0f, 0.0f, float(full.extent.width), float(full.extent.height),
                            0.0f, 1.0f};
  vkCmdSetViewport(ctx.cmd, 0, 1, &viewport);
  vkCmdSetScissor(ctx.cmd, 0, 1, &full);
}

void BeginSceneDraw(const PassContext& ctx, VkPipeline pipeline) {
  vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline);
  vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, ctx.scene_pipeline_layout, 0, 1,
                          &ctx.scene_set, 0, nullptr);
  const VkBuffer vb = ctx.scene->vertices().handle();
  const VkDeviceSize offset = 0;
  vkCmdBindVertexBuffers(ctx.cmd, 0, 1, &vb, &offset);
  vkCmdBindIndexBuffer(ctx.cmd, ctx.scene->indices().handle(), 0, VK_INDEX_TYPE_UINT32);
}

void RecordDraws(const PassContext& ctx, const std::vector<const DrawItem*>& items, bool textured) {
  int cull = -1;
  uint32_t material = UINT32_MAX;
  for (const DrawItem* item : items) {
    if (textured && item->material != material) {
      const VkDescriptorSet set = ctx.scene->material_set(item->material);
      vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, ctx.scene_pipeline_layout,
                              gpu::kMaterialSet, 1, &set, 0, nullptr);
      material = item->material;
    }
    const int want = item->double_sided ? 0 : 1;
    if (want != cull) {
      vkCmdSetCullMode(ctx.cmd, want ? VK_CULL_MODE_BACK_BIT : VK_CULL_MODE_NONE);
      cull = want;
    }
    vkCmdDrawIndexed(ctx.cmd, item->index_count, 1, item->first_index, item->vertex_offset,
                     item->drawable);
    ctx.stats->draws++;
    ctx.stats->triangles += item->index_count / 3;
  }
}

}  // namespace tessera
