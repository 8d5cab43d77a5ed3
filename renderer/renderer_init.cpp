// The renderer's one-time setup: the scene layouts, every pass, the executor, the frame's
// descriptor pool and uniform buffers, and the stand-ins bound while an effect is off.
#include <cstring>

#include "common/status_macros.h"
#include "renderer/log.h"
#include "renderer/renderer_impl.h"
#include "renderer/vk/descriptor_limits.h"
#include "renderer/vk/vk_check.h"

namespace tessera {

absl::Status Renderer::Impl::InitLayouts() {
  // The scene's sets are read by fragment shaders and by the visibility pipeline's compute
  // shading (features/vis_shade.cpp).
  constexpr VkShaderStageFlags kPixel = VK_SHADER_STAGE_FRAGMENT_BIT | VK_SHADER_STAGE_COMPUTE_BIT;
  constexpr VkShaderStageFlags kVertexPixel = VK_SHADER_STAGE_VERTEX_BIT | kPixel;
  constexpr VkDescriptorType kUniform = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
  constexpr VkDescriptorType kBuffer = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  constexpr VkDescriptorType kSampled = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
  constexpr VkDescriptorType kTexels = VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;
  std::vector<VkDescriptorSetLayoutBinding> bindings = {
      LayoutBinding(gpu::kBindingFrame, kUniform, kVertexPixel),
      LayoutBinding(gpu::kBindingLights, kUniform, kPixel),
      LayoutBinding(gpu::kBindingDrawables, kBuffer, kVertexPixel),
      LayoutBinding(gpu::kBindingMaterials, kBuffer, kVertexPixel),
      LayoutBinding(gpu::kBindingLocalLights, kBuffer, kPixel),
      LayoutBinding(gpu::kBindingTileCounts, kBuffer, kPixel),
      LayoutBinding(gpu::kBindingTileLights, kBuffer, kPixel),
      LayoutBinding(gpu::kBindingShadows, kUniform, kPixel),
      LayoutBinding(gpu::kBindingShadowAtlas, kSampled, kPixel),
      LayoutBinding(gpu::kBindingAo, kSampled, kPixel),
      LayoutBinding(gpu::kBindingIrradiance, kSampled, kPixel),
      LayoutBinding(gpu::kBindingSpecular, kSampled, kPixel),
      LayoutBinding(gpu::kBindingBrdfLut, kSampled, kPixel),
      LayoutBinding(gpu::kBindingEnvironment, kSampled, kPixel),
      LayoutBinding(gpu::kBindingLocalLightTexels, kTexels, kPixel),
      LayoutBinding(gpu::kBindingTileLightTexels, kTexels, kPixel),
  };
  RETURN_IF_ERROR(ctx->CreateSetLayout(bindings, "scene set layout", &scene_set_layout));
  std::vector<VkDescriptorSetLayoutBinding> texture_bindings = {
      LayoutBinding(gpu::kBindingMaterialUniform, kUniform, kPixel)};
  for (uint32_t k = 0; k < gpu::kMaterialTextureSlots; ++k)
    texture_bindings.push_back(LayoutBinding(gpu::kBindingBaseColorTex + k, kSampled, kPixel));
  RETURN_IF_ERROR(
      ctx->CreateSetLayout(texture_bindings, "material set layout", &material_set_layout));
  // The bucket set (gpu::kBindingBuckets): every texture bucket, for the visibility shading of
  // devices that index sampler arrays.
  VkDescriptorSetLayoutBinding buckets =
      LayoutBinding(gpu::kBindingBuckets, kSampled, VK_SHADER_STAGE_COMPUTE_BIT);
  buckets.descriptorCount = gpu::kMaxTextureBuckets;
  RETURN_IF_ERROR(ctx->CreateSetLayout({buckets}, "bucket set layout", &bucket_set_layout));
  RETURN_IF_ERROR(ctx->CreatePipelineLayout({scene_set_layout.get(), material_set_layout.get()}, {},
                                            "scene pipeline layout", &scene_pipeline_layout));
  scene_layout = {scene_set_layout.get(), material_set_layout.get(), scene_pipeline_layout.get(),
                  bucket_set_layout.get()};
  return absl::OkStatus();
}

absl::Status Renderer::Impl::InitPasses() {

  auto add = [this](absl::StatusOr<std::unique_ptr<Pass>> pass) -> absl::Status {
    if (!pass.ok()) return pass.status();
    passes[static_cast<size_t>((*pass)->id())] = std::move(*pass);
    return absl::OkStatus();
  };
  RETURN_IF_ERROR(add(CreateDepthPrepass(*ctx, scene_layout)));
  RETURN_IF_ERROR(add(CreateDepthPrepass(*ctx, scene_layout, PassId::kDepthPrepassLate)));
  RETURN_IF_ERROR(add(CreateCullPass(*ctx, PassId::kCull)));
  RETURN_IF_ERROR(add(CreateCullPass(*ctx, PassId::kCullLate)));
  RETURN_IF_ERROR(add(CreateHizBuildPass(*ctx)));
  RETURN_IF_ERROR(add(CreateForwardPass(*ctx, scene_layout)));
  RETURN_IF_ERROR(add(CreateTransparentPass(*ctx, scene_layout)));
  RETURN_IF_ERROR(add(CreateTonemapPass(*ctx)));
  RETURN_IF_ERROR(add(CreateLightCullPass(*ctx)));
  RETURN_IF_ERROR(add(CreateReadbackPass()));
  // The visibility pipeline's passes. Where a layout of theirs exceeds the device's descriptor
  // limits (the forward passes' fit: they were made above), the device renders without them,
  // as one that lacks the visibility buffer's features: pipeline visibility renders forward and
  // vis_mlaa msaa, and DeviceInfo::fallbacks says why.
  absl::Status one_dispatch;  // the one-dispatch shading's layouts do not fit (CreateShadePass)
  const absl::Status visibility = [&]() -> absl::Status {
    RETURN_IF_ERROR(add(CreateVisibilityPass(*ctx, scene_layout, PassId::kVisibility)));
    RETURN_IF_ERROR(add(CreateVisibilityPass(*ctx, scene_layout, PassId::kVisibilityLate)));
    RETURN_IF_ERROR(add(CreateVisResolvePass(*ctx, scene_layout)));
    RETURN_IF_ERROR(add(CreateVisClassifyPass(*ctx, scene_layout)));
    RETURN_IF_ERROR(add(CreateShadePass(*ctx, scene_layout, &one_dispatch)));
    return add(CreateGeometricAaPass(*ctx));
  }();
  if (vk::IsDescriptorLimitError(visibility)) {
    for (PassId id : {PassId::kVisibility, PassId::kVisibilityLate, PassId::kVisResolve,
                      PassId::kVisClassify, PassId::kShade, PassId::kGeometricAa}) {
      passes[static_cast<size_t>(id)].reset();
    }
    ctx->DisableVisibilityBuffer(std::string(visibility.message()));
  } else {
    RETURN_IF_ERROR(visibility);
    // The one-dispatch shading's layouts (with the bucket set) are the largest: without room
    // for them the shading runs per material, whose layouts were made.
    if (!one_dispatch.ok()) ctx->DisableShadeAllMaterials(std::string(one_dispatch.message()));
  }
  RETURN_IF_ERROR(add(CreateTaaPass(*ctx)));
  RETURN_IF_ERROR(add(CreateMotionPass(*ctx, scene_layout)));
  RETURN_IF_ERROR(add(CreateFxaaPass(*ctx)));
  RETURN_IF_ERROR(add(CreateShadowPass(*ctx, scene_layout)));
  RETURN_IF_ERROR(add(CreateSsaoPass(*ctx)));
  RETURN_IF_ERROR(add(CreateExposurePass(*ctx)));
  RETURN_IF_ERROR(add(CreateBloomPass(*ctx)));
  RETURN_IF_ERROR(add(CreateSkinningPass(*ctx)));

  return absl::OkStatus();
}

absl::Status Renderer::Impl::Init() {
  const VkDevice d = ctx->device();
  RETURN_IF_ERROR(InitLayouts());
  RETURN_IF_ERROR(InitPasses());
  ASSIGN_OR_RETURN(executor, GraphExecutor::Create(*ctx));
  // Per frame: the scene set, light culling, two culling phases, a set per pyramid level, the
  // vis_mlaa and post passes' sets.
  // Shadows, ssao, ibl: six more images and a uniform buffer in the scene set; the post passes
  // allocate a set per draw (bloom: eleven). Storage buffers, at most 52 in a frame: the scene
  // set 5, skinning 5, the two culling phases 8 each, light culling 5, vis_mlaa's resolve 6,
  // classification 5, shading 6 and geometric AA 4, and the motion pass 1 (taa, so not with
  // vis_mlaa); 64 leaves room. Texel buffers: 2 in the scene set, 3 in each of the resolve's,
  // the classification's and the shading's sets.
  const VkDescriptorPoolSize sizes[] = {
      {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 12},
      {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 64},
      {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 192},
      {VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 48},
      {VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, 24},
  };
  VkDescriptorPoolCreateInfo dpi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  dpi.maxSets = 128;
  dpi.poolSizeCount = 5;
  dpi.pPoolSizes = sizes;
  VK_RETURN_IF_ERROR(vkCreateDescriptorPool(d, &dpi, nullptr, frame_pool.Replace(d)),
                     "descriptor pool");

  RETURN_IF_ERROR(MakeBuffer(*ctx, sizeof(gpu::FrameUniforms), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT,
                             vk::MemoryUsage::kDynamic, "frame_uniforms", &frame_ubo));
  RETURN_IF_ERROR(MakeBuffer(*ctx, sizeof(gpu::GpuLight) * gpu::kMaxLights,
                             VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, vk::MemoryUsage::kDynamic,
                             "lights", &lights_ubo));
  // Zeroed once: the shading reads light 0 for the sun block even in frames without global
  // lights (its result dropped), and a zero light has no shadow map to look up.
  std::memset(lights_ubo.mapped(), 0, sizeof(gpu::GpuLight) * gpu::kMaxLights);
  RETURN_IF_ERROR(EnsureRowBuffer(1024));
  Log().info("per-frame buffers (uniforms, lights, light lists) in {} memory",
             (frame_ubo.memory_flags() & VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT) ? "device-local"
                                                                              : "system");
  // A storage buffer, not a uniform one: on lavapipe (Mesa 22.3) every dispatch of the cull
  // shader that read its view-projection matrix from a uniform buffer left about 1 MB of mapped
  // memory behind (README, Soak); read from a storage buffer, nothing grows.
  const VkDeviceSize align =
      std::max<VkDeviceSize>(16, ctx->limits().minStorageBufferOffsetAlignment);
  cull_uniform_stride = (sizeof(gpu::CullUniforms) + align - 1) / align * align;
  RETURN_IF_ERROR(MakeBuffer(*ctx, 2 * cull_uniform_stride, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                  vk::MemoryUsage::kDynamic, "cull_uniforms", &cull_uniforms));
  RETURN_IF_ERROR(MakeBuffer(*ctx, 4,
                                  VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                      VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                  vk::MemoryUsage::kUpload, "no_visibility", &no_visibility));
  std::memset(no_visibility.mapped(), 0, 4);
  RETURN_IF_ERROR(EnsureCullBuffers(1, 1));
  RETURN_IF_ERROR(InitShadows());
  return EnsureLightBuffers(1, 1);
}

absl::Status Renderer::Impl::InitShadows() {
  RETURN_IF_ERROR(MakeBuffer(*ctx, sizeof(gpu::ShadowUniforms),
                                  VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, vk::MemoryUsage::kDynamic,
                                  "shadow_uniforms", &shadow_ubo));
  std::memset(shadow_ubo.mapped(), 0, sizeof(gpu::ShadowUniforms));
  // The hardware shadow sampler: bilinear comparison taps (the PCF's 4 taps each weigh 2x2
  // texels). Standard Z: lit where the reference is nearer than (or at) the stored depth.
  VkSamplerCreateInfo si{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
  si.magFilter = si.minFilter = VK_FILTER_LINEAR;
  si.addressModeU = si.addressModeV = si.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
  si.compareEnable = VK_TRUE;
  si.compareOp = VK_COMPARE_OP_LESS_OR_EQUAL;
  ASSIGN_OR_RETURN(shadow_sampler, vk::Sampler::Create(*ctx, si, "shadow_compare"));
  ASSIGN_OR_RETURN(linear_sampler, CreateClampSampler(*ctx, true, "ao_linear"));
  // What the scene set binds while shadows are off: a 1x1 atlas in shader-read layout.
  vk::ImageDesc desc;
  desc.format = kShadowFormat;
  desc.usage = VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT;
  ASSIGN_OR_RETURN(shadow_placeholder, vk::Image::Create(*ctx, desc, "shadow_placeholder"));
  // And without ssao, a 1x1 AO image (its contents are never read: the shaders test a flag).
  desc.format = kAoFormat;
  desc.usage = VK_IMAGE_USAGE_SAMPLED_BIT;
  ASSIGN_OR_RETURN(ao_placeholder, vk::Image::Create(*ctx, desc, "ao_placeholder"));
  // And without ibl, a 1x1 cube (never read either).
  desc.format = VK_FORMAT_R16G16B16A16_SFLOAT;
  desc.array_layers = 6;
  desc.view_type = VK_IMAGE_VIEW_TYPE_CUBE;
  ASSIGN_OR_RETURN(cube_placeholder, vk::Image::Create(*ctx, desc, "cube_placeholder"));
  executor->BeginOneTime();
  VkImageMemoryBarrier2 b[3];
  for (int i = 0; i < 3; ++i) {
    b[i] = vk::MakeImageBarrier(
        i == 0 ? shadow_placeholder : i == 1 ? ao_placeholder : cube_placeholder,
        {VK_PIPELINE_STAGE_2_NONE, VK_ACCESS_2_NONE, VK_IMAGE_LAYOUT_UNDEFINED,
         VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT, VK_ACCESS_2_SHADER_SAMPLED_READ_BIT,
         VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL});
  }
  vk::CmdBarrier(executor->cmd(), b, 3);
  return executor->SubmitAndWait(/*host_read=*/false);
}


}  // namespace tessera
