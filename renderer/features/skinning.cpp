// Animated scenes (renderer/scene/scene_animator.h): the frame's first pass brings the device to
// the pose GpuScene::Pose computed. It copies the moving drawables' records (world matrix and
// bounds) from the pose buffer into the Drawable buffer, then skins and morphs each deformed
// drawable's vertices from the rest vertices into its copy (shaders/skin.comp, one dispatch for
// all of them). Every later pass (culling, shadows, depth or visibility, shading) reads the posed
// geometry. The pass runs only in frames whose pose differs from what the device holds.
#include <algorithm>

#include "common/status_macros.h"
#include "renderer/features/features.h"
#include "renderer/features/pass.h"
#include "renderer/renderer_impl.h"
#include "renderer/vk/pipeline.h"
#include "renderer/vk/vk_check.h"
#include "shaders/common/gpu_types.h"

namespace tessera {

namespace {

class SkinningPass final : public Pass {
 public:
  SkinningPass(VkDevice device, PassLayout layout, vk::Pipeline pipeline)
      : device_(device), layout_(std::move(layout)), pipeline_(std::move(pipeline)) {}
  PassId id() const override { return PassId::kSkinning; }

  void Record(PassContext& ctx) override {
    const GpuScene& gs = *ctx.scene;
    const std::vector<VkBufferCopy>& copies = gs.pose_copies();
    if (!copies.empty()) {
      vkCmdCopyBuffer(ctx.cmd, gs.pose_buffer().handle(), gs.drawables().handle(),
                      uint32_t(copies.size()), copies.data());
    }
    if (gs.skin_job_count() > 0) {
      const VkDescriptorSet set = layout_.Allocate(ctx);
      SetWriter(device_, set)
          .Buffer(gpu::kSkinBindingVertices, gs.vertices().handle())
          .Buffer(gpu::kSkinBindingAttributes, gs.skin_attributes().handle())
          .Buffer(gpu::kSkinBindingDeltas, gs.morph_deltas().handle())
          .Buffer(gpu::kSkinBindingPose, gs.pose_buffer().handle())
          .Buffer(gpu::kSkinBindingJobs, gs.skin_jobs().handle())
          .Update();
      vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_.handle());
      vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout_.pipeline_layout(),
                              0, 1, &set, 0, nullptr);
      // Every deformed drawable in one dispatch (several past the device's workgroup count
      // limit). The jobs write disjoint copies and read only rest vertices: no barriers.
      const uint64_t limit = ctx.vk->limits().maxComputeWorkGroupCount[0];
      for (uint64_t first = 0; first < gs.skin_groups(); first += limit) {
        const gpu::SkinPush push{glm::uvec4(gs.skin_job_count(), uint32_t(first), 0, 0)};
        vkCmdPushConstants(ctx.cmd, layout_.pipeline_layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0,
                           sizeof(push), &push);
        vkCmdDispatch(ctx.cmd, uint32_t(std::min(limit, gs.skin_groups() - first)), 1, 1);
      }
    }
    // The graph orders the copy and the dispatches (Resource::kPosedGeometry, written in the
    // compute and transfer stages) before every pass that reads the geometry.
  }

 private:
  VkDevice device_;
  PassLayout layout_;
  vk::Pipeline pipeline_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateSkinningPass(const vk::Context& ctx) {
  std::vector<VkDescriptorSetLayoutBinding> bindings;
  for (uint32_t b : {gpu::kSkinBindingVertices, gpu::kSkinBindingAttributes,
                     gpu::kSkinBindingDeltas, gpu::kSkinBindingPose, gpu::kSkinBindingJobs})
    bindings.push_back(
        LayoutBinding(b, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, VK_SHADER_STAGE_COMPUTE_BIT));
  absl::StatusOr<PassLayout> layout = PassLayout::Create(
      ctx, bindings, {{VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(gpu::SkinPush)}}, "skinning layout");
  if (!layout.ok()) return layout.status();
  ASSIGN_OR_RETURN(vk::Pipeline pipeline, vk::CreateComputePipeline(ctx, "skinning", "skin.comp",
                                                                    layout->pipeline_layout()));
  return std::make_unique<SkinningPass>(ctx.device(), std::move(*layout), std::move(pipeline));
}

void SetupSkinning(GraphBuilder& b) {
  if (!b.features().pose_pending) return;
  b.Pass(PassId::kSkinning).Use(Resource::kPosedGeometry, Access::kComputeWrite);
}

}  // namespace tessera
