// The depth pyramid (HiZ) for occlusion culling (shaders/hiz_build.comp): level 0 from the depth
// buffer at the power of two at or below half the frame size, then each level from the one below
// with a min-reduction sampler. One dispatch per level, with a barrier on the level just
// written; every level stays in the general layout until the frame graph hands the pyramid to
// the culling pass.
#include <algorithm>

#include "renderer/features/pass.h"
#include "renderer/vk/pipeline.h"
#include "renderer/vk/vk_check.h"
#include "shaders/common/gpu_types.h"

namespace tessera {

namespace {

class HizBuildPass final : public Pass {
 public:
  HizBuildPass(VkDevice device, PassLayout layout, vk::Pipeline pipeline,
               vk::Sampler depth_sampler, vk::Sampler min_sampler, bool minmax)
      : device_(device),
        layout_(std::move(layout)),
        pipeline_(std::move(pipeline)),
        depth_sampler_(std::move(depth_sampler)),
        min_sampler_(std::move(min_sampler)),
        minmax_(minmax) {}
  PassId id() const override { return PassId::kHizBuild; }

  void Record(PassContext& ctx) override {
    const FrameTargets& t = *ctx.targets;
    vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_.handle());
    uint32_t src_w = t.width, src_h = t.height;
    for (uint32_t level = 0; level < t.hiz_levels.size(); ++level) {
      const uint32_t dst_w = std::max(1u, t.hiz_width >> level);
      const uint32_t dst_h = std::max(1u, t.hiz_height >> level);
      const VkDescriptorSet set = layout_.Allocate(ctx);
      SetWriter w(device_, set);
      if (level == 0) {
        w.Sampled(gpu::kHizBindingSource, depth_sampler_.handle(), t.depth.view());
      } else {
        w.Sampled(gpu::kHizBindingSource,
                  minmax_ ? min_sampler_.handle() : depth_sampler_.handle(),
                  t.hiz_levels[level - 1], VK_IMAGE_LAYOUT_GENERAL);
      }
      w.Storage(gpu::kHizBindingDest, t.hiz_levels[level]).Update();
      vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout_.pipeline_layout(),
                              0, 1, &set, 0, nullptr);
      // Each level view has one mip, so the source level is 0 in its view.
      const gpu::HizPush push{glm::uvec2(src_w, src_h), glm::uvec2(dst_w, dst_h),
                              level == 0 ? 0u : (minmax_ ? 1u : 2u), 0u};
      vkCmdPushConstants(ctx.cmd, layout_.pipeline_layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
      vkCmdDispatch(ctx.cmd, (dst_w + gpu::kHizGroupSize - 1) / gpu::kHizGroupSize,
                    (dst_h + gpu::kHizGroupSize - 1) / gpu::kHizGroupSize, 1);
      // The level just written is the next dispatch's source.
      const VkImageMemoryBarrier2 b = vk::MakeImageBarrier(
          t.hiz,
          {VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
           VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
           VK_ACCESS_2_SHADER_SAMPLED_READ_BIT, VK_IMAGE_LAYOUT_GENERAL},
          level, 1);
      vk::CmdBarrier(ctx.cmd, &b, 1);
      src_w = dst_w;
      src_h = dst_h;
    }
  }

 private:
  VkDevice device_;
  PassLayout layout_;
  vk::Pipeline pipeline_;
  vk::Sampler depth_sampler_;
  vk::Sampler min_sampler_;
  bool minmax_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateHizBuildPass(const vk::Context& ctx) {
  const std::vector<VkDescriptorSetLayoutBinding> bindings = {
      {gpu::kHizBindingSource, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
       VK_SHADER_STAGE_COMPUTE_BIT, nullptr},
      {gpu::kHizBindingDest, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1, VK_SHADER_STAGE_COMPUTE_BIT,
       nullptr},
  };
  absl::StatusOr<PassLayout> layout = PassLayout::Create(
      ctx, bindings, {{VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(gpu::HizPush)}}, "hiz layout");
  if (!layout.ok()) return layout.status();
  absl::StatusOr<vk::Pipeline> pipeline = vk::CreateComputePipeline(
      ctx, "hiz_build", "hiz_build.comp", layout->pipeline_layout());
  VkSamplerCreateInfo si{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
  si.magFilter = si.minFilter = VK_FILTER_NEAREST;
  si.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST;
  si.addressModeU = si.addressModeV = si.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
  absl::StatusOr<vk::Sampler> nearest = vk::Sampler::Create(ctx, si, "hiz.nearest");
  const bool minmax = ctx.info().sampler_minmax;
  VkSamplerReductionModeCreateInfo reduction{VK_STRUCTURE_TYPE_SAMPLER_REDUCTION_MODE_CREATE_INFO};
  reduction.reductionMode = VK_SAMPLER_REDUCTION_MODE_MIN;
  if (minmax) si.pNext = &reduction;
  si.magFilter = si.minFilter = VK_FILTER_LINEAR;
  absl::StatusOr<vk::Sampler> min_sampler = vk::Sampler::Create(ctx, si, "hiz.min");
  if (!pipeline.ok()) return pipeline.status();
  if (!nearest.ok()) return nearest.status();
  if (!min_sampler.ok()) return min_sampler.status();
  return std::make_unique<HizBuildPass>(ctx.device(), std::move(*layout), std::move(*pipeline),
                                        std::move(*nearest), std::move(*min_sampler), minmax);
}

}  // namespace tessera
