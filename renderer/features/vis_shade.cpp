// The visibility shading of the visibility pipeline (pipeline: visibility, with aa none, fxaa or
// taa) and of vis_mlaa. The visibility pass (vis_mlaa.cpp) drew the opaque and alpha-mask
// geometry once into the frame's depth and a triangle id per pixel (vis_mlaa: per sample, then
// resolved to the id of the surface each pixel shows, its coverage and mean sample position);
// then, all in compute:
//  - vis_classify: per pixel its material (the drawable's); per material a count (vis_mlaa:
//    counted by its resolve already), a scan into list offsets and indirect dispatch sizes, and
//    the list of its pixels; and the background where no surface is, written by its pass over
//    the pixels, or where the sky is less than a third of the frame, listed there and written by a
//    dispatch of its own (shaders/common/vis_classify.glsl);
//  - shade: per material on screen one vkCmdDispatchIndirect over exactly its pixels, with its
//    descriptor set 1 bound as a forward draw binds it (lavapipe cannot index samplers, and reads
//    a uniform material far faster than an indexed one), each pixel's surface rebuilt from its id
//    and shaded once (shaders/vis_shade.comp; vis_mlaa: vis_shade_mlaa.comp, at the surface's
//    mean sample position); vis_mlaa then one over its runner-up surfaces that are the sky
//    (vis_sky_mlaa.comp).
// The classification writes the sky where no surface is (vis_mlaa: where the surface a pixel
// shows is the sky); vis_mlaa lists the sky only where it is a
// pixel's runner-up surface, with a colour of its own at its samples' mean (vis_sky_mlaa.comp).
// Where the device indexes sampler arrays (DeviceInfo::shade_all_materials: GPUs by default),
// there is no classification: the shading is one dispatch over the frame's pixels in 8x8 tiles,
// which writes the sky too, each pixel's material read from the scene's material buffer and its
// textures from the scene's bucket set (common/textures.glsl, SHADE_ALL_MATERIALS); vis_mlaa then
// one over its blend list for the runner-ups (ShadePass::RecordAll).
// Blended surfaces follow in the forward transparent pass, against the visibility pass's depth.
#include <algorithm>
#include <array>
#include <optional>

#include "absl/strings/str_cat.h"
#include "common/status_macros.h"
#include "renderer/features/features.h"
#include "renderer/features/pass.h"
#include "renderer/renderer_impl.h"
#include "renderer/vk/descriptor_limits.h"
#include "renderer/vk/pipeline.h"
#include "renderer/vk/vk_check.h"
#include "shaders/common/gpu_types.h"

namespace tessera {

namespace {

// Which set 2: the one-sample passes'; vis_mlaa's classification's (and the resolve's runner-up
// records); vis_mlaa's shading's (and the resolve's coverage, the visibility samples and the edge
// colours). Separate layouts: lavapipe reads every descriptor of a bound set, so none may be left
// unwritten, and a pass binds only what it reads.
enum class ShadeSet { kOneSample, kVisMlaaClassify, kVisMlaa };

// Set 2 of these passes and their pipeline layout (sets 0 and 1 are the scene's).
class ShadeLayout {
 public:
  // `all_materials`: set 1 is the scene's bucket set (one dispatch shades every material,
  // DeviceInfo::shade_all_materials), else a material's set.
  static absl::StatusOr<ShadeLayout> Create(const vk::Context& ctx, const SceneLayout& scene,
                                            ShadeSet kind, bool all_materials = false) {
    ShadeLayout l;
    l.device_ = ctx.device();
    l.kind_ = kind;
    constexpr VkShaderStageFlags kCompute = VK_SHADER_STAGE_COMPUTE_BIT;
    constexpr VkDescriptorType kSampled = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
    constexpr VkDescriptorType kBuffer = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    std::vector<VkDescriptorSetLayoutBinding> b = VisibilityBufferBindings();
    b.push_back(LayoutBinding(gpu::kShadeBindingId, kSampled, kCompute));
    b.push_back(LayoutBinding(gpu::kShadeBindingColor, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, kCompute));
    if (kind != ShadeSet::kOneSample) {
      b.push_back(LayoutBinding(gpu::kShadeBindingRunnerUps, kBuffer, kCompute));
    }
    if (kind == ShadeSet::kVisMlaa) {
      b.push_back(LayoutBinding(gpu::kShadeBindingCoverage, kSampled, kCompute));
      b.push_back(LayoutBinding(gpu::kShadeBindingEdgeColors, kBuffer, kCompute));
    }
    ASSIGN_OR_RETURN(l.layout_, PassLayout::Create(
                                    ctx, b, {{kCompute, 0, sizeof(gpu::ShadePush)}}, "shade layout",
                                    {scene.set_layout, all_materials ? scene.bucket_set_layout
                                                                     : scene.material_set_layout}));
    ASSIGN_OR_RETURN(l.sampler_, CreateClampSampler(ctx, false, "shade.ids"));
    return l;
  }
  VkPipelineLayout pipeline_layout() const { return layout_.pipeline_layout(); }

  // Writes this frame's set 2 and binds it with the scene's set 0.
  void Bind(const PassContext& ctx) const {
    const VkDescriptorSet set = layout_.Allocate(ctx);
    SetWriter w(device_, set);
    w.Sampled(gpu::kShadeBindingId, sampler_.handle(), ctx.targets->vis_id.view())
        .Storage(gpu::kShadeBindingColor, ctx.targets->hdr.view())
        .VisibilityBuffers(ctx);
    // vis_mlaa's targets and buffers exist in its frames.
    if (kind_ != ShadeSet::kOneSample) w.Buffer(gpu::kShadeBindingRunnerUps, ctx.shade->runner_ups);
    if (kind_ == ShadeSet::kVisMlaa) {
      w.Sampled(gpu::kShadeBindingCoverage, sampler_.handle(), ctx.targets->vis_coverage.view())
          .Buffer(gpu::kShadeBindingEdgeColors, ctx.shade->edge_colors);
    }
    w.Update();
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_layout(), 0, 1,
                            &ctx.scene_set, 0, nullptr);
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_layout(),
                            gpu::kVisSet, 1, &set, 0, nullptr);
  }

 private:
  VkDevice device_ = VK_NULL_HANDLE;
  ShadeSet kind_ = ShadeSet::kOneSample;
  PassLayout layout_;
  vk::Sampler sampler_;
};

// A compute-to-compute dependency on the entries and lists between the classification's steps
// (`indirect`: the next step's dispatch size is read from the entries too).
void ComputeBarrier(VkCommandBuffer cmd, bool indirect = false) {
  vk::CmdMemoryBarrier(
      cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
      VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT |
          (indirect ? VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT : VkPipelineStageFlags2{0}),
      VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT |
          (indirect ? VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT : VkAccessFlags2{0}));
}

// vis_mlaa's classification also lists the runner-up surfaces to shade (dispatched over the
// resolve's blend list, with vis_mlaa's layout).
class VisClassifyPass final : public Pass {
 public:
  VisClassifyPass(ShadeLayout one, ShadeLayout mlaa)
      : one_(std::move(one)), mlaa_(std::move(mlaa)) {}
  PassId id() const override { return PassId::kVisClassify; }

  // A pipeline per mode (vis_classify.glsl's specialization constant 0, kClassify*), for the one
  // sample classification or vis_mlaa's, and per way of reading the drawables (vis.glsl's
  // kVisTexels), built for the first frame that needs them. One atomic per subgroup and material
  // where the device appends so (DeviceInfo::subgroup_appends), else per pixel. The scan, the one
  // step with workgroup barriers, has a shader of its own (vis_classify_scan.comp: see
  // vis_classify.glsl) that reads none of the key's constants: one pipeline per layout.
  absl::Status PrepareScene(const vk::Context& ctx, const Settings& s, const GpuScene& scene,
                            const FrameFeatures& features) override {
    const bool vis_mlaa = s.aa == AaMode::kVisMlaa;
    const bool ballots = ctx.info().subgroup_appends;
    vk::Pipeline& scan = scan_[vis_mlaa ? 1 : 0];
    if (!scan.handle()) {
      ASSIGN_OR_RETURN(scan, vk::CreateComputePipeline(
                                 ctx, vis_mlaa ? "vis_classify.vis_mlaa.scan" : "vis_classify.scan",
                                 "vis_classify_scan.comp",
                                 (vis_mlaa ? mlaa_ : one_).pipeline_layout()));
    }
    return (vis_mlaa ? mlaa_pipelines_ : pipelines_)
        .Ensure(Key(s, scene, features), [&](uint32_t key) -> absl::StatusOr<ModePipelines> {
          const uint32_t texels = key & 1u, ibl = (key >> 1) & 1u, count_background = key >> 2;
          ModePipelines made;
          // vis_mlaa: the resolve counted (no kClassifyCount); the runner-ups are listed.
          const std::vector<uint32_t> modes =
              vis_mlaa ? std::vector<uint32_t>{gpu::kClassifyFillRunnerUps, gpu::kClassifyFill,
                                               gpu::kClassifyFillListSky, gpu::kClassifySky}
                       : std::vector<uint32_t>{gpu::kClassifyCount, gpu::kClassifyFill,
                                               gpu::kClassifyFillListSky, gpu::kClassifySky};
          const char* shader = vis_mlaa ? (ballots ? "vis_classify_mlaa.comp"
                                                   : "vis_classify_atomic_mlaa.comp")
                                        : (ballots ? "vis_classify.comp"
                                                   : "vis_classify_atomic.comp");
          for (const uint32_t mode : modes) {
            ASSIGN_OR_RETURN(
                made[mode],
                vk::CreateComputePipeline(
                    ctx, absl::StrCat(vis_mlaa ? "vis_classify.vis_mlaa." : "vis_classify.", mode,
                                      texels ? ".texels" : "", ibl ? ".ibl" : "",
                                      count_background ? ".count_background" : ""),
                    shader, (vis_mlaa ? mlaa_ : one_).pipeline_layout(),
                    {mode, ibl, count_background, texels}));
          }
          return made;
        });
  }
  // The pipelines' key: the way the drawables are read (vis.glsl's kVisTexels), whether the
  // frame has IBL, whose environment is the sky the classification writes, and whether it
  // counts the sky's pixels (FrameFeatures::count_background).
  static uint32_t Key(const Settings& s, const GpuScene& scene, const FrameFeatures& features) {
    return VisTexels(scene) | (s.ibl ? 2u : 0u) | (features.count_background ? 4u : 0u);
  }

  void Record(PassContext& ctx) override {
    const ShadeBuffers& sb = *ctx.shade;
    const bool vis_mlaa = ctx.settings->aa == AaMode::kVisMlaa;
    const ShadeLayout& layout = vis_mlaa ? mlaa_ : one_;
    // The scene's materials and the sky's entry (and, copied for the statistics, vis_mlaa's
    // edge list's and blend list's).
    const VkDeviceSize entry_bytes =
        VkDeviceSize(sb.materials + 1) * sizeof(gpu::GpuShadeEntry);
    // The counts start at zero (the graph ordered this after the last frame's reads); vis_mlaa's
    // resolve zeroed and counted them already (vis_resolve.comp).
    if (!vis_mlaa) {
      vkCmdFillBuffer(ctx.cmd, sb.entries, 0, entry_bytes, 0);
      vk::CmdMemoryBarrier(
          ctx.cmd, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
          VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
          VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
    }
    const ModePipelines& pipelines =
        (vis_mlaa ? mlaa_pipelines_ : pipelines_)
            .at(Key(*ctx.settings, *ctx.scene, *ctx.features));
    layout.Bind(ctx);
    const uint32_t gx = (ctx.targets->width + gpu::kClassifyTile - 1) / gpu::kClassifyTile;
    const uint32_t gy = (ctx.targets->height + gpu::kClassifyTile - 1) / gpu::kClassifyTile;
    auto push = [&](uint32_t mode) {
      const vk::Pipeline& pipeline =
          mode == gpu::kClassifyScan ? scan_[vis_mlaa ? 1 : 0] : pipelines[mode];
      vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.handle());
      const gpu::ShadePush p{glm::uvec4(0u, sb.materials, vis_mlaa ? 1u : 0u, 0u)};
      vkCmdPushConstants(ctx.cmd, layout.pipeline_layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0,
                         sizeof(p), &p);
    };
    auto step = [&](uint32_t mode, uint32_t x, uint32_t y) {
      push(mode);
      vkCmdDispatch(ctx.cmd, x, y, 1);
    };
    auto indirect = [&](uint32_t mode, uint32_t entry) {  // sized by the scan (or the resolve)
      push(mode);
      vkCmdDispatchIndirect(ctx.cmd, sb.entries, VkDeviceSize(entry) * sizeof(gpu::GpuShadeEntry));
    };
    if (!vis_mlaa) {
      step(gpu::kClassifyCount, gx, gy);
      ComputeBarrier(ctx.cmd);
    }
    step(gpu::kClassifyScan, 1, 1);
    // The next steps' dispatch sizes are read from the entries (an indirect read, ordered after
    // every storage write to them).
    ComputeBarrier(ctx.cmd, /*indirect=*/true);
    if (vis_mlaa) {  // over the blend list, sized by the resolve
      indirect(gpu::kClassifyFillRunnerUps, sb.blend_entry());
      ComputeBarrier(ctx.cmd, /*indirect=*/true);
    }
    // The fill that writes the sky, or the one that lists it (the scan gave the other no
    // workgroups), then the listed sky. (Each dispatch size is read from the entries after a
    // step that wrote to them: a barrier before each.)
    indirect(gpu::kClassifyFill, sb.fill_entry(false));
    ComputeBarrier(ctx.cmd, /*indirect=*/true);
    indirect(gpu::kClassifyFillListSky, sb.fill_entry(true));
    ComputeBarrier(ctx.cmd, /*indirect=*/true);
    indirect(gpu::kClassifySky, sb.sky_list_entry());
    // This pass's own copy of the entries for the statistics (the graph orders the entries
    // before the shading's dispatches).
    vk::CmdMemoryBarrier(ctx.cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                         VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, VK_PIPELINE_STAGE_2_COPY_BIT,
                         VK_ACCESS_2_TRANSFER_READ_BIT);
    const VkBufferCopy copy{0, 0, entry_bytes + 2 * sizeof(gpu::GpuShadeEntry)};
    vkCmdCopyBuffer(ctx.cmd, sb.entries, sb.entries_readback, 1, &copy);
    vk::CmdMemoryBarrier(ctx.cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                         VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_READ_BIT);
  }

 private:
  // A mode the classification does not run (and the scan) has a null pipeline.
  using ModePipelines = std::array<vk::Pipeline, 6>;
  ShadeLayout one_, mlaa_;
  PerSampleCount<ModePipelines> pipelines_, mlaa_pipelines_;  // by Key
  std::array<vk::Pipeline, 2> scan_;  // one sample's layout, vis_mlaa's
};

// The shading pipelines per key: ShadingConstants::Key() (a pipeline per set of texture slots the
// scene's materials use, and per effects, debug view and way of reading the scene's triangles and
// the lights) | kMlaaKey for vis_mlaa's (vis_shade_mlaa.comp). vis_mlaa's sky has one.
constexpr uint32_t kMlaaKey = 1u << kShadingKeyBits;

// The layouts and pipelines of the shading in one dispatch (DeviceInfo::shade_all_materials): set 1
// the scene's bucket set; per key (ShadePass::Key, with the union of the scene's texture slots),
// the pixels' pipeline and vis_mlaa's runner-ups'.
struct AllMaterials {
  ShadeLayout one, mlaa;
  PerSampleCount<std::array<vk::Pipeline, 2>> pipelines;  // pixels, runner-ups (vis_mlaa)
};

class ShadePass final : public Pass {
 public:
  ShadePass(ShadeLayout one, ShadeLayout mlaa, vk::Pipeline mlaa_sky,
            std::optional<AllMaterials> all)
      : one_(std::move(one)),
        mlaa_(std::move(mlaa)),
        mlaa_sky_(std::move(mlaa_sky)),
        all_(std::move(all)) {}
  PassId id() const override { return PassId::kShade; }

  absl::Status PrepareScene(const vk::Context& ctx, const Settings& s, const GpuScene& scene,
                            const FrameFeatures& features) override {
    if (features.shade_all_materials) return PrepareAll(ctx, s, scene, features);
    for (const uint32_t textures : scene.texture_sets()) {
      RETURN_IF_ERROR(shading_.Ensure(Key(s, scene, features, textures), [&](uint32_t key) {
        const bool vis_mlaa = (key & kMlaaKey) != 0;
        // The driver applies the constants, also where the device has them applied on the host
        // (DeviceInfo::host_specialization, SwiftShader): specialized there, SwiftShader shaded a
        // few pixels differently from one run to the next (VisibilityPipelineTest.
        // ShadowedLocalLightsRenderTheSameEveryTime: 2-10 of 230,400, by up to 10/255, where a
        // pixel's company in its SIMD group changes with the lists' order), its own
        // specialization not. It is the local lights' loop (DirectLight, common/shading.glsl),
        // which tests its end at the bottom: tested at its top, the pixels were the same in every
        // run (three runs), but that form cost lavapipe's shading (Sponza, --lights 256: 68-86 ms
        // against 73-102 in four alternating rounds). The forward pass's fragment shaders run the
        // same loop over quads that do not change, and are specialized on the host.
        return vk::CreateComputePipeline(
            ctx, absl::StrCat(vis_mlaa ? "shade.vis_mlaa." : "shade.", absl::Hex(key)),
            vis_mlaa ? "vis_shade_mlaa.comp" : "vis_shade.comp",
            (vis_mlaa ? mlaa_ : one_).pipeline_layout(),
            ShadingConstants::FromKey(key & ~kMlaaKey).Values(), vk::Specialize::kByDriver);
      }));
    }
    return absl::OkStatus();
  }
  static uint32_t Key(const Settings& s, const GpuScene& scene, const FrameFeatures& features,
                      uint32_t textures) {
    ShadingConstants c = ShadingConstantsFor(s, features, textures);
    c.vis_texels = VisTexels(scene);
    return c.Key() | (s.aa == AaMode::kVisMlaa ? kMlaaKey : 0u);
  }

  void Record(PassContext& ctx) override {
    if (ctx.features->shade_all_materials) return RecordAll(ctx);
    const Settings& s = *ctx.settings;
    const bool vis_mlaa = s.aa == AaMode::kVisMlaa;
    const ShadeLayout& layout = vis_mlaa ? mlaa_ : one_;
    layout.Bind(ctx);
    VkPipeline bound = VK_NULL_HANDLE;
    // The materials whose drawables are in the frustum; the others have no pixels.
    for (const uint32_t m : ctx.vis->materials) {
      const VkPipeline pipeline =
          shading_.at(Key(s, *ctx.scene, *ctx.features, ctx.scene->material_textures(m)))
              .handle();
      if (pipeline != bound) {
        vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline);
        bound = pipeline;
      }
      const VkDescriptorSet material = ctx.scene->material_set(m);
      vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout.pipeline_layout(),
                              gpu::kMaterialSet, 1, &material, 0, nullptr);
      const gpu::ShadePush push{glm::uvec4(m, 0u, 0u, 0u)};
      vkCmdPushConstants(ctx.cmd, layout.pipeline_layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0,
                         sizeof(push), &push);
      vkCmdDispatchIndirect(ctx.cmd, ctx.shade->entries,
                            VkDeviceSize(m) * sizeof(gpu::GpuShadeEntry));
      ctx.stats->material_draws++;
    }
    // vis_mlaa's runner-ups that are the sky (the classification wrote the sky where a pixel
    // shows it).
    if (!vis_mlaa) return;
    const uint32_t sky = ctx.shade->materials;
    vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, mlaa_sky_.handle());
    const gpu::ShadePush push{glm::uvec4(sky, 0u, 0u, 0u)};
    vkCmdPushConstants(ctx.cmd, layout.pipeline_layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0,
                       sizeof(push), &push);
    vkCmdDispatchIndirect(ctx.cmd, ctx.shade->entries,
                          VkDeviceSize(sky) * sizeof(gpu::GpuShadeEntry));
  }

 private:
  // The texture slots any of the scene's materials has: the one pipeline's (shading.glsl's
  // specialization constant 1).
  static uint32_t AllTextures(const GpuScene& scene) {
    uint32_t textures = 0;
    for (const uint32_t t : scene.texture_sets()) textures |= t;
    return textures;
  }

  absl::Status PrepareAll(const vk::Context& ctx, const Settings& s, const GpuScene& scene,
                          const FrameFeatures& features) {
    if (!all_) return absl::InternalError("shade: no bucket-indexing layouts on this device");
    const bool vis_mlaa = s.aa == AaMode::kVisMlaa;
    return all_->pipelines.Ensure(
        Key(s, scene, features, AllTextures(scene)),
        [&](uint32_t key) -> absl::StatusOr<std::array<vk::Pipeline, 2>> {
          const std::vector<uint32_t> constants =
              ShadingConstants::FromKey(key & ~kMlaaKey).Values();
          const VkPipelineLayout layout = (vis_mlaa ? all_->mlaa : all_->one).pipeline_layout();
          // Specialized by the driver, as the per-material shading (above).
          std::array<vk::Pipeline, 2> made;
          ASSIGN_OR_RETURN(
              made[0],
              vk::CreateComputePipeline(
                  ctx,
                  absl::StrCat(vis_mlaa ? "shade_all.vis_mlaa." : "shade_all.", absl::Hex(key)),
                  vis_mlaa ? "vis_shade_all_mlaa.comp" : "vis_shade_all.comp", layout, constants,
                  vk::Specialize::kByDriver));
          if (vis_mlaa) {
            ASSIGN_OR_RETURN(
                made[1],
                vk::CreateComputePipeline(
                    ctx, absl::StrCat("shade_all.runner_ups.", absl::Hex(key)),
                    "vis_shade_all_runner_ups.comp", layout, constants, vk::Specialize::kByDriver));
          }
          return made;
        });
  }

  // One dispatch over the frame's pixels in 8x8 tiles, which writes the sky too; vis_mlaa then
  // one over its blend list for the runner-up surfaces no neighbour shows. In one-sample frames
  // each material's entry counts its pixels (vis_mlaa's resolve counted those); the sky's entry
  // counts the sky's pixels where a capture asks.
  void RecordAll(PassContext& ctx) {
    static_assert(gpu::kClassifyTile * gpu::kClassifyTile == gpu::kShadeGroupSize,
                  "vis_shade.glsl maps a workgroup to a tile");
    const Settings& s = *ctx.settings;
    const ShadeBuffers& sb = *ctx.shade;
    const bool vis_mlaa = s.aa == AaMode::kVisMlaa;
    const ShadeLayout& layout = vis_mlaa ? all_->mlaa : all_->one;
    const std::array<vk::Pipeline, 2>& pipelines =
        all_->pipelines.at(Key(s, *ctx.scene, *ctx.features, AllTextures(*ctx.scene)));
    const VkDeviceSize entry = sizeof(gpu::GpuShadeEntry);
    // The counts start at zero (vis_mlaa's resolve zeroed the entries and counted in them).
    if (!vis_mlaa) {
      vkCmdFillBuffer(ctx.cmd, sb.entries, 0, VkDeviceSize(sb.materials + 1) * entry, 0);
      vk::CmdMemoryBarrier(
          ctx.cmd, VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
          VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
          VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
    }
    layout.Bind(ctx);
    const VkDescriptorSet buckets = ctx.scene->bucket_set();
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout.pipeline_layout(),
                            gpu::kMaterialSet, 1, &buckets, 0, nullptr);
    // w: count the sky's pixels, only where a capture asks (FrameFeatures::count_background), as
    // the classification does.
    const gpu::ShadePush push{glm::uvec4(sb.materials, sb.edge_entry(), vis_mlaa ? 0u : 1u,
                                         ctx.features->count_background ? 1u : 0u)};
    vkCmdPushConstants(ctx.cmd, layout.pipeline_layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0,
                       sizeof(push), &push);
    vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipelines[0].handle());
    const uint32_t gx = (ctx.targets->width + gpu::kClassifyTile - 1) / gpu::kClassifyTile;
    const uint32_t gy = (ctx.targets->height + gpu::kClassifyTile - 1) / gpu::kClassifyTile;
    vkCmdDispatch(ctx.cmd, gx, gy, 1);
    ctx.stats->material_draws++;
    ctx.stats->shading_invocations += uint64_t(gx) * gy * gpu::kShadeGroupSize;
    if (vis_mlaa) {
      // Sized by the resolve (its kResolveArgs step over the blend list).
      vk::CmdMemoryBarrier(
          ctx.cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
          VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT, VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT);
      vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipelines[1].handle());
      vkCmdDispatchIndirect(ctx.cmd, sb.entries, VkDeviceSize(sb.blend_entry()) * entry);
      ctx.stats->material_draws++;
    }
    // The entries for the statistics (as the classification copies them).
    vk::CmdMemoryBarrier(ctx.cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                         VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, VK_PIPELINE_STAGE_2_COPY_BIT,
                         VK_ACCESS_2_TRANSFER_READ_BIT);
    const VkBufferCopy copy{0, 0, VkDeviceSize(sb.materials + 3) * entry};
    vkCmdCopyBuffer(ctx.cmd, sb.entries, sb.entries_readback, 1, &copy);
    vk::CmdMemoryBarrier(ctx.cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                         VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_READ_BIT);
  }

  ShadeLayout one_, mlaa_;  // one sample, vis_mlaa
  vk::Pipeline mlaa_sky_;  // vis_mlaa's sky (the one-sample classification writes its own)
  PerSampleCount<vk::Pipeline> shading_;  // by Key
  std::optional<AllMaterials> all_;       // where the device indexes sampler arrays
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateVisClassifyPass(const vk::Context& ctx,
                                                            const SceneLayout& scene) {
  ASSIGN_OR_RETURN(ShadeLayout one, ShadeLayout::Create(ctx, scene, ShadeSet::kOneSample));
  ASSIGN_OR_RETURN(ShadeLayout mlaa,
                   ShadeLayout::Create(ctx, scene, ShadeSet::kVisMlaaClassify));
  return std::make_unique<VisClassifyPass>(std::move(one), std::move(mlaa));
}

absl::StatusOr<std::unique_ptr<Pass>> CreateShadePass(const vk::Context& ctx,
                                                      const SceneLayout& scene,
                                                      absl::Status* one_dispatch) {
  ASSIGN_OR_RETURN(ShadeLayout one, ShadeLayout::Create(ctx, scene, ShadeSet::kOneSample));
  ASSIGN_OR_RETURN(ShadeLayout mlaa, ShadeLayout::Create(ctx, scene, ShadeSet::kVisMlaa));
  ASSIGN_OR_RETURN(vk::Pipeline mlaa_sky,
                   vk::CreateComputePipeline(ctx, "shade.vis_mlaa.sky", "vis_sky_mlaa.comp",
                                             mlaa.pipeline_layout()));
  std::optional<AllMaterials> all;
  if (ctx.info().shade_all_materials) {
    absl::StatusOr<ShadeLayout> all_one =
        ShadeLayout::Create(ctx, scene, ShadeSet::kOneSample, true);
    absl::StatusOr<ShadeLayout> all_mlaa =
        all_one.ok() ? ShadeLayout::Create(ctx, scene, ShadeSet::kVisMlaa, true) : all_one.status();
    const absl::Status s = all_mlaa.status();
    if (s.ok()) {
      all.emplace();
      all->one = std::move(*all_one);
      all->mlaa = std::move(*all_mlaa);
    } else if (one_dispatch != nullptr && vk::IsDescriptorLimitError(s)) {
      *one_dispatch = s;  // shaded per material instead (the caller turns it off)
    } else {
      return s;
    }
  }
  return std::make_unique<ShadePass>(std::move(one), std::move(mlaa), std::move(mlaa_sky),
                                     std::move(all));
}

void SetupVisibilityShading(GraphBuilder& b) {
  if (!DrawsVisibility(b.settings())) return;
  const bool vis_mlaa = b.settings().aa == AaMode::kVisMlaa;
  const bool one_dispatch = b.features().shade_all_materials;
  using R = Resource;
  using A = Access;
  // The entries and lists are rewritten whole each frame.
  if (!b.Imported(R::kShadeLists)) b.Import(R::kShadeLists, A::kNone, A::kIndirectRead);
  // Where the shading is one dispatch over every pixel (and vis_mlaa's over its runner-ups), it
  // writes the sky too and counts in the entries; else the classification does both, and lists
  // the pixels per material for the shading's dispatches.
  if (!one_dispatch) {
    b.Pass(PassId::kVisClassify)
        .UseIfPresent(R::kPosedGeometry, A::kGeometryRead)
        .Use(R::kVisId, A::kComputeRead)
        .Use(R::kShadeLists, A::kComputeWrite);
    b.Use(R::kHdrColor, A::kComputeWrite);                   // the sky, where no surface is
    if (vis_mlaa) b.Use(R::kEdgeSurfaces, A::kComputeRead);  // the runner-ups to list
  }
  b.Pass(PassId::kShade)
      .UseIfPresent(R::kPosedGeometry, A::kGeometryRead)
      .Use(R::kVisId, A::kComputeRead)
      .Use(R::kShadeLists, one_dispatch ? A::kComputeWrite : A::kIndirectRead)
      .Use(R::kHdrColor, A::kComputeWrite)
      .UseIfPresent(R::kAo, A::kComputeRead)
      .UseIfPresent(R::kShadowAtlas, A::kComputeRead)
      .UseIfPresent(R::kLightLists, A::kComputeRead);
  if (vis_mlaa) {
    b.Use(R::kVisCoverage, A::kComputeRead)
        .Use(R::kEdgeSurfaces, A::kComputeWrite);  // the runner-ups' colours
  }
}


namespace {

// The materials of the opaque and alpha-mask drawables in the frustum, ascending: the only
// ones a visibility id can show.
std::vector<uint32_t> MaterialsInFrustum(const GpuScene& gs, const Frustum& frustum) {
  std::vector<uint32_t> out;
  for (const DrawItem& d : gs.draws()) {
    if (d.alpha == AlphaMode::kBlend || !AabbIntersectsFrustum(d.world_bounds, frustum)) continue;
    out.push_back(d.material);
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace

absl::Status Renderer::Impl::PrepareShade(FrameData& f) {
  if (!DrawsVisibility(f.s)) return absl::OkStatus();
  // The materials the shading dispatches for (the others have no pixels).
  f.vis.materials = MaterialsInFrustum(f.gs, FrustumFromViewProj(f.fu.view_proj));
  const uint32_t materials = f.gs.material_count();
  // vis_mlaa's edge list (at most a pixel each) and blend list (at most an edge pixel each)
  // precede the materials' lists, which hold its runner-up surfaces too (at most one per edge
  // pixel). The sky's list follows them, in frames that list it (a pixel each no other list
  // holds).
  const uint64_t pixels =
      uint64_t(f.s.width) * f.s.height * (f.s.aa == AaMode::kVisMlaa ? 4 : 1);
  // And the sky's entry, vis_mlaa's edge list's and blend list's (vis_mlaa.cpp), the sky list's
  // and the two fills' (ShadeBuffers::sky_list_entry).
  if (materials + 6 > shade_material_capacity) {
    const uint32_t cap = std::max(materials + 6, shade_material_capacity * 2);
    const VkDeviceSize bytes = VkDeviceSize(cap) * sizeof(gpu::GpuShadeEntry);
    RETURN_IF_ERROR(MakeBuffer(*ctx, bytes,
                               VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                   VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT |
                                   VK_BUFFER_USAGE_TRANSFER_DST_BIT |
                                   VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                               vk::MemoryUsage::kDeviceLocal, "shade_entries", &shade_entries));
    RETURN_IF_ERROR(MakeBuffer(*ctx, bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                               vk::MemoryUsage::kReadback, "shade_entries_readback",
                               &shade_entries_readback));
    shade_material_capacity = cap;
  }
  if (pixels > shade_pixel_capacity) {
    RETURN_IF_ERROR(MakeBuffer(*ctx, VkDeviceSize(pixels) * sizeof(uint32_t),
                               VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUsage::kDeviceLocal,
                               "shade_pixels", &shade_pixels));
    shade_pixel_capacity = pixels;
  }
  if (f.s.aa == AaMode::kVisMlaa && uint64_t(f.s.width) * f.s.height > edge_color_capacity) {
    // Per edge pixel its runner-up surface and a colour (a uvec2 each; ShadeBuffers).
    edge_color_capacity = uint64_t(f.s.width) * f.s.height;
    RETURN_IF_ERROR(MakeBuffer(*ctx, VkDeviceSize(edge_color_capacity) * 8,
                               VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUsage::kDeviceLocal,
                               "edge_colors", &edge_colors));
    RETURN_IF_ERROR(MakeBuffer(*ctx, VkDeviceSize(edge_color_capacity) * 8,
                               VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUsage::kDeviceLocal,
                               "runner_ups", &runner_ups));
  }
  f.shade.entries = shade_entries.handle();
  f.shade.pixels = shade_pixels.handle();
  f.shade.edge_colors = edge_colors.handle();
  f.shade.runner_ups = runner_ups.handle();
  f.shade.entries_readback = shade_entries_readback.handle();
  f.shade.materials = materials;
  return absl::OkStatus();
}

}  // namespace tessera
