#include "renderer/vk/format_support.h"

#include "absl/strings/str_cat.h"

namespace tessera::vk {

const std::vector<FormatNeed>& FormatNeeds() {
  constexpr VkFormatFeatureFlags kTexels = VK_FORMAT_FEATURE_UNIFORM_TEXEL_BUFFER_BIT;
  constexpr VkFormatFeatureFlags kDepth =
      VK_FORMAT_FEATURE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT;
  static const std::vector<FormatNeed> needs = {
      // Vulkan requires these of every device; the visibility passes and the scene set bind
      // buffers as texel buffers of them (the shaders hold both paths on every device).
      {VK_FORMAT_R32_UINT, "R32_UINT", true, kTexels, "uniform texel buffers",
       "the scene's and the lights' texel views"},
      {VK_FORMAT_R32G32_UINT, "R32G32_UINT", true, kTexels, "uniform texel buffers",
       "the scene's and the lights' texel views"},
      {VK_FORMAT_R32G32B32A32_UINT, "R32G32B32A32_UINT", true, kTexels, "uniform texel buffers",
       "the scene's and the lights' texel views"},
      // Not required (a device must have it or X8_D24_UNORM_PACK32): every depth buffer, which
      // the depth pyramid, SSAO and the visibility resolve sample.
      {VK_FORMAT_D32_SFLOAT, "D32_SFLOAT", false, kDepth, "depth attachments and sampled images",
       "every depth buffer"},
  };
  return needs;
}

std::vector<std::string> MissingFormatFeatures(
    const std::function<VkFormatProperties(VkFormat)>& properties) {
  std::vector<std::string> missing;
  for (const FormatNeed& n : FormatNeeds()) {
    const VkFormatProperties p = properties(n.format);
    const VkFormatFeatureFlags have = n.buffer ? p.bufferFeatures : p.optimalTilingFeatures;
    if ((have & n.features) != n.features)
      missing.push_back(absl::StrCat(n.format_name, " ", n.features_name, " (", n.use, ")"));
  }
  return missing;
}

}  // namespace tessera::vk
