// Light culling (forward+): one compute dispatch builds every tile's light list from the
// prepass depth and the per-light bounds and row bins (prepared on the CPU, or, with
// light_binning gpu, by two compute dispatches before it); a buffer barrier then hands the
// lists to the fragment shaders, and the counts are copied out for the frame's statistics.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "absl/strings/str_cat.h"
#include "common/status_macros.h"
#include "renderer/features/features.h"
#include "renderer/features/pass.h"
#include "renderer/renderer_impl.h"
#include "renderer/vk/pipeline.h"
#include "renderer/vk/vk_check.h"
#include "shaders/common/gpu_types.h"

namespace tessera {

namespace {

class LightCullPass final : public Pass {
 public:
  LightCullPass(VkDevice device, PassLayout layout, vk::Pipeline pipeline, vk::Pipeline bounds,
                vk::Pipeline bins, vk::Sampler sampler)
      : device_(device),
        layout_(std::move(layout)),
        pipeline_(std::move(pipeline)),
        bounds_(std::move(bounds)),
        bins_(std::move(bins)),
        sampler_(std::move(sampler)) {}
  PassId id() const override { return PassId::kLightCull; }

  void Record(PassContext& ctx) override {
    const LightCullBuffers& lb = *ctx.light_buffers;
    const VkDescriptorSet set = layout_.Allocate(ctx);
    SetWriter(device_, set)
        .Buffer(gpu::kCullBindingFrame, lb.frame_ubo, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER)
        .Buffer(gpu::kCullBindingLightBounds, lb.bounds)
        .Sampled(gpu::kCullBindingDepth, sampler_.handle(), ctx.targets->depth.view())
        .Buffer(gpu::kCullBindingTileCounts, lb.tile_counts)
        .Buffer(gpu::kCullBindingTileLights, lb.tile_lights)
        .Buffer(gpu::kCullBindingRowLights, lb.row_lights)
        .Buffer(gpu::kCullBindingLocalLights, lb.local_lights)
        .Update();

    // The graph ordered the lists after their earlier uses (SetupLightCulling).

    vkCmdBindDescriptorSets(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout_.pipeline_layout(), 0,
                            1, &set, 0, nullptr);
    if (lb.gpu_binning) {
      // Each light's bounds, then the row lists from them, then the tile lists (below).
      auto compute_to_compute = [&](VkBuffer buffer) {
        const VkBufferMemoryBarrier2 b = vk::MakeBufferBarrier(
            buffer, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
            VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_READ_BIT);
        vk::CmdBarrier(ctx.cmd, nullptr, 0, &b, 1);
      };
      vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, bounds_.handle());
      vkCmdDispatch(ctx.cmd, (lb.lights + gpu::kLightCullGroupSize - 1) / gpu::kLightCullGroupSize,
                    1, 1);
      compute_to_compute(lb.bounds);
      vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, bins_.handle());
      vkCmdDispatch(ctx.cmd, lb.rows, 1, 1);
      compute_to_compute(lb.row_lights);
    }
    vkCmdBindPipeline(ctx.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_.handle());
    vkCmdDispatch(ctx.cmd, (lb.tiles + gpu::kLightCullGroupSize - 1) / gpu::kLightCullGroupSize, 1,
                  1);

    // This pass's own copy of the counts for the statistics (the graph orders the lists
    // before the shading's reads).
    const VkBufferMemoryBarrier2 after =
        vk::MakeBufferBarrier(lb.tile_counts, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                              VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, VK_PIPELINE_STAGE_2_COPY_BIT,
                              VK_ACCESS_2_TRANSFER_READ_BIT);
    vk::CmdBarrier(ctx.cmd, nullptr, 0, &after, 1);
    const VkBufferCopy copy{0, 0, VkDeviceSize(lb.tiles) * sizeof(uint32_t)};
    vkCmdCopyBuffer(ctx.cmd, lb.tile_counts, lb.counts_readback, 1, &copy);
    const VkBufferMemoryBarrier2 host = vk::MakeBufferBarrier(
        lb.counts_readback, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
        VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_READ_BIT);
    vk::CmdBarrier(ctx.cmd, nullptr, 0, &host, 1);
  }

 private:
  VkDevice device_;
  PassLayout layout_;
  vk::Pipeline pipeline_, bounds_, bins_;
  vk::Sampler sampler_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateLightCullPass(const vk::Context& ctx) {
  constexpr VkShaderStageFlags kCompute = VK_SHADER_STAGE_COMPUTE_BIT;
  constexpr VkDescriptorType kBuffer = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  const std::vector<VkDescriptorSetLayoutBinding> bindings = {
      LayoutBinding(gpu::kCullBindingFrame, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, kCompute),
      LayoutBinding(gpu::kCullBindingLightBounds, kBuffer, kCompute),
      LayoutBinding(gpu::kCullBindingDepth, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, kCompute),
      LayoutBinding(gpu::kCullBindingTileCounts, kBuffer, kCompute),
      LayoutBinding(gpu::kCullBindingTileLights, kBuffer, kCompute),
      LayoutBinding(gpu::kCullBindingRowLights, kBuffer, kCompute),
      LayoutBinding(gpu::kCullBindingLocalLights, kBuffer, kCompute)};
  ASSIGN_OR_RETURN(PassLayout layout, PassLayout::Create(ctx, bindings, {}, "light cull layout"));
  const VkPipelineLayout pl = layout.pipeline_layout();
  ASSIGN_OR_RETURN(vk::Pipeline pipeline,
                   vk::CreateComputePipeline(ctx, "light_cull", "light_cull.comp", pl));
  ASSIGN_OR_RETURN(vk::Pipeline bounds,
                   vk::CreateComputePipeline(ctx, "light_bounds", "light_bounds.comp", pl));
  ASSIGN_OR_RETURN(vk::Pipeline bins,
                   vk::CreateComputePipeline(ctx, "light_bins", "light_bins.comp", pl));
  VkSamplerCreateInfo si{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
  si.magFilter = si.minFilter = VK_FILTER_NEAREST;
  si.addressModeU = si.addressModeV = si.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
  ASSIGN_OR_RETURN(vk::Sampler sampler, vk::Sampler::Create(ctx, si, "light_cull.depth_sampler"));
  return std::make_unique<LightCullPass>(ctx.device(), std::move(layout), std::move(pipeline),
                                         std::move(bounds), std::move(bins), std::move(sampler));
}

void SetupLightCulling(GraphBuilder& b) {
  // Nothing to cull, or brute force asked for: no lists.
  if (!b.settings().light_culling || b.features().local_lights == 0) return;
  // The lists are rewritten whole each frame; the shading reads them (UseIfPresent).
  b.Import(Resource::kLightLists, Access::kNone, Access::kSampled);
  b.Pass(PassId::kLightCull)
      .Use(Resource::kDepth, Access::kComputeRead)
      .Use(Resource::kLightLists, Access::kComputeWrite);
}


namespace {

gpu::GpuLight ToGpu(const Light& l) {
  gpu::GpuLight g{};
  g.position_range = glm::vec4(l.position, l.range);
  g.color_intensity = glm::vec4(l.color, l.intensity);
  g.direction_type = glm::vec4(glm::normalize(l.direction), float(static_cast<uint32_t>(l.type)));
  // glTF spot falloff: smooth between cos(outer) and cos(inner).
  const float cos_outer = std::cos(l.outer_cone_angle);
  const float cos_inner = std::cos(l.inner_cone_angle);
  const float scale = 1.0f / std::max(0.001f, cos_inner - cos_outer);
  g.spot = glm::vec4(scale, -cos_outer * scale, 0.0f, 0.0f);
  return g;
}

// The light a scene without lights gets: a warm sun from above and in front.
Light DefaultSun() {
  Light sun;
  sun.name = "default_sun";
  sun.type = LightType::kDirectional;
  sun.color = glm::vec3(1.0f, 0.96f, 0.90f);
  sun.intensity = 3.0f;
  sun.direction = glm::normalize(glm::vec3(-0.35f, -1.0f, -0.45f));
  return sun;
}

// Tile lists take tiles x 1 KiB; past 128 MiB (lavapipe's storage-buffer range) the frame
// shades every light instead, and says so.
constexpr uint64_t kMaxTileListBytes = 128ull << 20;

}  // namespace

void Renderer::Impl::SplitSceneLights(const std::vector<Light>& lights, bool scene_lights,
                                      std::vector<Light>& global, std::vector<Light>& local) {
  if (scene_lights) {
    // Point and spot lights without a range reach everywhere: they are global too.
    for (const Light& l : lights) (IsLocalLight(l) ? local : global).push_back(l);
  }
  if (global.empty() && local.empty()) global.push_back(DefaultSun());
}

absl::Status Renderer::Impl::PrepareLights(FrameData& f, Frame& frame) {
  // Directional lights are global (uniform buffer); point and spot lights, the scene's and the
  // synthetic ones, are local and culled per tile. A scene without lights gets a sun.
  const Settings& s = f.s;
  std::vector<Light>& global = f.global;
  std::vector<Light>& local = f.local;
  SplitSceneLights(f.gs.lights(), s.scene_lights, global, local);
  // Directional lights first: the one PlaceSun shadows is then global light 0, which the
  // shading reads at a constant index (shading.glsl's DirectLight).
  std::stable_partition(global.begin(), global.end(),
                        [](const Light& l) { return l.type == LightType::kDirectional; });
  if (global.size() > gpu::kMaxLights) {
    frame.settings.notes.push_back(
        {"scene_lights", absl::StrCat("only the first ", gpu::kMaxLights, " of ", global.size(),
                                      " directional or unbounded lights (directional first) "
                                      "are shaded")});
    global.resize(gpu::kMaxLights);
  }
  if (s.synthetic_lights > 0) {
    std::vector<Light> synthetic = MakeSyntheticLights(
        f.info.bounds, {s.synthetic_lights, s.light_seed, s.light_radius_min,
                        s.light_radius_max, s.lights_animated, s.light_time});
    local.insert(local.end(), synthetic.begin(), synthetic.end());
  }
  if (local.size() > gpu::kMaxLocalLights) {
    frame.settings.notes.push_back(
        {"synthetic_lights", absl::StrCat("only the first ", gpu::kMaxLocalLights, " of ",
                                          local.size(), " point and spot lights are shaded")});
    local.resize(gpu::kMaxLocalLights);
  }
  f.grid = TileGrid{s.width, s.height, s.tile_size};
  f.tiled = s.light_culling && !local.empty();
  if (f.tiled && uint64_t(f.grid.tiles()) * gpu::kMaxLightsPerTile * 4 > kMaxTileListBytes) {
    frame.settings.notes.push_back(
        {"light_culling", absl::StrCat("not applied: ", f.grid.tiles(), " tiles of ", s.tile_size,
                                       " px need more than 128 MiB of light lists; every light "
                                       "is shaded at every pixel (use a larger tile_size)")});
    frame.settings.effective.light_culling = false;
    f.tiled = false;
  }
  // light_binning gpu: every row list has room for every light, after the 2-entry row headers.
  const uint64_t gpu_row_entries = (2 + uint64_t(local.size())) * f.grid.tiles_y();
  if (f.tiled && s.light_binning == LightBinning::kGpu) {
    const uint64_t bytes = gpu_row_entries * 4;
    const uint64_t range = ctx->limits().maxStorageBufferRange;
    if (bytes > range) {
      frame.settings.notes.push_back(
          {"light_binning", absl::StrCat("binned on the CPU: ", f.grid.tiles_y(), " tile rows x ",
                                         local.size(), " lights need ", bytes,
                                         " bytes of row lists, more than the device's storage "
                                         "buffer range (", range, ")")});
      frame.settings.effective.light_binning = LightBinning::kCpu;
    }
  }
  RETURN_IF_ERROR(EnsureLightBuffers(uint32_t(local.size()), f.tiled ? f.grid.tiles() : 1));
  auto* gl = static_cast<gpu::GpuLight*>(lights_ubo.mapped());
  for (size_t i = 0; i < global.size(); ++i) gl[i] = ToGpu(global[i]);
  auto* ll = static_cast<gpu::GpuLight*>(local_lights.mapped());
  for (size_t i = 0; i < local.size(); ++i) ll[i] = ToGpu(local[i]);
  // Shadows are off until PrepareShadows says otherwise.
  static_cast<gpu::ShadowUniforms*>(shadow_ubo.mapped())->counts = glm::uvec4(0u);
  frame.stats.lights = uint32_t(global.size() + local.size());
  frame.stats.local_lights = uint32_t(local.size());
  LightCullBuffers& lb = f.light_buffers;
  lb.frame_ubo = frame_ubo.handle();
  lb.bounds = light_bounds.handle();
  lb.tile_counts = tile_counts.handle();
  lb.tile_lights = tile_lights.handle();
  lb.counts_readback = tile_counts_readback.handle();
  lb.row_lights = row_lights.handle();
  lb.local_lights = local_lights.handle();
  lb.tiles = f.grid.tiles();
  lb.lights = uint32_t(local.size());
  lb.rows = f.grid.tiles_y();
  lb.gpu_binning = f.tiled && s.light_binning == LightBinning::kGpu;
  if (lb.gpu_binning) {  // the light-culling pass bounds and bins them into these
    RETURN_IF_ERROR(EnsureGpuBinBuffers(lb.lights, gpu_row_entries));
    lb.bounds = gpu_light_bounds.handle();
    lb.row_lights = gpu_row_lights.handle();
    lb.row_entries = gpu_row_entries;
  }
  return absl::OkStatus();
}

absl::Status Renderer::Impl::EnsureGpuBinBuffers(uint32_t lights, uint64_t row_entries) {
  constexpr VkBufferUsageFlags kUsage =
      VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT;  // + captures
  if (lights > gpu_bounds_capacity) {
    const uint32_t cap = std::max(lights, gpu_bounds_capacity * 2);
    RETURN_IF_ERROR(MakeBuffer(*ctx, VkDeviceSize(cap) * sizeof(gpu::GpuLightBounds), kUsage,
                               vk::MemoryUsage::kDeviceLocal, "gpu_light_bounds",
                               &gpu_light_bounds));
    gpu_bounds_capacity = cap;
  }
  if (row_entries > gpu_row_capacity) {
    // Doubling, but within the storage-buffer range (PrepareLights keeps row_entries in it).
    const uint64_t cap = std::min(std::max(row_entries, gpu_row_capacity * 2),
                                  uint64_t(ctx->limits().maxStorageBufferRange) / 4);
    RETURN_IF_ERROR(MakeBuffer(*ctx, VkDeviceSize(cap) * 4, kUsage,
                               vk::MemoryUsage::kDeviceLocal, "gpu_row_lights", &gpu_row_lights));
    gpu_row_capacity = cap;
  }
  return absl::OkStatus();
}

absl::Status Renderer::Impl::WriteLightBins(FrameData& f) {
  LightCullBuffers& lb = f.light_buffers;
  if (!f.tiled || lb.gpu_binning) return absl::OkStatus();  // gpu: the pass bins them
  // What the light-culling pass reads: each light projected once, binned by row.
  std::vector<gpu::GpuLightBounds> bounds(f.local.size());
  for (size_t i = 0; i < f.local.size(); ++i)
    bounds[i] = BoundLight(f.local[i], f.fu.view, f.fu.proj, f.camera.znear, f.grid);
  std::memcpy(light_bounds.mapped(), bounds.data(), bounds.size() * sizeof(bounds[0]));
  const std::vector<uint32_t> rows = BinLightsByRow(bounds, f.grid.tiles_y());
  RETURN_IF_ERROR(EnsureRowBuffer(rows.size()));
  std::memcpy(row_lights.mapped(), rows.data(), rows.size() * sizeof(uint32_t));
  lb.row_lights = row_lights.handle();
  lb.row_entries = rows.size();
  return absl::OkStatus();
}

void Renderer::Impl::WriteFrameUniforms(FrameData& f, Frame& frame) {
  const Settings& s = f.s;
  gpu::FrameUniforms& fu = f.fu;
  fu.counts = glm::uvec4(uint32_t(f.global.size()), static_cast<uint32_t>(s.debug_view),
                         s.width, s.height);
  fu.params = glm::vec4(0.0f, f.camera.znear, f.camera.zfar, 0.0f);
  fu.lighting = glm::uvec4(uint32_t(f.local.size()), s.tile_size, f.grid.tiles_x(),
                           (f.tiled ? 1u : 0u) | (s.tile_depth_mask ? 2u : 0u));
  fu.depth_params = glm::vec4(fu.proj[2][2], fu.proj[3][2], float(f.grid.tiles_y()), 0.0f);
  fu.aa = glm::uvec4(f.vis.triangle_bits, targets.samples, 0u, 0u);
  std::memcpy(frame_ubo.mapped(), &fu, sizeof(fu));
  frame.stats.drawables = uint32_t(f.gs.draws().size());
}

}  // namespace tessera
