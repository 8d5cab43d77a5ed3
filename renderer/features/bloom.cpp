// Bloom (Jimenez, "Next Generation Post Processing in Call of Duty: Advanced Warfare", 2014):
// the tonemap's input, exposed and soft-thresholded, downsampled by the 13-tap filter into
// kBloomLevels mips of bloom_down (shaders/bloom_down.frag), then upsampled with a 3x3 tent
// back up through bloom_up, each level adding the downsample chain's level of its size
// (shaders/bloom_up.frag). bloom_up's level 0 (half the frame) holds the sum of every level's
// blur: the tonemap pass adds it, divided by the level count, at bloom_strength.
//
// The frame graph hands both chains over as colour targets (every mip). Each mip is drawn and
// then read by the next draw: the pass makes those per-mip transitions itself, and at the end
// puts bloom_up's read mips back in the colour-target layout, so that the whole image is where
// the graph believes it is (its transition then makes level 0 readable by the tonemap pass).
// bloom_down's mips stay in the shader-read layout: nothing after this pass uses them, and the
// next frame's graph starts them from the undefined layout.
#include <algorithm>

#include "common/status_macros.h"
#include "renderer/features/features.h"
#include "renderer/features/pass.h"
#include "renderer/vk/vk_check.h"

namespace tessera {

namespace {

// What passes the threshold: exposed values above 1 (brighter than the display's white), with a
// soft knee of +-0.5 around it.
constexpr float kThreshold = 1.0f;
constexpr float kKnee = 0.5f;

class BloomPass final : public Pass {
 public:
  BloomPass(FullscreenProgram down, FullscreenProgram up, vk::Sampler linear, vk::Sampler nearest)
      : down_(std::move(down)),
        up_(std::move(up)),
        linear_(std::move(linear)),
        nearest_(std::move(nearest)) {}
  PassId id() const override { return PassId::kBloom; }

  // The downsample's variants (gpu_types.h): the first level's and the others', each also in
  // 2x2 pixels an invocation in compute (for a level exactly half its source, HalvesExactly).
  absl::Status Prepare(const vk::Context& ctx, const Settings& s) override {
    if (!s.bloom) return absl::OkStatus();
    const bool compute = FullscreenProgram::Compute(s);
    for (uint32_t variant : {0u, gpu::kBloomDownFirst, gpu::kBloomDownQuads,
                             gpu::kBloomDownFirst | gpu::kBloomDownQuads}) {
      if (!compute && (variant & gpu::kBloomDownQuads)) continue;
      RETURN_IF_ERROR(down_.Ensure(ctx, s, variant));
    }
    return absl::OkStatus();
  }

  void Record(PassContext& ctx) override {
    const FrameTargets& t = *ctx.targets;
    const uint32_t levels = uint32_t(t.bloom_down_levels.size());
    auto extent = [&](uint32_t level) {
      return VkExtent2D{std::max(1u, t.bloom_down.desc().width >> level),
                        std::max(1u, t.bloom_down.desc().height >> level)};
    };
    const bool compute = FullscreenProgram::Compute(*ctx.settings);
    // In compute both chains stay in the general layout; a mip is read after the dispatch that
    // wrote it.
    const VkImageLayout read = compute ? VK_IMAGE_LAYOUT_GENERAL
                                       : VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
    auto written = [&](const vk::Image& image, uint32_t level) {
      if (!compute) return ToRead(ctx, image, level);
      const VkPipelineStageFlags2 cs = VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;
      vk::CmdMemoryBarrier(ctx.cmd, cs, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, cs,
                           VK_ACCESS_2_SHADER_SAMPLED_READ_BIT);
    };
    const PostInput exposure{ctx.exposure->view, nearest_.handle(), ctx.exposure->layout};
    gpu::BloomDownPush down{glm::vec4(0.0f), glm::vec4(kThreshold, kKnee, 0.0f, 0.0f),
                            ctx.exposure->params};
    for (uint32_t i = 0; i < levels; ++i) {
      const VkExtent2D src = i == 0 ? VkExtent2D{t.width, t.height} : extent(i - 1);
      down.src = glm::vec4(1.0f / float(src.width), 1.0f / float(src.height), 0.0f, 0.0f);
      const PostInput in{i == 0 ? PostColor(ctx).view() : t.bloom_down_levels[i - 1],
                         linear_.handle(),
                         i == 0 ? VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL : read};
      const uint32_t variant = (i == 0 ? gpu::kBloomDownFirst : 0u) |
                               (compute && HalvesExactly(src, extent(i)) ? gpu::kBloomDownQuads : 0u);
      // kBloomDownQuads' invocations take 2x2 pixels each.
      const VkExtent2D grid = (variant & gpu::kBloomDownQuads)
                                  ? VkExtent2D{(extent(i).width + 1) / 2, (extent(i).height + 1) / 2}
                                  : extent(i);
      down_.Draw(ctx, {in, exposure}, {t.bloom_down_levels[i]}, &down, grid, variant);
      written(t.bloom_down, i);
    }
    // Up: level i of bloom_up = tent(the level below, magnified) + level i of bloom_down; the
    // level below is bloom_down's last for the first step.
    for (uint32_t i = levels - 1; i-- > 0;) {  // levels - 2 .. 0
      const VkExtent2D low = extent(i + 1);
      const gpu::BloomUpPush push{
          glm::vec4(1.0f / float(low.width), 1.0f / float(low.height), 0.0f, 0.0f)};
      const VkImageView low_view =
          i + 1 == levels - 1 ? t.bloom_down_levels[i + 1] : t.bloom_up_levels[i + 1];
      up_.Draw(ctx,
               {{low_view, linear_.handle(), read}, {t.bloom_down_levels[i], linear_.handle(), read}},
               {t.bloom_up_levels[i]}, &push, extent(i));
      if (i > 0) written(t.bloom_up, i);
    }
    // Levels 1.. were read above (after their writes): back to the target layout, for the graph.
    if (!compute && levels > 2) {
      const VkImageMemoryBarrier2 b = vk::MakeImageBarrier(
          t.bloom_up,
          {VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT, VK_ACCESS_2_NONE,
           VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT,
           VK_ACCESS_2_NONE, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL},
          1, levels - 2);
      vk::CmdBarrier(ctx.cmd, &b, 1);
    }
  }

 private:
  // Whether a level is exactly half its source, its taps then on the source's texel corners,
  // shared by neighbouring pixels (bloom_down.comp's kBloomDownQuads variant).
  static bool HalvesExactly(VkExtent2D src, VkExtent2D level) {
    return src.width == 2 * level.width && src.height == 2 * level.height;
  }

  // A mip just drawn, to be sampled by the next draw (and bloom_up's level 0 by the tonemap).
  static void ToRead(const PassContext& ctx, const vk::Image& image, uint32_t level) {
    const VkImageMemoryBarrier2 b = vk::MakeImageBarrier(
        image,
        {VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT, VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT,
         VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT,
         VK_ACCESS_2_SHADER_SAMPLED_READ_BIT, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL},
        level, 1);
    vk::CmdBarrier(ctx.cmd, &b, 1);
  }

  FullscreenProgram down_, up_;
  vk::Sampler linear_, nearest_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateBloomPass(const vk::Context& ctx) {
  absl::StatusOr<FullscreenProgram> down =
      FullscreenProgram::Create(ctx, "bloom_down", "bloom_down.frag", 2,
                                sizeof(gpu::BloomDownPush), {kHdrFormat}, "bloom_down.comp");
  if (!down.ok()) return down.status();
  absl::StatusOr<FullscreenProgram> up = FullscreenProgram::Create(
      ctx, "bloom_up", "bloom_up.frag", 2, sizeof(gpu::BloomUpPush), {kHdrFormat}, "bloom_up.comp");
  if (!up.ok()) return up.status();
  ASSIGN_OR_RETURN(vk::Sampler linear, CreateClampSampler(ctx, true, "bloom.linear"));
  absl::StatusOr<vk::Sampler> nearest = CreateClampSampler(ctx, false, "bloom.nearest");
  if (!nearest.ok()) return nearest.status();
  return std::unique_ptr<Pass>(
      new BloomPass(std::move(*down), std::move(*up), std::move(linear), std::move(*nearest)));
}

void SetupBloom(GraphBuilder& b) {
  if (!b.settings().bloom) return;
  const Resource color = b.SceneColor();
  // The pass makes its own per-mip barriers inside the chains; the graph sees the chains as
  // colour targets, all mips, so its transition to the tonemap's read covers them.
  const bool compute = FullscreenProgram::Compute(b.settings());
  const Access write = compute ? Access::kComputeWrite : Access::kColorWrite;
  b.Pass(PassId::kBloom)
      .Use(color, compute ? Access::kComputeRead : Access::kSampled)
      .Use(Resource::kBloomDown, write)
      .Use(Resource::kBloomUp, write)
      .UseIfPresent(Resource::kExposureState,
                    compute ? Access::kComputeReadGeneral : Access::kSampledGeneral);
}

}  // namespace tessera
