// TAA's object motion on animated scenes. TAA reprojects each pixel by the camera alone (its
// depth through last frame's view-projection); a surface that moved with the scene's animation
// was elsewhere on last frame's screen. When the pose changed since the view's last frame, this
// pass draws every moved opaque and alpha-mask drawable again against the frame's depth
// (shaders/motion.vert, .frag): where one is the visible surface, the target gets how far from
// the camera's reprojection the surface point was last frame, computed from the drawable's world
// matrix and vertices in the view's last pose. TAA adds that offset (at its dilated texel) to
// its reprojection. Pixels nothing moved on keep the clear value, 0.
//
// The last pose is kept per view (views show one scene at different times): the world matrices
// on the CPU (TaaHistory::world), the deformed vertices on the device, copied here after the
// draws from the scene's posed copies (TaaHistory::vertices), and the pass runs only when the
// view's pose differs from the one it kept. The first frame of a view only clears the target and
// keeps its pose. Blended drawables draw no motion: TAA sees them through
// the neighbourhood clamp as before.
#include "common/status_macros.h"
#include "renderer/features/features.h"
#include "renderer/features/pass.h"
#include "renderer/renderer_impl.h"
#include "renderer/vk/pipeline.h"
#include "renderer/vk/vk_check.h"
#include "shaders/common/gpu_types.h"

namespace tessera {

namespace {

class MotionPass final : public Pass {
 public:
  MotionPass(VkDevice device, PassLayout layout, vk::Pipeline opaque, vk::Pipeline mask)
      : device_(device),
        layout_(std::move(layout)),
        opaque_(std::move(opaque)),
        mask_(std::move(mask)) {}
  PassId id() const override { return PassId::kMotion; }

  void Record(PassContext& ctx) override {
    const TaaFrame& taa = *ctx.taa;
    const GpuScene& gs = *ctx.scene;
    const SceneAnimator& a = *gs.animator();  // the pass runs for animated scenes only
    if (taa.kept && !taa.draws.empty()) {
      // Last frame's copy (a transfer write in an earlier submission) before the vertex shader
      // reads it.
      vk::CmdMemoryBarrier(ctx.cmd, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT,
                           VK_ACCESS_2_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_2_VERTEX_SHADER_BIT,
                           VK_ACCESS_2_SHADER_STORAGE_READ_BIT);
    }
    VkRenderingAttachmentInfo color{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    color.imageView = ctx.targets->motion.view();
    color.imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
    color.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;  // 0: nothing moved here
    color.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    VkRenderingAttachmentInfo depth{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    depth.imageView = ctx.targets->depth.view();
    depth.imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
    depth.loadOp = VK_ATTACHMENT_LOAD_OP_LOAD;
    depth.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    BeginRendering(ctx, &color, &depth);
    if (!taa.draws.empty()) {
      const VkPipelineLayout layout = layout_.pipeline_layout();
      const VkDescriptorSet kept = layout_.Allocate(ctx);
      // Without deformed drawables the binding is unused; the scene's vertices stand in (as
      // much of them as a storage binding may hold: GpuScene::Upload checks only the deformed).
      SetWriter(device_, kept)
          .StorageBuffer(0, ctx, taa.kept ? *taa.kept : gs.vertices())
          .Update();
      BeginSceneDraw(ctx, opaque_.handle(), layout);
      vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout, 2, 1, &kept, 0,
                              nullptr);
      DrawState state{layout};  // materials and cull modes as the depth pass drew them
      VkPipeline bound = opaque_.handle();
      for (const TaaFrame::MotionDraw& d : taa.draws) {
        const DrawItem& item = gs.draws()[d.item];
        const VkPipeline pipeline =
            item.alpha == AlphaMode::kMask ? mask_.handle() : opaque_.handle();
        if (pipeline != bound) {
          vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline);
          bound = pipeline;
        }
        state.Apply(ctx, item.double_sided, item.material, /*textured=*/true);
        const gpu::MotionPush push{
            d.prev_world, glm::uvec4(uint32_t(a.first_copy_vertex()), d.kept ? 1u : 0u, 0, 0)};
        vkCmdPushConstants(ctx.cmd, layout, VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(push), &push);
        vkCmdDrawIndexed(ctx.cmd, item.index_count, 1, item.first_index, item.vertex_offset,
                         item.drawable);
      }
    }
    vkCmdEndRendering(ctx.cmd);
    if (taa.kept) {
      // This frame's deformed vertices (written by a skinning pass, this frame's or an earlier
      // one's) become the view's kept pose, after the draws above read the last one.
      // The source scope also holds the last frame's copy into the kept buffer (write after
      // write, when no draw read it in between).
      vk::CmdMemoryBarrier(ctx.cmd,
                           VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT |
                               VK_PIPELINE_STAGE_2_VERTEX_SHADER_BIT |
                               VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT,
                           VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT | VK_ACCESS_2_TRANSFER_WRITE_BIT,
                           VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT,
                           VK_ACCESS_2_TRANSFER_READ_BIT | VK_ACCESS_2_TRANSFER_WRITE_BIT);
      const VkBufferCopy region{a.first_copy_vertex() * sizeof(Vertex), 0,
                                a.copy_vertices() * sizeof(Vertex)};
      vkCmdCopyBuffer(ctx.cmd, gs.vertices().handle(), taa.kept->handle(), 1, &region);
    }
  }

 private:
  VkDevice device_;
  PassLayout layout_;
  vk::Pipeline opaque_, mask_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateMotionPass(const vk::Context& ctx,
                                                       const SceneLayout& scene) {
  ASSIGN_OR_RETURN(
      PassLayout layout,
      PassLayout::Create(
          ctx,
          {LayoutBinding(0, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, VK_SHADER_STAGE_VERTEX_BIT)},
          {{VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(gpu::MotionPush)}}, "motion layout",
          {scene.set_layout, scene.material_set_layout}));
  vk::GraphicsPipelineDesc d;
  d.name = "motion";
  d.vertex_shader = "motion.vert";
  d.fragment_shader = "motion.frag";
  d.layout = layout.pipeline_layout();
  d.attribute_mask = gpu::kAlphaMaskAttributes;
  d.color_formats = {kMotionFormat};
  d.depth_format = kDepthFormat;
  d.depth_test = true;
  d.depth_write = false;
  d.depth_compare = VK_COMPARE_OP_GREATER_OR_EQUAL;  // the visible surface (reverse Z)
  d.fragment_constants = {0u};
  ASSIGN_OR_RETURN(vk::Pipeline opaque, vk::CreateGraphicsPipeline(ctx, d));
  d.name = "motion.mask";
  d.fragment_constants = {1u};  // kAlphaTest
  ASSIGN_OR_RETURN(vk::Pipeline mask, vk::CreateGraphicsPipeline(ctx, d));
  return std::make_unique<MotionPass>(ctx.device(), std::move(layout), std::move(opaque),
                                      std::move(mask));
}

void SetupMotion(GraphBuilder& b) {
  if (b.settings().aa != AaMode::kTaa || !b.features().object_motion) return;
  b.Pass(PassId::kMotion)
      .UseIfPresent(Resource::kPosedGeometry, Access::kGeometryRead)
      .Use(Resource::kDepth, Access::kDepthTest)
      .Use(Resource::kMotion, Access::kColorWrite);
}

absl::Status Renderer::Impl::PrepareMotion(FrameData& f, TaaHistory& history, bool valid) {
  const GpuScene& gs = f.gs;
  const SceneAnimator* a = gs.animator();
  // The pose key, not GpuScene::pose_serial: another view's frame in between re-poses the scene,
  // and a view back at its own pose must see no motion (a job accumulating at one time while
  // viewers render stays byte-identical).
  if (!a || a->drawables().empty() || (history.kept_pose && history.pose_key == a->pose_key()))
    return absl::OkStatus();
  TaaFrame& taa = f.taa;
  taa.motion_pass = true;
  taa.motion = valid && history.kept_pose;
  if (a->copy_vertices() > 0) {
    const VkDeviceSize bytes = a->copy_vertices() * sizeof(Vertex);
    if (history.vertices.size() != bytes)
      RETURN_IF_ERROR(MakeBuffer(*ctx, bytes,
                                 VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                     VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                 vk::MemoryUsage::kDeviceLocal, "taa_kept_vertices",
                                 &history.vertices));
    taa.kept = &history.vertices;
  }
  if (taa.motion) {
    for (size_t i = 0; i < a->drawables().size(); ++i) {
      const AnimatedDrawable& ad = a->drawables()[i];
      const uint32_t item = gs.item_of(ad.drawable);
      if (gs.draws()[item].alpha == AlphaMode::kBlend) continue;
      taa.draws.push_back({item, ad.deformed, history.world[i]});
    }
  }
  // Kept now; a frame that fails from here on resets the history (RenderFrame).
  history.world = a->world();
  history.pose_key = a->pose_key();
  history.kept_pose = true;
  return absl::OkStatus();
}

}  // namespace tessera
