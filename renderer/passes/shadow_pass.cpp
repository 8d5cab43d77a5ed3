// Shadow maps into the atlas: for each face the renderer decided to (re)render this frame (its
// view changed, or it was evicted, or caching is off), clear its square and draw the opaque and
// alpha-mask items in its frustum, depth only, through the face's matrix (a push constant).
// Cached faces are not touched: the atlas is loaded, not cleared, so a frame where nothing
// changed records no draw at all. The atlas lives across frames outside the frame graph; it
// waits in shader-read layout and this pass moves it to attachment layout and back.
// Draws are direct (one per item in the face's frustum, the items culled on the CPU per face):
// a face sees few items, and its list changes with the face, not per frame.
#include "renderer/passes/pass.h"
#include "renderer/vk/pipeline.h"
#include "renderer/vk/vk_check.h"

namespace tessera {

namespace {

// Depth bias of the shadow maps, in D16 units and per unit of depth slope: with the shader's
// normal offset this keeps lit surfaces free of acne without visible peter-panning.
constexpr float kBiasConstant = 2.0f;
constexpr float kBiasSlope = 1.75f;

class ShadowPass final : public Pass {
 public:
  PassId id() const override { return PassId::kShadows; }

  static absl::StatusOr<std::unique_ptr<Pass>> Create(const vk::Context& ctx,
                                                      const SceneLayout& scene) {
    auto pass = std::make_unique<ShadowPass>();
    pass->device_ = ctx.device();
    const VkDescriptorSetLayout sets[] = {scene.set_layout, scene.material_set_layout};
    const VkPushConstantRange push{VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(glm::mat4)};
    VkPipelineLayoutCreateInfo pli{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    pli.setLayoutCount = 2;
    pli.pSetLayouts = sets;
    pli.pushConstantRangeCount = 1;
    pli.pPushConstantRanges = &push;
    VK_RETURN_IF_ERROR(vkCreatePipelineLayout(ctx.device(), &pli, nullptr, &pass->layout_),
                       "shadow pipeline layout");
    vk::GraphicsPipelineDesc d;
    d.name = "shadows.opaque";
    d.vertex_shader = "shadow.vert";
    d.layout = pass->layout_;
    d.depth_format = kShadowFormat;
    d.depth_test = true;
    d.depth_write = true;
    d.depth_compare = VK_COMPARE_OP_LESS;  // standard Z in the atlas (renderer/shadows.h)
    d.depth_bias_constant = kBiasConstant;
    d.depth_bias_slope = kBiasSlope;
    absl::StatusOr<vk::Pipeline> opaque = vk::CreateGraphicsPipeline(ctx, d);
    if (!opaque.ok()) return opaque.status();
    pass->opaque_ = std::move(*opaque);
    d.name = "shadows.mask";
    d.vertex_shader = "shadow_mask.vert";
    d.fragment_shader = "depth_mask.frag";
    d.attribute_mask = (1u << gpu::kAttrPosition) | (1u << gpu::kAttrUv0) | (1u << gpu::kAttrUv1);
    absl::StatusOr<vk::Pipeline> mask = vk::CreateGraphicsPipeline(ctx, d);
    if (!mask.ok()) return mask.status();
    pass->mask_ = std::move(*mask);
    return std::unique_ptr<Pass>(std::move(pass));
  }

  ~ShadowPass() override {
    if (layout_) vkDestroyPipelineLayout(device_, layout_, nullptr);
  }

  void Record(PassContext& ctx) override {
    const ShadowFrame& sf = *ctx.shadows;
    const vk::Image& atlas = *sf.atlas;
    if (sf.faces.empty() && !sf.atlas_new) return;  // every face cached: nothing to do
    const VkImageLayout read = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
    const VkImageLayout attach = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
    constexpr VkPipelineStageFlags2 kDepthStages =
        VK_PIPELINE_STAGE_2_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_2_LATE_FRAGMENT_TESTS_BIT;
    constexpr VkAccessFlags2 kDepthAccess = VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT |
                                            VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT;
    // Last frame's shading read it (or it is new); loading keeps the cached faces.
    VkImageMemoryBarrier2 before = vk::MakeImageBarrier(
        atlas, {VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT, VK_ACCESS_2_SHADER_SAMPLED_READ_BIT,
                sf.atlas_new ? VK_IMAGE_LAYOUT_UNDEFINED : read, kDepthStages, kDepthAccess,
                attach});
    vk::CmdBarrier(ctx.cmd, &before, 1);
    const uint32_t size = atlas.desc().width;
    VkRenderingAttachmentInfo depth{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    depth.imageView = atlas.view();
    depth.imageLayout = attach;
    depth.loadOp = sf.atlas_new ? VK_ATTACHMENT_LOAD_OP_CLEAR : VK_ATTACHMENT_LOAD_OP_LOAD;
    depth.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    depth.clearValue.depthStencil = {1.0f, 0};
    VkRenderingInfo ri{VK_STRUCTURE_TYPE_RENDERING_INFO};
    ri.renderArea = {{0, 0}, {size, size}};
    ri.layerCount = 1;
    ri.pDepthAttachment = &depth;
    vkCmdBeginRendering(ctx.cmd, &ri);
    const VkBuffer vb = ctx.scene->vertices().handle();
    const VkDeviceSize offset = 0;
    vkCmdBindVertexBuffers(ctx.cmd, 0, 1, &vb, &offset);
    vkCmdBindIndexBuffer(ctx.cmd, ctx.scene->indices().handle(), 0, VK_INDEX_TYPE_UINT32);
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout_, 0, 1,
                            &ctx.scene_set, 0, nullptr);
    // Both sides of every surface cast: open geometry (a wall plane) must still block the
    // light from behind; the bias handles the acne of front faces.
    vkCmdSetCullMode(ctx.cmd, VK_CULL_MODE_NONE);
    const std::vector<DrawItem>& items = ctx.scene->draws();
    for (const ShadowFace& face : sf.faces) {
      const VkRect2D rect{{int32_t(face.x), int32_t(face.y)}, {face.size, face.size}};
      const VkViewport viewport{float(face.x), float(face.y), float(face.size),
                                float(face.size), 0.0f, 1.0f};
      vkCmdSetViewport(ctx.cmd, 0, 1, &viewport);
      vkCmdSetScissor(ctx.cmd, 0, 1, &rect);
      if (!sf.atlas_new) {
        VkClearAttachment clear{VK_IMAGE_ASPECT_DEPTH_BIT, 0, {}};
        clear.clearValue.depthStencil = {1.0f, 0};
        const VkClearRect clear_rect{rect, 0, 1};
        vkCmdClearAttachments(ctx.cmd, 1, &clear, 1, &clear_rect);
      }
      VkPipeline bound = VK_NULL_HANDLE;
      uint32_t material = UINT32_MAX;
      for (uint32_t i : face.items) {
        const DrawItem& item = items[i];
        const bool mask = item.alpha == AlphaMode::kMask;
        const VkPipeline want = mask ? mask_.handle() : opaque_.handle();
        if (want != bound) {
          vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, want);
          vkCmdPushConstants(ctx.cmd, layout_, VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(glm::mat4),
                             &face.view_proj);
          bound = want;
        }
        if (mask && item.material != material) {
          const VkDescriptorSet set = ctx.scene->material_set(item.material);
          vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout_,
                                  gpu::kMaterialSet, 1, &set, 0, nullptr);
          material = item.material;
        }
        vkCmdDrawIndexed(ctx.cmd, item.index_count, 1, item.first_index, item.vertex_offset,
                         item.drawable);
      }
    }
    vkCmdEndRendering(ctx.cmd);
    VkImageMemoryBarrier2 after = vk::MakeImageBarrier(
        atlas, {kDepthStages, VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT, attach,
                VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT, VK_ACCESS_2_SHADER_SAMPLED_READ_BIT,
                read});
    vk::CmdBarrier(ctx.cmd, &after, 1);
  }

 private:
  VkDevice device_ = VK_NULL_HANDLE;
  VkPipelineLayout layout_ = VK_NULL_HANDLE;
  vk::Pipeline opaque_, mask_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateShadowPass(const vk::Context& ctx,
                                                       const SceneLayout& layout) {
  return ShadowPass::Create(ctx, layout);
}

}  // namespace tessera
