// SSAO: Scalable Ambient Obscurance (shaders/ssao.frag) from the frame's depth alone (normals
// are reconstructed from it), at the size of FrameTargets::ao (half the frame by default), into
// AO + view depth packed in one RGBA16F texel (RGBA: a storage format every device has, for
// the compute variant); then a separable bilateral blur (ssao_blur.frag)
// that reads both in one tap: ao -> ao_temp (horizontal) -> ao (vertical). The shading passes
// multiply their ambient light by it. The two intermediate barriers are the pass's own: the
// frame graph sees one pass that writes ao.
#include "common/status_macros.h"
#include "renderer/features/features.h"
#include "renderer/features/pass.h"
#include "renderer/renderer_impl.h"
#include "renderer/vk/vk_check.h"

namespace tessera {

namespace {

// Weight of a blur tap falls with its relative depth difference at this rate.
constexpr float kDepthSharpness = 8.0f;

class SsaoPass final : public Pass {
 public:
  SsaoPass(FullscreenProgram ao, FullscreenProgram blur, vk::Sampler nearest)
      : ao_(std::move(ao)), blur_(std::move(blur)), nearest_(std::move(nearest)) {}
  PassId id() const override { return PassId::kSsao; }

  void Record(PassContext& ctx) override {
    const FrameTargets& t = *ctx.targets;
    const VkExtent2D extent{t.ao.desc().width, t.ao.desc().height};
    const gpu::SsaoPush push{ctx.ssao->proj, ctx.ssao->params,
                             glm::uvec4(t.width, t.height, extent.width, extent.height)};
    ao_.Draw(ctx, {{t.depth.view(), nearest_.handle(), VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL}},
             {t.ao.view()}, &push, extent);
    gpu::SsaoBlurPush blur{glm::ivec4(1, 0, extent.width, extent.height),
                           glm::vec4(kDepthSharpness, 0, 0, 0)};
    if (FullscreenProgram::Compute(*ctx.settings)) {  // both images stay in the general layout
      const VkPipelineStageFlags2 cs = VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;
      const VkAccessFlags2 rw = VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT |
                                VK_ACCESS_2_SHADER_SAMPLED_READ_BIT;
      const VkImageLayout general = VK_IMAGE_LAYOUT_GENERAL;
      vk::CmdMemoryBarrier(ctx.cmd, cs, rw, cs, rw);
      blur_.Draw(ctx, {{t.ao.view(), nearest_.handle(), general}}, {t.ao_temp.view()}, &blur,
                 extent);
      vk::CmdMemoryBarrier(ctx.cmd, cs, rw, cs, rw);
      blur.dir = glm::ivec4(0, 1, extent.width, extent.height);
      blur_.Draw(ctx, {{t.ao_temp.view(), nearest_.handle(), general}}, {t.ao.view()}, &blur,
                 extent);
      return;
    }
    ToRead(ctx, t.ao);
    blur_.Draw(ctx, {{t.ao.view(), nearest_.handle(), VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL}},
               {t.ao_temp.view()}, &blur, extent);
    // ao: read above, written below (write after read); ao_temp: written above, read below.
    VkImageMemoryBarrier2 b[2] = {
        vk::MakeImageBarrier(t.ao, {VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT, VK_ACCESS_2_NONE,
                                    VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                                    VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT,
                                    VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT,
                                    VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL}),
        ReadBarrier(t.ao_temp)};
    vk::CmdBarrier(ctx.cmd, b, 2);
    blur.dir = glm::ivec4(0, 1, extent.width, extent.height);
    blur_.Draw(ctx,
               {{t.ao_temp.view(), nearest_.handle(), VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL}},
               {t.ao.view()}, &blur, extent);
  }

 private:
  static VkImageMemoryBarrier2 ReadBarrier(const vk::Image& image) {
    return vk::MakeImageBarrier(
        image, {VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT,
                VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT, VK_ACCESS_2_SHADER_SAMPLED_READ_BIT,
                VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL});
  }
  static void ToRead(const PassContext& ctx, const vk::Image& image) {
    const VkImageMemoryBarrier2 b = ReadBarrier(image);
    vk::CmdBarrier(ctx.cmd, &b, 1);
  }

  FullscreenProgram ao_, blur_;
  vk::Sampler nearest_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateSsaoPass(const vk::Context& ctx) {
  absl::StatusOr<FullscreenProgram> ao = FullscreenProgram::Create(
      ctx, "ssao", "ssao.frag", 1, sizeof(gpu::SsaoPush), {kAoFormat}, "ssao.comp");
  if (!ao.ok()) return ao.status();
  absl::StatusOr<FullscreenProgram> blur =
      FullscreenProgram::Create(ctx, "ssao_blur", "ssao_blur.frag", 1, sizeof(gpu::SsaoBlurPush),
                                {kAoFormat}, "ssao_blur.comp");
  if (!blur.ok()) return blur.status();
  ASSIGN_OR_RETURN(vk::Sampler nearest, CreateClampSampler(ctx, false, "ssao"));
  return std::unique_ptr<Pass>(new SsaoPass(std::move(*ao), std::move(*blur), std::move(nearest)));
}

void SetupSsao(GraphBuilder& b) {
  if (!b.settings().ssao) return;
  const bool compute = FullscreenProgram::Compute(b.settings());
  const Access write = compute ? Access::kComputeWrite : Access::kColorWrite;
  b.Pass(PassId::kSsao)
      .Use(Resource::kDepth, compute ? Access::kComputeRead : Access::kSampled)
      .Use(Resource::kAo, write)
      .Use(Resource::kAoTemp, write);
}


absl::Status Renderer::Impl::PrepareSsao(FrameData& f) {
  const Settings& s = f.s;
  if (!s.ssao) return absl::OkStatus();
  const Aabb& b = f.gs.bounds();
  const float diagonal = b.empty() ? 1.0f : glm::length(b.max - b.min);
  const float radius = s.ssao_radius > 0.0f ? s.ssao_radius : 0.015f * diagonal;
  const gpu::FrameUniforms& fu = f.fu;
  f.ssao.proj = glm::vec4(fu.proj[0][0], fu.proj[1][1], fu.proj[2][2], fu.proj[3][2]);
  f.ssao.params = glm::vec4(radius, s.ssao_strength, 0.01f * radius, 0.0f);
  static_cast<gpu::ShadowUniforms*>(shadow_ubo.mapped())->counts.w |= gpu::kSsaoOn;
  return absl::OkStatus();
}

}  // namespace tessera
