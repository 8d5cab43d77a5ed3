#pragma once
// Image-based lighting on the device: a procedural sky (renderer/ibl.h's SkyParams) baked into
// an environment cube, prefiltered once per sky into a diffuse irradiance cube and a specular
// mip chain (GGX, one roughness per mip), plus the split-sum BRDF lookup table (made once).
// The shading passes sample the three (set 0, kBindingIrradiance / kBindingSpecular /
// kBindingBrdfLut) and the sky pass the environment's level 0 (kBindingEnvironment). The sun is
// in the background only: the lighting maps are baked without it (it is a directional light).
#include <vulkan/vulkan.h>

#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "renderer/ibl.h"
#include "renderer/vk/context.h"
#include "renderer/vk/pipeline.h"
#include "renderer/vk/resources.h"

namespace tessera {

// Sizes: the environment's face (and its full mip chain), the irradiance cube's face, the
// specular cube's face and its mips (roughness m / (kIblSpecularMips - 1) at mip m).
inline constexpr uint32_t kIblEnvSize = 128;
inline constexpr uint32_t kIblIrradianceSize = 16;
inline constexpr uint32_t kIblSpecularSize = 64;
inline constexpr uint32_t kIblSpecularMips = 6;

class IblMaps {
 public:
  static absl::StatusOr<std::unique_ptr<IblMaps>> Create(const vk::Context& ctx);
  ~IblMaps();
  IblMaps(const IblMaps&) = delete;
  IblMaps& operator=(const IblMaps&) = delete;

  // Records the bake of `sky` into `cmd` (and of the BRDF table on the first bake). Before it
  // the maps may be in use by an earlier frame's commands that have completed; after it all four
  // are in the shader-read layout, visible to fragment shaders.
  void RecordBake(VkCommandBuffer cmd, const SkyParams& sky);
  bool baked() const { return baked_; }

  const vk::Image& environment() const { return env_; }
  const vk::Image& irradiance() const { return irradiance_; }
  const vk::Image& specular() const { return specular_; }
  const vk::Image& brdf_lut() const { return brdf_; }
  VkSampler sampler() const { return sampler_.handle(); }  // trilinear, clamp to edge

 private:
  IblMaps() = default;
  VkDevice device_ = VK_NULL_HANDLE;
  vk::Image env_, irradiance_, specular_, brdf_;
  std::vector<vk::UniqueImageView> storage_views_;  // 2D-array views of single mips
  vk::UniqueDescriptorPool pool_;
  struct Program {
    vk::UniqueDescriptorSetLayout set_layout;
    vk::UniquePipelineLayout layout;
    vk::Pipeline pipeline;
  };
  Program env_program_, irradiance_program_, specular_program_, brdf_program_;
  VkDescriptorSet env_set_ = VK_NULL_HANDLE, irradiance_set_ = VK_NULL_HANDLE,
                  brdf_set_ = VK_NULL_HANDLE;
  std::vector<VkDescriptorSet> specular_sets_;  // one per mip
  vk::Sampler sampler_;
  bool baked_ = false;
  bool brdf_baked_ = false;
};

}  // namespace tessera
