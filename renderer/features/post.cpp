// Full-screen post passes: tonemapping, and the anti-aliasing passes that work on whole images
// (vis_mlaa's geometric AA, TAA, FXAA). Each is one FullscreenProgram: a fragment shader over a
// full-screen triangle (shaders/fullscreen.vert), or its compute twin where post_stage says so,
// reading images through combined samplers.
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>

#include "absl/strings/str_cat.h"
#include "common/status_macros.h"
#include "renderer/features/features.h"
#include "renderer/features/pass.h"
#include "renderer/renderer_impl.h"
#include "renderer/vk/pipeline.h"
#include "renderer/vk/vk_check.h"
#include "shaders/common/gpu_types.h"

namespace tessera {

absl::StatusOr<vk::Sampler> CreateClampSampler(const vk::Context& ctx, bool linear,
                                               const char* name) {
  VkSamplerCreateInfo si{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
  si.magFilter = si.minFilter = linear ? VK_FILTER_LINEAR : VK_FILTER_NEAREST;
  si.addressModeU = si.addressModeV = si.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
  return vk::Sampler::Create(ctx, si, name);
}

absl::StatusOr<FullscreenProgram> FullscreenProgram::Create(const vk::Context& ctx,
                                                            const char* name,
                                                            const char* fragment_shader,
                                                            uint32_t inputs, uint32_t push_size,
                                                            std::vector<VkFormat> outputs,
                                                            const char* compute_shader,
                                                            ComputeRule rule) {
  FullscreenProgram p;
  p.device_ = ctx.device();
  p.name_ = name;
  p.fragment_shader_ = fragment_shader;
  p.compute_shader_ = compute_shader ? compute_shader : "";
  p.outputs_ = std::move(outputs);
  p.rule_ = rule;
  p.inputs_ = inputs;
  p.push_size_ = push_size;
  std::vector<VkDescriptorSetLayoutBinding> bindings;
  for (uint32_t i = 0; i < inputs; ++i)
    bindings.push_back({i, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
                        VK_SHADER_STAGE_FRAGMENT_BIT, nullptr});
  std::vector<VkPushConstantRange> push;
  if (push_size > 0) push.push_back({VK_SHADER_STAGE_FRAGMENT_BIT, 0, push_size});
  ASSIGN_OR_RETURN(PassLayout layout, PassLayout::Create(ctx, bindings, push, name));
  p.layout_ = std::move(layout);
  ASSIGN_OR_RETURN(p.pipelines_[0], p.Build(ctx, false, 0));
  if (p.compute_shader_.empty()) return p;
  for (VkDescriptorSetLayoutBinding& b : bindings) b.stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
  for (uint32_t i = 0; i < p.outputs_.size(); ++i)
    bindings.push_back({inputs + i, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1,
                        VK_SHADER_STAGE_COMPUTE_BIT, nullptr});
  for (VkPushConstantRange& r : push) r.stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
  const std::string compute_name = std::string(name) + ".compute";
  ASSIGN_OR_RETURN(p.compute_layout_,
                   PassLayout::Create(ctx, bindings, push, compute_name.c_str()));
  ASSIGN_OR_RETURN(p.compute_pipelines_[0], p.Build(ctx, true, 0));
  return p;
}

absl::StatusOr<vk::Pipeline> FullscreenProgram::Build(const vk::Context& ctx, bool compute,
                                                      uint32_t variant) const {
  const std::string suffix = variant == 0 ? "" : absl::StrCat(".", variant);
  if (compute) {
    return vk::CreateComputePipeline(ctx, name_ + ".compute" + suffix, compute_shader_,
                                     compute_layout_.pipeline_layout(), {variant});
  }
  vk::GraphicsPipelineDesc d;
  d.name = name_ + suffix;
  d.vertex_shader = "fullscreen.vert";
  d.fragment_shader = fragment_shader_;
  d.layout = layout_.pipeline_layout();
  d.scene_vertex_input = false;
  d.color_formats = outputs_;
  d.fragment_constants = {variant};
  return vk::CreateGraphicsPipeline(ctx, d);
}

absl::Status FullscreenProgram::Ensure(const vk::Context& ctx, const Settings& s,
                                       uint32_t variant) {
  const bool compute = RunsCompute(s);
  std::map<uint32_t, vk::Pipeline>& built = compute ? compute_pipelines_ : pipelines_;
  if (built.count(variant)) return absl::OkStatus();
  ASSIGN_OR_RETURN(vk::Pipeline pipeline, Build(ctx, compute, variant));
  built.emplace(variant, std::move(pipeline));
  return absl::OkStatus();
}

void FullscreenProgram::Draw(const PassContext& ctx, const std::vector<PostInput>& inputs,
                             const std::vector<VkImageView>& outputs, const void* push,
                             VkExtent2D extent, uint32_t variant) const {
  if (RunsCompute(*ctx.settings)) {
    SetWriter w(device_, compute_layout_.Allocate(ctx));
    for (uint32_t i = 0; i < inputs_; ++i)
      w.Sampled(i, inputs[i].sampler, inputs[i].view, inputs[i].layout);
    for (uint32_t i = 0; i < outputs.size(); ++i) w.Storage(inputs_ + i, outputs[i]);
    w.Update();
    const VkPipelineLayout layout = compute_layout_.pipeline_layout();
    vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE,
                      compute_pipelines_.at(variant).handle());
    const VkDescriptorSet set = w.set();
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout, 0, 1, &set, 0,
                            nullptr);
    if (push_size_ > 0)
      vkCmdPushConstants(ctx.cmd, layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, push_size_, push);
    const uint32_t width = extent.width ? extent.width : ctx.targets->width;
    const uint32_t height = extent.height ? extent.height : ctx.targets->height;
    vkCmdDispatch(ctx.cmd, (width + 7) / 8, (height + 7) / 8, 1);
    return;
  }
  const VkDescriptorSet set = layout_.Allocate(ctx);
  SetWriter w(device_, set);
  for (uint32_t i = 0; i < inputs_; ++i)
    w.Sampled(i, inputs[i].sampler, inputs[i].view, inputs[i].layout);
  w.Update();

  std::vector<VkRenderingAttachmentInfo> colors;
  for (VkImageView v : outputs) {
    VkRenderingAttachmentInfo c{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
    c.imageView = v;
    c.imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
    c.loadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;  // every pixel is written
    c.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    colors.push_back(c);
  }
  BeginRendering(ctx, colors.data(), uint32_t(colors.size()), nullptr, extent);
  vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipelines_.at(variant).handle());
  vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout_.pipeline_layout(), 0,
                          1, &set, 0, nullptr);
  vkCmdSetCullMode(ctx.cmd, VK_CULL_MODE_NONE);
  if (push_size_ > 0)
    vkCmdPushConstants(ctx.cmd, layout_.pipeline_layout(), VK_SHADER_STAGE_FRAGMENT_BIT, 0,
                       push_size_, push);
  vkCmdDraw(ctx.cmd, 3, 1, 0, 0);
  vkCmdEndRendering(ctx.cmd);
}

const vk::Image& PostColor(const PassContext& ctx) { return ctx.targets->Get(ctx.post_color); }

namespace {

// A pass made of one full-screen program and its samplers.
class PostPass : public Pass {
 public:
  PostPass(FullscreenProgram program, vk::Sampler nearest, vk::Sampler linear)
      : program_(std::move(program)), nearest_(std::move(nearest)), linear_(std::move(linear)) {}

 protected:
  PostInput Nearest(const vk::Image& image,
                    VkImageLayout layout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL) const {
    return {image.view(), nearest_.handle(), layout};
  }
  PostInput Linear(const vk::Image& image) const {
    return {image.view(), linear_.handle(), VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
  }
  // The tonemapped image, filtered in linear light: through its sRGB view where a compute
  // tonemap wrote it as UNORM (ImageDesc::sampled_view_format), else its own sRGB view.
  PostInput LinearSrgb(const vk::Image& image) const {
    return {image.sampled_view(), linear_.handle(), VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
  }
  FullscreenProgram program_;
  vk::Sampler nearest_, linear_;
};

template <typename T>
absl::StatusOr<std::unique_ptr<Pass>> MakePost(const vk::Context& ctx, const char* name,
                                               const char* fragment, uint32_t inputs,
                                               uint32_t push_size, std::vector<VkFormat> outputs,
                                               const char* compute = nullptr,
                                               FullscreenProgram::ComputeRule rule =
                                                   &FullscreenProgram::Compute) {
  ASSIGN_OR_RETURN(FullscreenProgram program,
                   FullscreenProgram::Create(ctx, name, fragment, inputs, push_size,
                                             std::move(outputs), compute, rule));
  absl::StatusOr<vk::Sampler> nearest = CreateClampSampler(ctx, false, name);
  if (!nearest.ok()) return nearest.status();
  absl::StatusOr<vk::Sampler> linear = CreateClampSampler(ctx, true, name);
  if (!linear.ok()) return linear.status();
  return std::unique_ptr<Pass>(new T(std::move(program), std::move(*nearest), std::move(*linear)));
}

// Tonemap: HDR colour -> exposure (fixed or auto) + bloom -> Khronos PBR Neutral or the
// photographic operator on luma -> sRGB RGBA8 (the attachment's sRGB format does the encoding).
// PBR Neutral keeps base colours true under neutral light, which is what product and
// sample-model renders are judged by. Debug views pass through without tonemapping. Reads the
// post-AA colour when an AA pass made one.
class TonemapPass final : public PostPass {
 public:
  using PostPass::PostPass;
  PassId id() const override { return PassId::kTonemap; }
  absl::Status Prepare(const vk::Context& ctx, const Settings& s) override {
    return program_.Ensure(ctx, s, Variant(s));
  }
  void Record(PassContext& ctx) override {
    const Settings& s = *ctx.settings;
    const ExposureFrame& e = *ctx.exposure;
    const bool bloom = s.bloom;
    const gpu::TonemapPush push{
        e.params,
        glm::vec4(s.bloom_strength / float(kBloomLevels), 1.0f / float(kBloomLevels), 0.0f, 0.0f)};
    // The atlas is in shader-read layout outside the shadow pass, ao in the frame graph's
    // sampled state (1x1 stand-ins without shadows, ssao); without bloom, ao's image stands in
    // for the bloom too (never read).
    const PostInput bloom_in =
        bloom ? PostInput{ctx.targets->bloom_up_levels[0], linear_.handle(),
                          VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL}
              : Linear(*ctx.ao_view);
    program_.Draw(ctx,
                  {Nearest(PostColor(ctx)), Linear(*ctx.ao_view),
                   Nearest(*ctx.shadow_atlas_view), bloom_in,
                   {e.view, nearest_.handle(), e.layout}},
                  {ctx.targets->ldr.view()}, &push, {0, 0}, Variant(s));
  }

 private:
  // The shader's variant (tonemap.glsl's kVariant): what it shows, bloom, curve and exposure.
  static uint32_t Variant(const Settings& s) {
    uint32_t view = gpu::kTonemapViewPlain;  // debug views of surfaces: the colour as shaded
    switch (s.debug_view) {
      case DebugView::kNone: view = gpu::kTonemapViewColor; break;
      case DebugView::kBloom: view = gpu::kTonemapViewBloom; break;
      case DebugView::kShadowAtlas: view = gpu::kTonemapViewAtlas; break;
      case DebugView::kSsao: view = gpu::kTonemapViewSsao; break;
      default: break;
    }
    return view | (s.bloom ? gpu::kTonemapBloom : 0u) |
           (s.tonemapper == Tonemapper::kPhotographic ? gpu::kTonemapPhotographic : 0u) |
           (s.exposure_mode == ExposureMode::kAuto ? gpu::kTonemapAutoExposure : 0u);
  }
};

// vis_mlaa's geometric AA (shaders/common/geometric_aa.glsl): pixels whose surface owns every
// sample pass through; the others blend with the two neighbours their coverage points away from.
// It runs over the resolve's blend list only (its edge pixels with more than one surface), in
// place in the HDR colour (shaders/geometric_aa_edges.comp: each listed pixel's blend into a list,
// then into the image), so its cost comes from the edges. The aa_mask debug view, which shows every pixel, is a full-screen
// program into the post-AA colour (fragment or compute: post_stage).
class GeometricAaPass final : public PostPass {
 public:
  using PostPass::PostPass;
  PassId id() const override { return PassId::kGeometricAa; }

  absl::Status CreateEdges(const vk::Context& ctx) {
    device_ = ctx.device();
    constexpr VkShaderStageFlags kCompute = VK_SHADER_STAGE_COMPUTE_BIT;
    constexpr VkDescriptorType kSampled = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
    constexpr VkDescriptorType kBuffer = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    ASSIGN_OR_RETURN(
        edge_layout_,
        PassLayout::Create(ctx,
                           {LayoutBinding(1, kSampled, kCompute), LayoutBinding(2, kSampled, kCompute),
                            LayoutBinding(gpu::kGeometricAaBindingEntries, kBuffer, kCompute),
                            LayoutBinding(gpu::kGeometricAaBindingPixels, kBuffer, kCompute),
                            LayoutBinding(gpu::kGeometricAaBindingColors, kBuffer, kCompute),
                            LayoutBinding(gpu::kGeometricAaBindingOut,
                                          VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, kCompute),
                            LayoutBinding(gpu::kGeometricAaBindingRunnerUps, kBuffer, kCompute)},
                           {{kCompute, 0, sizeof(gpu::GeometricAaPush)}}, "geometric_aa.edges"));
    ASSIGN_OR_RETURN(blend_, vk::CreateComputePipeline(ctx, "geometric_aa.edges",
                                                       "geometric_aa_edges.comp",
                                                       edge_layout_.pipeline_layout(),
                                                       {gpu::kGeometricAaBlend}));
    ASSIGN_OR_RETURN(write_, vk::CreateComputePipeline(ctx, "geometric_aa.edges.write",
                                                       "geometric_aa_edges.comp",
                                                       edge_layout_.pipeline_layout(),
                                                       {gpu::kGeometricAaWrite}));
    return absl::OkStatus();
  }

  void Record(PassContext& ctx) override {
    const FrameTargets& t = *ctx.targets;
    gpu::GeometricAaPush push{ctx.samples, 0u, ctx.vis->triangle_bits, 0u};
    if (ctx.settings->debug_view == DebugView::kAaMask) {
      push.show_mask = 1u;
      program_.Draw(ctx, {Nearest(t.hdr), Nearest(t.vis_coverage), Nearest(t.vis_id)},
                    {t.post_hdr.view()}, &push);
      return;
    }
    const ShadeBuffers& sb = *ctx.shade;
    push.edges = sb.edge_entry();  // the resolve's edge list (the blend list's entry is the next)
    const VkDescriptorSet set = edge_layout_.Allocate(ctx);
    SetWriter(device_, set)
        .Sampled(1, nearest_.handle(), t.vis_coverage.view())
        .Sampled(2, nearest_.handle(), t.vis_id.view())
        .Buffer(gpu::kGeometricAaBindingEntries, sb.entries)
        .Buffer(gpu::kGeometricAaBindingPixels, sb.pixels)
        .Buffer(gpu::kGeometricAaBindingColors, sb.edge_colors)
        .Buffer(gpu::kGeometricAaBindingRunnerUps, sb.runner_ups)
        .Storage(gpu::kGeometricAaBindingOut, t.hdr.view())
        .Update();
    const VkPipelineLayout layout = edge_layout_.pipeline_layout();
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout, 0, 1, &set, 0,
                            nullptr);
    vkCmdPushConstants(ctx.cmd, layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
    // Dispatched over the blend list (the edge pixels with more than one surface).
    const VkDeviceSize args = VkDeviceSize(sb.blend_entry()) * sizeof(gpu::GpuShadeEntry);
    vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, blend_.handle());
    vkCmdDispatchIndirect(ctx.cmd, sb.entries, args);
    // The blends are written (and every neighbour read) before any pixel changes.
    vk::CmdMemoryBarrier(ctx.cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                         VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                         VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                         VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
    vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, write_.handle());
    vkCmdDispatchIndirect(ctx.cmd, sb.entries, args);
  }

 private:
  VkDevice device_ = VK_NULL_HANDLE;
  PassLayout edge_layout_;
  vk::Pipeline blend_, write_;  // kGeometricAaBlend, kGeometricAaWrite
};

// TAA (shaders/taa.frag): this frame with the reprojected history, clamped to the frame's
// neighbourhood; writes the frame's post-AA colour and the next frame's history.
class TaaPass final : public PostPass {
 public:
  using PostPass::PostPass;
  PassId id() const override { return PassId::kTaa; }
  void Record(PassContext& ctx) override {
    const TaaFrame& taa = *ctx.taa;  // the history images are imported (SetupTaa)
    const gpu::TaaPush push{
        taa.reproject,
        glm::vec4(taa.current_weight, taa.history_valid ? 1.0f : 0.0f,
                  1.0f / float(ctx.targets->width), 1.0f / float(ctx.targets->height)),
        glm::vec4(taa.motion ? 1.0f : 0.0f, taa.camera_moved ? 1.0f : 0.0f, 0.0f, 0.0f)};
    // Without object motion the depth stands in for the motion target (not read).
    const PostInput motion =
        taa.motion ? Nearest(ctx.targets->motion) : Nearest(ctx.targets->depth);
    program_.Draw(ctx,
                  {Nearest(ctx.targets->hdr), Nearest(ctx.targets->depth),
                   Linear(*taa.history_read), motion},
                  {ctx.targets->post_hdr.view(), taa.history_write->view()}, &push);
  }
};

// FXAA (shaders/common/fxaa.glsl) on the tonemapped image, read through a bilinear sampler and
// an sRGB view (filtering in linear light in both stages).
class FxaaPass final : public PostPass {
 public:
  using PostPass::PostPass;
  PassId id() const override { return PassId::kFxaa; }
  void Record(PassContext& ctx) override {
    const gpu::FxaaPush push{
        glm::vec2(1.0f / float(ctx.targets->width), 1.0f / float(ctx.targets->height))};
    program_.Draw(ctx, {LinearSrgb(ctx.targets->ldr)}, {ctx.targets->fxaa.view()}, &push);
  }
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateTonemapPass(const vk::Context& ctx) {
  return MakePost<TonemapPass>(ctx, "tonemap", "tonemap.frag", 5, sizeof(gpu::TonemapPush),
                               {kLdrFormat}, "tonemap.comp");
}
absl::StatusOr<std::unique_ptr<Pass>> CreateGeometricAaPass(const vk::Context& ctx) {
  ASSIGN_OR_RETURN(std::unique_ptr<Pass> pass,
                   MakePost<GeometricAaPass>(ctx, "geometric_aa", "geometric_aa.frag", 3,
                                             sizeof(gpu::GeometricAaPush), {kHdrFormat},
                                             "geometric_aa.comp"));
  RETURN_IF_ERROR(static_cast<GeometricAaPass&>(*pass).CreateEdges(ctx));
  return pass;
}
absl::StatusOr<std::unique_ptr<Pass>> CreateTaaPass(const vk::Context& ctx) {
  return MakePost<TaaPass>(ctx, "taa", "taa.frag", 4, sizeof(gpu::TaaPush),
                           {kHdrFormat, kHdrFormat}, "taa.comp");
}
absl::StatusOr<std::unique_ptr<Pass>> CreateFxaaPass(const vk::Context& ctx) {
  return MakePost<FxaaPass>(ctx, "fxaa", "fxaa.frag", 1, sizeof(gpu::FxaaPush), {kLdrFormat},
                            "fxaa.comp");
}

void SetupTaa(GraphBuilder& b) {
  if (b.settings().aa != AaMode::kTaa) return;
  // The view's history: last frame's output is read (undefined before the first), this
  // frame's is written whole and left readable for the next frame.
  b.Import(Resource::kTaaHistory, b.features().taa_history_valid ? Access::kSampled : Access::kNone,
           Access::kSampled);
  b.Import(Resource::kTaaHistoryNext, Access::kNone, Access::kSampled);
  const bool compute = FullscreenProgram::Compute(b.settings());
  const Access read = compute ? Access::kComputeRead : Access::kSampled;
  const Access write = compute ? Access::kComputeWrite : Access::kColorWrite;
  b.Pass(PassId::kTaa)
      .Use(Resource::kHdrColor, read)
      .Use(Resource::kDepth, read)
      .Use(Resource::kTaaHistory, read)
      .UseIfPresent(Resource::kMotion, read)
      .Use(Resource::kPostHdr, write)
      .Use(Resource::kTaaHistoryNext, write);
}

void SetupTonemap(GraphBuilder& b) {
  const Resource color = b.SceneColor();
  const bool compute = FullscreenProgram::Compute(b.settings());
  const Access read = compute ? Access::kComputeRead : Access::kSampled;
  b.Pass(PassId::kTonemap)
      .Use(color, read)
      .Use(Resource::kLdrColor, compute ? Access::kComputeWrite : Access::kColorWrite)
      .UseIfPresent(Resource::kAo, read)  // the ssao debug view
      .UseIfPresent(Resource::kBloomUp, read)
      .UseIfPresent(Resource::kShadowAtlas, read)  // the shadow_atlas debug view
      .UseIfPresent(Resource::kExposureState,
                    compute ? Access::kComputeReadGeneral : Access::kSampledGeneral);
}

void SetupFxaa(GraphBuilder& b) {
  if (b.settings().aa != AaMode::kFxaa) return;
  const bool compute = FullscreenProgram::Compute(b.settings());
  b.Pass(PassId::kFxaa)
      .Use(Resource::kLdrColor, compute ? Access::kComputeRead : Access::kSampled)
      .Use(Resource::kFxaaColor, compute ? Access::kComputeWrite : Access::kColorWrite);
}


namespace {

// TAA's sub-pixel jitter: the Halton (2, 3) sequence over 16 frames, in pixels around the
// pixel centre.
glm::vec2 TaaJitter(uint32_t frame) {
  auto halton = [](uint32_t i, uint32_t base) {
    float f = 1.0f, r = 0.0f;
    for (; i > 0; i /= base) {
      f /= float(base);
      r += f * float(i % base);
    }
    return r;
  };
  const uint32_t i = frame % 16 + 1;
  return glm::vec2(halton(i, 2) - 0.5f, halton(i, 3) - 0.5f);
}

}  // namespace

absl::Status Renderer::Impl::PrepareCamera(FrameData& f) {
  const Settings& s = f.s;
  gpu::FrameUniforms& fu = f.fu;
  f.aspect = float(s.width) / float(s.height);
  fu.view = ViewMatrix(f.camera);
  fu.proj = ProjectionMatrix(f.camera, f.aspect);
  f.unjittered_view_proj = fu.proj * fu.view;
  // taa: this view's history, and this frame's jitter of the projection (sub-pixel).
  if (s.aa == AaMode::kTaa) {
    ASSIGN_OR_RETURN(TaaHistory * h, Taa(f.gs, f.view));
    TaaHistory& history = *h;
    f.taa_history = h;
    TaaFrame& taa = f.taa;
    const bool valid = history.written[history.current];
    fu.prev_view_proj = history.view_proj;
    RETURN_IF_ERROR(PrepareMotion(f, history, valid));
    const bool still = valid && history.view_proj == f.unjittered_view_proj;
    taa.camera_moved = valid && !still;
    // A still camera averages every frame so far (converging on the jittered supersample); a
    // moving one blends its history too, keeping at least a tenth of each new frame (its count
    // grows to 9: it used to stay at 0 for a view that moved from its first frame, which then
    // never blended and shook with the jitter). Moving geometry under a still camera averages
    // like a still camera: its history follows it.
    history.frames = !valid ? 0 : still ? std::min(history.frames + 1, 15u)
                                        : std::min(history.frames + 1, 9u);
    taa.current_weight = 1.0f / float(history.frames + 1);
    taa.history_valid = valid;
    taa.reproject = history.view_proj * glm::inverse(f.unjittered_view_proj);
    taa.history_read = &history.images[history.current];
    taa.history_write = &history.images[history.current ^ 1];
    const glm::vec2 jitter = TaaJitter(history.jitter_index++);
    fu.proj[2][0] += 2.0f * jitter.x / float(s.width);
    fu.proj[2][1] += 2.0f * jitter.y / float(s.height);
    history.current ^= 1;
    history.written[history.current] = true;
    history.view_proj = f.unjittered_view_proj;
  }
  fu.view_proj = fu.proj * fu.view;
  fu.camera_position = glm::vec4(CameraPosition(f.camera), 1.0f);
  const PixelRays rays = PixelRaysFor(fu.view_proj, s.width, s.height);
  fu.ray_origin = glm::vec4(rays.origin, 0.0f);
  fu.ray_dx = glm::vec4(rays.dx, 0.0f);
  fu.ray_dy = glm::vec4(rays.dy, 0.0f);
  fu.ambient_sky = glm::vec4(0.40f, 0.52f, 0.75f, s.ibl ? 1.0f : 0.0f);
  fu.ambient_ground = glm::vec4(0.24f, 0.21f, 0.18f, 0.0f);
  return absl::OkStatus();
}

}  // namespace tessera
