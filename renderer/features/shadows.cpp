// Shadow maps into the atlas: for each face the renderer decided to (re)render this frame (its
// view changed, or it was evicted, or caching is off), clear its square and draw the opaque and
// alpha-mask items in its frustum, depth only, through the face's matrix (a push constant).
// Cached faces are not touched: the atlas is loaded, not cleared, so a frame where nothing
// changed records no draw at all. The atlas lives across frames and is imported into each frame
// graph: it waits in shader-read layout, the graph moves it to attachment layout for this pass
// and back for the shading.
// Draws are direct (one per item in the face's frustum, the items culled on the CPU per face):
// a face sees few items, and its list changes with the face, not per frame.
#include "absl/strings/str_cat.h"
#include "common/status_macros.h"
#include "renderer/features/features.h"
#include "renderer/features/pass.h"
#include "renderer/renderer_impl.h"
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
    RETURN_IF_ERROR(
        ctx.CreatePipelineLayout({scene.set_layout, scene.material_set_layout},
                                 {{VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(gpu::ShadowPush)}},
                                 "shadow pipeline layout", &pass->layout_));
    vk::GraphicsPipelineDesc d;
    d.name = "shadows.opaque";
    d.vertex_shader = "shadow.vert";
    d.layout = pass->layout_.get();
    d.depth_format = kShadowFormat;
    d.depth_test = true;
    d.depth_write = true;
    d.depth_compare = VK_COMPARE_OP_LESS;  // standard Z in the atlas (renderer/shadows.h)
    d.depth_bias_constant = kBiasConstant;
    d.depth_bias_slope = kBiasSlope;
    ASSIGN_OR_RETURN(pass->opaque_, vk::CreateGraphicsPipeline(ctx, d));
    d.name = "shadows.mask";
    d.vertex_shader = "shadow_mask.vert";
    d.fragment_shader = "depth_mask.frag";
    d.attribute_mask = gpu::kAlphaMaskAttributes;
    ASSIGN_OR_RETURN(pass->mask_, vk::CreateGraphicsPipeline(ctx, d));
    return std::unique_ptr<Pass>(std::move(pass));
  }

  void Record(PassContext& ctx) override {
    const ShadowFrame& sf = *ctx.shadows;
    const vk::Image& atlas = *sf.atlas;
    if (sf.faces.empty() && !sf.atlas_new) return;  // every face cached: nothing to do
    // The graph moved the atlas (imported, SetupShadows) to the depth-attachment layout;
    // loading keeps the cached faces.
    const VkImageLayout attach = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
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
    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout_.get(), 0, 1,
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
          const gpu::ShadowPush push{face.view_proj};
          vkCmdPushConstants(ctx.cmd, layout_.get(), VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(push),
                             &push);
          bound = want;
        }
        if (mask && item.material != material) {
          const VkDescriptorSet set = ctx.scene->material_set(item.material);
          vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout_.get(),
                                  gpu::kMaterialSet, 1, &set, 0, nullptr);
          material = item.material;
        }
        vkCmdDrawIndexed(ctx.cmd, item.index_count, 1, item.first_index, item.vertex_offset,
                         item.drawable);
      }
    }
    vkCmdEndRendering(ctx.cmd);
  }

 private:
  VkDevice device_ = VK_NULL_HANDLE;
  vk::UniquePipelineLayout layout_;  // declared before the pipelines: destroyed after them
  vk::Pipeline opaque_, mask_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateShadowPass(const vk::Context& ctx,
                                                       const SceneLayout& layout) {
  return ShadowPass::Create(ctx, layout);
}

void SetupShadows(GraphBuilder& b) {
  if (!b.settings().shadows) return;
  // The atlas lives across frames in the shading's sampled state; loading it keeps the cached
  // faces (a new atlas is undefined and cleared whole).
  b.Import(Resource::kShadowAtlas,
           b.features().shadow_atlas_valid ? Access::kSampled : Access::kNone, Access::kSampled);
  b.Pass(PassId::kShadows)
      .Use(Resource::kShadowAtlas, Access::kDepthWrite)
      .UseIfPresent(Resource::kPosedGeometry, Access::kGeometryRead);
}

namespace {

// Places a frame's shadow views in the atlas: each face takes a view (its matrix into the
// atlas) and is listed for rendering unless the atlas already holds exactly it.
class ShadowPlacer {
 public:
  ShadowPlacer(const GpuScene& gs, const Settings& s, ShadowAtlas& atlas, gpu::ShadowUniforms& su,
               ShadowFrame& out)
      : gs_(gs), s_(s), atlas_(atlas), su_(su), out_(out), size_(s.shadow_atlas_size) {}

  uint32_t size() const { return size_; }
  uint32_t views() const { return views_; }

  uint64_t Key(uint64_t kind, uint64_t a, uint64_t b) const {
    const uint64_t k[4] = {kind, gs_.serial(), a, b};
    return HashBytes(k, sizeof(k));
  }

  bool AddFace(uint64_t key, uint32_t res, const glm::mat4& face_view_proj, float texel,
               bool perspective) {
    uint64_t content = HashBytes(&face_view_proj, sizeof(face_view_proj), gs_.serial());
    // An animated scene's maps hold one pose.
    const uint64_t pose = gs_.pose_serial();
    content = HashBytes(&pose, sizeof(pose), content);
    content = HashBytes(&res, sizeof(res), content);
    std::optional<ShadowAtlas::Placement> placed = atlas_.Acquire(key, res, content);
    if (!placed) return false;
    gpu::GpuShadowView& v = su_.views[views_++];
    v.world_to_atlas = AtlasTransform(placed->rect, size_) * face_view_proj;
    v.params = glm::vec4(texel, perspective ? 1.0f : 0.0f, 0.0f, 0.0f);
    if (placed->cached && s_.shadow_cache) return true;
    ShadowFace face{placed->rect.x, placed->rect.y, placed->rect.size, face_view_proj, {}};
    // The face's own culling: every item in its frustum (all of them with culling none).
    // Blended surfaces cast no shadow.
    const std::vector<DrawItem>& items = gs_.draws();
    const Frustum frustum = FrustumFromViewProj(face_view_proj);
    for (uint32_t i = 0; i < items.size(); ++i) {
      if (items[i].alpha == AlphaMode::kBlend) continue;
      if (s_.culling != CullingMode::kNone &&
          !AabbIntersectsFrustum(items[i].world_bounds, frustum))
        continue;
      face.items.push_back(i);
    }
    out_.faces.push_back(std::move(face));
    return true;
  }

  // Takes back the views and faces placed since `views` / `faces` (their atlas keys are given
  // back by the caller).
  void Rewind(uint32_t views, size_t faces) {
    views_ = views;
    out_.faces.resize(faces);
  }
  void Release(uint64_t key) { atlas_.Release(key); }

 private:
  const GpuScene& gs_;
  const Settings& s_;
  ShadowAtlas& atlas_;
  gpu::ShadowUniforms& su_;
  ShadowFrame& out_;
  const uint32_t size_;
  uint32_t views_ = 0;
};

// The sun: the first directional light, in cascades that follow this view's camera (so the
// key carries the view: two viewers of one scene do not overwrite each other's cascades).
// Returns the cascades placed (0: the sun stays unshadowed).
uint32_t PlaceSun(ShadowPlacer& placer, const FrameData& f, gpu::GpuLight* gl,
                  gpu::ShadowUniforms& su, Frame& frame) {
  const glm::vec3 eye = CameraPosition(f.camera);
  for (size_t i = 0; i < f.global.size(); ++i) {
    if (f.global[i].type != LightType::kDirectional) continue;
    const Aabb& b = f.gs.bounds();
    float distance = b.farthest_distance(eye);
    if (f.camera.zfar > 0.0f) distance = std::min(distance, f.camera.zfar);
    distance = std::max(distance, f.camera.znear * 2.0f);
    CascadeParams cp;
    cp.count = kMaxCascades;
    cp.resolution = placer.size() / 4;
    const std::vector<Cascade> cs =
        ComputeCascades(f.camera, f.aspect, f.global[i].direction, b, distance, cp);
    bool placed = true;
    for (uint32_t c = 0; c < cs.size() && placed; ++c)
      placed = placer.AddFace(placer.Key(1, f.view, c), cp.resolution, cs[c].view_proj,
                              cs[c].texel_world, false);
    if (!placed) {  // an atlas too small for them: the sun stays unshadowed
      placer.Rewind(0, 0);
      frame.settings.notes.push_back(
          {"shadows", "the sun's cascades did not fit the shadow atlas; the sun is unshadowed"});
      return 0;
    }
    // The spheres the shader picks cascades by, less the normal offset's 1.5 texels (and half a
    // texel of snapping): an offset lookup then stays inside the map's filter border.
    for (uint32_t c = 0; c < cs.size(); ++c)
      su.cascade_spheres[c] = glm::vec4(cs[c].center, cs[c].radius - 2.0f * cs[c].texel_world);
    gl[i].spot.z = 1.0f;  // views 0 .. cascades - 1
    gl[i].spot.w = float(cs.size());
    ++frame.stats.shadowed_lights;
    return uint32_t(cs.size());
  }
  return 0;
}

// Point and spot lights: the most important ones in view. A spot has one view, a point light
// six (its unrolled cubemap); a light whose faces do not fit even at half size stays
// unshadowed.
// Each one shadowed is listed in `su.shadowed` and knows its place there (GpuLight.spot.w).
void PlaceLocalLights(ShadowPlacer& placer, const FrameData& f, gpu::GpuLight* ll,
                      gpu::ShadowUniforms& su, Frame& frame) {
  uint32_t shadowed = 0;
  const std::vector<uint32_t> chosen = ChooseShadowedLights(
      f.local, FrustumFromViewProj(f.fu.view_proj), CameraPosition(f.camera), f.s.shadow_lights);
  const uint32_t size = placer.size();
  uint32_t dropped = 0;
  for (uint32_t li : chosen) {
    const Light& l = f.local[li];
    const bool spot = l.type == LightType::kSpot;
    const uint32_t faces = spot ? 1 : kCubeFaces;
    bool placed = false;
    for (uint32_t res = std::max(size / (spot ? 8 : 16), 64u); res >= 64 && !placed; res /= 2) {
      const uint32_t first = placer.views();
      const size_t rendered = f.shadows.faces.size();
      placed = true;
      const float border = float(res) / float(res - 2 * kShadowBorderTexels);
      const float tan_half =
          spot ? std::tan(std::min(l.outer_cone_angle, glm::radians(89.0f))) * border : border;
      for (uint32_t face = 0; face < faces && placed; ++face) {
        const glm::mat4 vp = spot ? SpotViewProj(l, res, f.gs.bounds())
                                  : PointFaceViewProj(l, face, res, f.gs.bounds());
        placed =
            placer.AddFace(placer.Key(2, li, face), res, vp, 2.0f * tan_half / float(res), true);
      }
      if (!placed) {  // give back the faces placed: they were never rendered
        for (uint32_t face = 0; face < faces; ++face) placer.Release(placer.Key(2, li, face));
        placer.Rewind(first, rendered);
        continue;
      }
      ll[li].spot.z = float(first + 1);
      ll[li].spot.w = float(shadowed);
      su.shadowed[shadowed / 4][shadowed % 4] = li;
      ++shadowed;
      ++frame.stats.shadowed_lights;
    }
    if (!placed) ++dropped;
  }
  if (dropped > 0) {
    frame.settings.notes.push_back(
        {"shadow_lights", absl::StrCat(dropped, " of ", chosen.size(),
                                       " lights did not fit the shadow atlas and are unshadowed "
                                       "(use a larger shadow_atlas_size)")});
  }
}

}  // namespace

// Places this frame's shadow views in the atlas, fills shadow_ubo's views, marks the shadowed
// lights in the light buffers and lists the faces to render.
absl::Status Renderer::Impl::PrepareShadows(FrameData& f, Frame& frame) {
  RETURN_IF_ERROR(EnsureShadowAtlas(f.s.shadow_atlas_size));
  auto& su = *static_cast<gpu::ShadowUniforms*>(shadow_ubo.mapped());
  ShadowAtlas& atlas = *shadow_faces;
  ShadowFrame& out = f.shadows;
  out.atlas = &shadow_atlas;
  out.atlas_new = !shadow_atlas_written;
  if (out.atlas_new) atlas.Clear();
  atlas.BeginFrame();
  const uint32_t evictions_before = atlas.evictions();
  ShadowPlacer placer(f.gs, f.s, atlas, su, out);
  const uint32_t cascades =
      PlaceSun(placer, f, static_cast<gpu::GpuLight*>(lights_ubo.mapped()), su, frame);
  PlaceLocalLights(placer, f, static_cast<gpu::GpuLight*>(local_lights.mapped()), su, frame);
  const uint32_t size = placer.size();
  su.counts = glm::uvec4(placer.views(), cascades, 0u, gpu::kShadowsOn);
  su.atlas = glm::vec4(float(size), 1.0f / float(size), 1.5f, 0.0f);
  FrameStats& stats = frame.stats;
  stats.shadow_views = placer.views();
  stats.shadow_faces_rendered = uint32_t(out.faces.size());
  for (const ShadowFace& face : out.faces) stats.shadow_draws += uint32_t(face.items.size());
  stats.shadow_evictions = atlas.evictions() - evictions_before;
  // Until this frame's submit succeeds the atlas is not known to hold what the faces say.
  if (!out.faces.empty()) shadow_atlas_written = false;
  return absl::OkStatus();
}

}  // namespace tessera
