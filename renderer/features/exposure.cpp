// Auto exposure (shaders/exposure.comp): one workgroup reduces the log2 luma of an even grid of
// points over the tonemap's input (each a bilinear tap at a texel corner: the mean of 2x2
// pixels) to its average, and moves the view's 1x1 state towards it. The state lives across
// frames, outside the frame graph, in the general layout: the pass orders itself after the
// last frame's reads and before this frame's (bloom and tonemap sample it).
#include <algorithm>
#include <cmath>

#include "common/status_macros.h"
#include "renderer/features/features.h"
#include "renderer/features/pass.h"
#include "renderer/renderer_impl.h"
#include "renderer/vk/pipeline.h"
#include "renderer/vk/vk_check.h"

namespace tessera {

namespace {

// Sample points per axis at most: 64 x 64 taps of 2x2 pixels, 16 per thread.
constexpr uint32_t kGrid = 64;
// The log2 luma range the average is kept in: a black or blown-out frame cannot push the
// exposure further than 2^16 either way.
constexpr float kMinLog2 = -16.0f;
constexpr float kMaxLog2 = 16.0f;

class ExposurePass final : public Pass {
 public:
  ExposurePass(VkDevice device, PassLayout layout, vk::Pipeline pipeline, vk::Sampler linear)
      : device_(device),
        layout_(std::move(layout)),
        pipeline_(std::move(pipeline)),
        linear_(std::move(linear)) {}
  PassId id() const override { return PassId::kExposure; }

  void Record(PassContext& ctx) override {
    const ExposureFrame& e = *ctx.exposure;
    const vk::Image& state = *e.state;  // imported (SetupExposure)

    const VkDescriptorSet set = layout_.Allocate(ctx);
    SetWriter(device_, set)
        .Sampled(0, linear_.handle(), PostColor(ctx).view())
        .Storage(1, state.view())
        .Update();
    vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_.handle());
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout_.pipeline_layout(), 0,
                            1, &set, 0, nullptr);
    const uint32_t w_px = ctx.targets->width, h_px = ctx.targets->height;
    const gpu::ExposurePush push{
        glm::uvec4(w_px, h_px, std::min(w_px, kGrid), std::min(h_px, kGrid)),
        glm::vec4(e.state_valid ? e.rate : 1.0f, kMinLog2, kMaxLog2, 0.0f)};
    vkCmdPushConstants(ctx.cmd, layout_.pipeline_layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0,
                       sizeof(push), &push);
    vkCmdDispatch(ctx.cmd, 1, 1, 1);
  }

 private:
  VkDevice device_;
  PassLayout layout_;
  vk::Pipeline pipeline_;
  vk::Sampler linear_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateExposurePass(const vk::Context& ctx) {
  const std::vector<VkDescriptorSetLayoutBinding> bindings = {
      {0, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr},
      {1, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr},
  };
  absl::StatusOr<PassLayout> layout = PassLayout::Create(
      ctx, bindings, {{VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(gpu::ExposurePush)}},
      "exposure layout");
  if (!layout.ok()) return layout.status();
  ASSIGN_OR_RETURN(
      vk::Pipeline pipeline,
      vk::CreateComputePipeline(ctx, "exposure", "exposure.comp", layout->pipeline_layout()));
  absl::StatusOr<vk::Sampler> linear = CreateClampSampler(ctx, true, "exposure");
  if (!linear.ok()) return linear.status();
  return std::make_unique<ExposurePass>(ctx.device(), std::move(*layout), std::move(pipeline),
                                        std::move(*linear));
}

void SetupExposure(GraphBuilder& b) {
  // Debug views other than bloom's are not exposed, and must not move a stream's adapted
  // exposure.
  const Settings& s = b.settings();
  if (s.exposure_mode != ExposureMode::kAuto) return;
  // The view's state lives across frames in the general layout, where bloom and tonemap read
  // it (a state never written is undefined until the exposure pass writes it).
  b.Import(Resource::kExposureState,
           b.features().exposure_valid ? Access::kSampledGeneral : Access::kNone,
           Access::kSampledGeneral);
  const bool exposed = s.debug_view == DebugView::kNone || s.debug_view == DebugView::kBloom;
  if (!exposed) return;
  const Resource color = b.SceneColor();
  b.Pass(PassId::kExposure)
      .Use(color, Access::kComputeRead)
      .Use(Resource::kExposureState, Access::kComputeWrite);
}


namespace {
// Auto exposure maps the frame's average luma to middle grey (Reinhard's key, 0.18) and moves a
// tenth of the way towards each frame's average: about 90% of a change within 22 frames, under a
// second at 30 frames a second. A view's first frame takes its own average at once.
constexpr float kExposureKey = 0.18f;
constexpr float kExposureAdaptRate = 0.1f;
}  // namespace

absl::Status Renderer::Impl::PrepareExposure(FrameData& f) {
  // Fixed, or auto with this view's adapted state.
  ExposureFrame& exposure = f.exposure;
  exposure.params = glm::vec4(std::exp2(f.s.exposure_ev), 0.0f, kExposureKey, 0.0f);
  exposure.view = ao_placeholder.view();  // never read without auto exposure
  if (f.s.exposure_mode != ExposureMode::kAuto) return absl::OkStatus();
  ASSIGN_OR_RETURN(ExposureState * state, Exposure(f.gs, f.view));
  f.exposure_written = &state->written;
  exposure.params.y = 1.0f;
  exposure.state = &state->image;
  exposure.state_valid = state->written;
  exposure.rate = kExposureAdaptRate;
  exposure.view = state->image.view();
  exposure.layout = VK_IMAGE_LAYOUT_GENERAL;
  return absl::OkStatus();
}

}  // namespace tessera
