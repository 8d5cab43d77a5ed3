#include "renderer/ibl_maps.h"

#include <algorithm>
#include <bit>
#include <glm/vec4.hpp>
#include <string>

#include "absl/strings/str_cat.h"
#include "common/status_macros.h"
#include "renderer/vk/vk_check.h"
#include "shaders/common/gpu_types.h"

namespace tessera {

namespace {

constexpr VkFormat kCubeFormat = VK_FORMAT_R16G16B16A16_SFLOAT;
// The split-sum table: RG16F, or RGBA16F (two channels used) where the device has no
// R16G16_SFLOAT storage images, one of Vulkan's optional storage formats (RGBA16F is required).
// RG16F where it can: on lavapipe the shading's lookups of the RGBA16F table cost Sponza's
// visibility shading with IBL 2.7% (71.9 -> 73.9 ms, 8 alternating rounds).
VkFormat LutFormat(const vk::Context& ctx) {
  return ctx.info().storage_rg16f ? VK_FORMAT_R16G16_SFLOAT : VK_FORMAT_R16G16B16A16_SFLOAT;
}
constexpr uint32_t kGroup = 8;  // the compute shaders' local size (x, y)
constexpr float kSpecularSamples = 128.0f;
// The environment level the irradiance integrates over: every texel of a 16x16 face.
constexpr uint32_t kIrradianceSourceLevel = std::countr_zero(kIblEnvSize / 16);

uint32_t Groups(uint32_t n) { return (n + kGroup - 1) / kGroup; }

VkImageMemoryBarrier2 Barrier(const vk::Image& image, VkPipelineStageFlags2 src_stage,
                              VkAccessFlags2 src_access, VkImageLayout from,
                              VkPipelineStageFlags2 dst_stage, VkAccessFlags2 dst_access,
                              VkImageLayout to, uint32_t mip = 0,
                              uint32_t mips = VK_REMAINING_MIP_LEVELS) {
  return vk::MakeImageBarrier(image, {src_stage, src_access, from, dst_stage, dst_access, to},
                              mip, mips);
}

// A map: `size` texels a side, `mips` levels, a cube (six layers) or a 2D image, written by the
// bake's compute shaders and sampled by the shading.
absl::StatusOr<vk::Image> MakeImage(const vk::Context& ctx, uint32_t size, uint32_t mips, bool cube,
                                    VkFormat format, VkImageUsageFlags extra, const char* name) {
  vk::ImageDesc desc;
  desc.format = format;
  desc.width = desc.height = size;
  desc.mip_levels = mips;
  desc.array_layers = cube ? 6 : 1;
  desc.view_type = cube ? VK_IMAGE_VIEW_TYPE_CUBE : VK_IMAGE_VIEW_TYPE_2D;
  desc.usage = VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_SAMPLED_BIT | extra;
  return vk::Image::Create(ctx, desc, name);
}

// Trilinear, clamped: what the shading samples the maps with.
absl::StatusOr<vk::Sampler> MakeSampler(const vk::Context& ctx) {
  VkSamplerCreateInfo si{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
  si.magFilter = si.minFilter = VK_FILTER_LINEAR;
  si.mipmapMode = VK_SAMPLER_MIPMAP_MODE_LINEAR;
  si.addressModeU = si.addressModeV = si.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
  si.maxLod = VK_LOD_CLAMP_NONE;
  return vk::Sampler::Create(ctx, si, "ibl");
}

}  // namespace

IblMaps::~IblMaps() = default;

absl::StatusOr<std::unique_ptr<IblMaps>> IblMaps::Create(const vk::Context& ctx) {
  std::unique_ptr<IblMaps> m(new IblMaps());
  m->device_ = ctx.device();
  const VkDevice d = ctx.device();

  auto image = [&](uint32_t size, uint32_t mips, bool cube, VkFormat format,
                   VkImageUsageFlags extra, const char* name, vk::Image* out) -> absl::Status {
    ASSIGN_OR_RETURN(*out, MakeImage(ctx, size, mips, cube, format, extra, name));
    return absl::OkStatus();
  };
  const uint32_t env_mips = uint32_t(std::bit_width(kIblEnvSize));
  RETURN_IF_ERROR(image(kIblEnvSize, env_mips, true, kCubeFormat,
                        VK_IMAGE_USAGE_TRANSFER_SRC_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT,
                        "ibl_environment", &m->env_));
  RETURN_IF_ERROR(
      image(kIblIrradianceSize, 1, true, kCubeFormat, 0, "ibl_irradiance", &m->irradiance_));
  RETURN_IF_ERROR(image(kIblSpecularSize, kIblSpecularMips, true, kCubeFormat, 0, "ibl_specular",
                        &m->specular_));
  RETURN_IF_ERROR(image(kIblBrdfLutSize, 1, false, LutFormat(ctx), 0, "ibl_brdf", &m->brdf_));

  // Storage views: one mip each, all six faces as an array.
  auto storage_view = [&](const vk::Image& img, VkFormat format, uint32_t mip,
                          bool cube) -> absl::StatusOr<VkImageView> {
    VkImageViewCreateInfo vi{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
    vi.image = img.handle();
    vi.viewType = cube ? VK_IMAGE_VIEW_TYPE_2D_ARRAY : VK_IMAGE_VIEW_TYPE_2D;
    vi.format = format;
    vi.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, mip, 1, 0, cube ? 6u : 1u};
    vk::UniqueImageView view;
    VK_RETURN_IF_ERROR(vkCreateImageView(d, &vi, nullptr, view.Replace(d)), "ibl storage view");
    m->storage_views_.push_back(std::move(view));
    return m->storage_views_.back().get();
  };

  ASSIGN_OR_RETURN(m->sampler_, MakeSampler(ctx));

  const VkDescriptorPoolSize sizes[] = {{VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 16},
                                        {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 16}};
  VkDescriptorPoolCreateInfo dpi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  dpi.maxSets = 16;
  dpi.poolSizeCount = 2;
  dpi.pPoolSizes = sizes;
  VK_RETURN_IF_ERROR(vkCreateDescriptorPool(d, &dpi, nullptr, m->pool_.Replace(d)),
                     "ibl descriptor pool");

  // A program: (sampled env at binding 0 when `reads_env`) + a storage image, push constants.
  auto program = [&](Program* p, const char* shader, bool reads_env,
                     uint32_t push) -> absl::Status {
    std::vector<VkDescriptorSetLayoutBinding> b;
    if (reads_env)
      b.push_back({0, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_COMPUTE_BIT,
                   nullptr});
    b.push_back({reads_env ? 1u : 0u, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1,
                 VK_SHADER_STAGE_COMPUTE_BIT, nullptr});
    RETURN_IF_ERROR(ctx.CreateSetLayout(b, shader, &p->set_layout));
    std::vector<VkPushConstantRange> ranges;
    if (push > 0) ranges.push_back({VK_SHADER_STAGE_COMPUTE_BIT, 0, push});
    RETURN_IF_ERROR(ctx.CreatePipelineLayout({p->set_layout.get()}, ranges, shader, &p->layout));
    ASSIGN_OR_RETURN(p->pipeline, vk::CreateComputePipeline(ctx, shader, shader, p->layout.get()));
    return absl::OkStatus();
  };
  RETURN_IF_ERROR(program(&m->env_program_, "ibl_env.comp", false, sizeof(gpu::IblEnvPush)));
  RETURN_IF_ERROR(program(&m->irradiance_program_, "ibl_irradiance.comp", true,
                          sizeof(gpu::IblIrradiancePush)));
  RETURN_IF_ERROR(
      program(&m->specular_program_, "ibl_specular.comp", true, sizeof(gpu::IblSpecularPush)));
  RETURN_IF_ERROR(program(&m->brdf_program_,
                          ctx.info().storage_rg16f ? "ibl_brdf.comp" : "ibl_brdf_rgba16f.comp",
                          false, 0));

  // The sets never change: write them once.
  auto set = [&](const Program& p, VkImageView out, bool reads_env) -> VkDescriptorSet {
    VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    ai.descriptorPool = m->pool_.get();
    ai.descriptorSetCount = 1;
    const VkDescriptorSetLayout set_layout = p.set_layout.get();
    ai.pSetLayouts = &set_layout;
    VkDescriptorSet s;
    VK_CHECK(vkAllocateDescriptorSets(d, &ai, &s));
    const VkDescriptorImageInfo env{m->sampler_.handle(), m->env_.view(),
                                    VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    const VkDescriptorImageInfo dst{VK_NULL_HANDLE, out, VK_IMAGE_LAYOUT_GENERAL};
    VkWriteDescriptorSet w[2] = {{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET},
                                 {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET}};
    uint32_t n = 0;
    if (reads_env) {
      w[n].dstSet = s;
      w[n].dstBinding = 0;
      w[n].descriptorCount = 1;
      w[n].descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
      w[n].pImageInfo = &env;
      ++n;
    }
    w[n].dstSet = s;
    w[n].dstBinding = reads_env ? 1 : 0;
    w[n].descriptorCount = 1;
    w[n].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE;
    w[n].pImageInfo = &dst;
    ++n;
    vkUpdateDescriptorSets(d, n, w, 0, nullptr);
    return s;
  };
  absl::StatusOr<VkImageView> v = storage_view(m->env_, kCubeFormat, 0, true);
  if (!v.ok()) return v.status();
  m->env_set_ = set(m->env_program_, *v, false);
  v = storage_view(m->irradiance_, kCubeFormat, 0, true);
  if (!v.ok()) return v.status();
  m->irradiance_set_ = set(m->irradiance_program_, *v, true);
  for (uint32_t mip = 0; mip < kIblSpecularMips; ++mip) {
    v = storage_view(m->specular_, kCubeFormat, mip, true);
    if (!v.ok()) return v.status();
    m->specular_sets_.push_back(set(m->specular_program_, *v, true));
  }
  v = storage_view(m->brdf_, LutFormat(ctx), 0, false);
  if (!v.ok()) return v.status();
  m->brdf_set_ = set(m->brdf_program_, *v, false);
  return m;
}

void IblMaps::RecordBake(VkCommandBuffer cmd, const SkyParams& sky) {
  constexpr VkPipelineStageFlags2 kCompute = VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;
  constexpr VkPipelineStageFlags2 kFragment = VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT;
  constexpr VkPipelineStageFlags2 kBlit = VK_PIPELINE_STAGE_2_BLIT_BIT;
  constexpr VkAccessFlags2 kWrite = VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT;
  constexpr VkAccessFlags2 kSampled = VK_ACCESS_2_SHADER_SAMPLED_READ_BIT;
  constexpr VkImageLayout kGeneral = VK_IMAGE_LAYOUT_GENERAL;
  constexpr VkImageLayout kRead = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
  auto bind = [&](const Program& p, VkDescriptorSet set) {
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, p.pipeline.handle());
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, p.layout.get(), 0, 1, &set, 0,
                            nullptr);
  };

  // The sun is a directional light the shading already adds: the maps the lighting reads are
  // baked from the sky without it (else diffuse gets it twice and mirrors show two suns). The
  // background (level 0) gets the sky with its glow and disc at the end.
  auto sky_pass = [&](const SkyParams& p) {
    const gpu::IblEnvPush push{glm::vec4(p.sun_dir, 0.0f), glm::vec4(p.sun_color, 0.0f),
                               glm::vec4(p.zenith, 0.0f),  glm::vec4(p.horizon, 0.0f),
                               glm::vec4(p.ground, 0.0f),  glm::uvec4(kIblEnvSize, 0u, 0u, 0u)};
    bind(env_program_, env_set_);
    vkCmdPushConstants(cmd, env_program_.layout.get(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push),
                       &push);
    vkCmdDispatch(cmd, Groups(kIblEnvSize), Groups(kIblEnvSize), 6);
  };
  SkyParams no_sun = sky;
  no_sun.sun_color = glm::vec3(0.0f);
  // 1. The sky into the environment's level 0 (the old contents are not needed).
  {
    VkImageMemoryBarrier2 b[3] = {
        Barrier(env_, kFragment, VK_ACCESS_2_NONE, VK_IMAGE_LAYOUT_UNDEFINED, kCompute, kWrite,
                kGeneral, 0, 1),
        Barrier(irradiance_, kFragment, VK_ACCESS_2_NONE, VK_IMAGE_LAYOUT_UNDEFINED, kCompute,
                kWrite, kGeneral),
        Barrier(specular_, kFragment, VK_ACCESS_2_NONE, VK_IMAGE_LAYOUT_UNDEFINED, kCompute,
                kWrite, kGeneral)};
    vk::CmdBarrier(cmd, b, 3);
    sky_pass(no_sun);
  }
  // 2. Its mip chain by bilinear blits (box filter), level by level.
  const uint32_t env_mips = env_.desc().mip_levels;
  {
    VkImageMemoryBarrier2 b[2] = {
        Barrier(env_, kCompute, kWrite, kGeneral, kBlit, VK_ACCESS_2_TRANSFER_READ_BIT,
                VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, 0, 1),
        Barrier(env_, kFragment, VK_ACCESS_2_NONE, VK_IMAGE_LAYOUT_UNDEFINED, kBlit,
                VK_ACCESS_2_TRANSFER_WRITE_BIT, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1,
                env_mips - 1)};
    vk::CmdBarrier(cmd, b, 2);
  }
  for (uint32_t mip = 1; mip < env_mips; ++mip) {
    const int32_t src = int32_t(kIblEnvSize >> (mip - 1)), dst = int32_t(kIblEnvSize >> mip);
    VkImageBlit blit{};
    blit.srcSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, mip - 1, 0, 6};
    blit.srcOffsets[1] = {src, src, 1};
    blit.dstSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, mip, 0, 6};
    blit.dstOffsets[1] = {dst, dst, 1};
    vkCmdBlitImage(cmd, env_.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, env_.handle(),
                   VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &blit, VK_FILTER_LINEAR);
    VkImageMemoryBarrier2 b = Barrier(env_, kBlit, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                                      VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, kBlit,
                                      VK_ACCESS_2_TRANSFER_READ_BIT,
                                      VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, mip, 1);
    vk::CmdBarrier(cmd, &b, 1);
  }
  {
    VkImageMemoryBarrier2 b = Barrier(env_, kBlit, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                                      VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, kCompute | kFragment,
                                      kSampled, kRead);
    vk::CmdBarrier(cmd, &b, 1);
  }
  // 3. Diffuse irradiance: every texel of a 16x16-face level, cosine-weighted.
  {
    const gpu::IblIrradiancePush push{glm::uvec4(kIblIrradianceSize, kIrradianceSourceLevel,
                                                 kIblEnvSize >> kIrradianceSourceLevel, 0u)};
    bind(irradiance_program_, irradiance_set_);
    vkCmdPushConstants(cmd, irradiance_program_.layout.get(), VK_SHADER_STAGE_COMPUTE_BIT, 0,
                       sizeof(push), &push);
    vkCmdDispatch(cmd, Groups(kIblIrradianceSize), Groups(kIblIrradianceSize), 6);
  }
  // 4. The specular chain: mip m filtered for roughness m / (mips - 1).
  for (uint32_t mip = 0; mip < kIblSpecularMips; ++mip) {
    const uint32_t size = std::max(1u, kIblSpecularSize >> mip);
    const gpu::IblSpecularPush push{
        glm::vec4(float(mip) / float(kIblSpecularMips - 1), float(kIblEnvSize), float(env_mips),
                  kSpecularSamples),
        glm::uvec4(size, 0u, 0u, 0u)};
    bind(specular_program_, specular_sets_[mip]);
    vkCmdPushConstants(cmd, specular_program_.layout.get(), VK_SHADER_STAGE_COMPUTE_BIT, 0,
                       sizeof(push), &push);
    vkCmdDispatch(cmd, Groups(size), Groups(size), 6);
  }
  // 5. The BRDF table depends on nothing: once.
  if (!brdf_baked_) {
    VkImageMemoryBarrier2 b = Barrier(brdf_, kFragment, VK_ACCESS_2_NONE,
                                      VK_IMAGE_LAYOUT_UNDEFINED, kCompute, kWrite, kGeneral);
    vk::CmdBarrier(cmd, &b, 1);
    bind(brdf_program_, brdf_set_);
    vkCmdDispatch(cmd, Groups(kIblBrdfLutSize), Groups(kIblBrdfLutSize), 1);
    b = Barrier(brdf_, kCompute, kWrite, kGeneral, kFragment, kSampled, kRead);
    vk::CmdBarrier(cmd, &b, 1);
    brdf_baked_ = true;
  }
  // 6. The background: level 0 again, with the sun (after the prefilters' reads of it).
  {
    VkImageMemoryBarrier2 b = Barrier(env_, kCompute | kFragment, VK_ACCESS_2_NONE, kRead,
                                      kCompute, kWrite, kGeneral, 0, 1);
    vk::CmdBarrier(cmd, &b, 1);
    sky_pass(sky);
    b = Barrier(env_, kCompute, kWrite, kGeneral, kFragment, kSampled, kRead, 0, 1);
    vk::CmdBarrier(cmd, &b, 1);
  }
  VkImageMemoryBarrier2 b[2] = {
      Barrier(irradiance_, kCompute, kWrite, kGeneral, kFragment, kSampled, kRead),
      Barrier(specular_, kCompute, kWrite, kGeneral, kFragment, kSampled, kRead)};
  vk::CmdBarrier(cmd, b, 2);
  baked_ = true;
}

}  // namespace tessera
