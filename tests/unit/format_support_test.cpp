// vk::MissingFormatFeatures: the format features Tessera relies on, checked when a device is
// made, with a fake device's format properties.
#include "renderer/vk/format_support.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace tessera::vk {
namespace {

// Every feature of every format, except `lacking`'s `features` (in `buffer` or optimal tiling).
std::function<VkFormatProperties(VkFormat)> DeviceLacking(VkFormat lacking, bool buffer,
                                                          VkFormatFeatureFlags features) {
  return [=](VkFormat format) {
    VkFormatProperties p{~0u, ~0u, ~0u};
    if (format == lacking) (buffer ? p.bufferFeatures : p.optimalTilingFeatures) &= ~features;
    return p;
  };
}

TEST(FormatSupport, ADeviceWithEveryFeatureLacksNothing) {
  EXPECT_TRUE(MissingFormatFeatures(DeviceLacking(VK_FORMAT_UNDEFINED, false, 0)).empty());
  // Features elsewhere (linear tiling, another format) do not count.
  EXPECT_TRUE(MissingFormatFeatures(DeviceLacking(VK_FORMAT_R16G16_SFLOAT, false, ~0u)).empty());
}

TEST(FormatSupport, EachMissingFeatureIsNamedWithItsUse) {
  EXPECT_EQ(MissingFormatFeatures(
                DeviceLacking(VK_FORMAT_D32_SFLOAT, false, VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT)),
            std::vector<std::string>{
                "D32_SFLOAT depth attachments and sampled images (every depth buffer)"});
  EXPECT_EQ(MissingFormatFeatures(DeviceLacking(VK_FORMAT_D32_SFLOAT, false,
                                                VK_FORMAT_FEATURE_DEPTH_STENCIL_ATTACHMENT_BIT))
                .size(),
            1u);
  // Texel buffers are buffer features: the same bit in optimal tiling does not stand in.
  EXPECT_EQ(MissingFormatFeatures(DeviceLacking(VK_FORMAT_R32G32_UINT, true,
                                                VK_FORMAT_FEATURE_UNIFORM_TEXEL_BUFFER_BIT)),
            std::vector<std::string>{"R32G32_UINT uniform texel buffers (the scene's and the "
                                     "lights' texel views)"});
  EXPECT_TRUE(MissingFormatFeatures(DeviceLacking(VK_FORMAT_R32G32_UINT, false,
                                                  VK_FORMAT_FEATURE_UNIFORM_TEXEL_BUFFER_BIT))
                  .empty());
  // Every need is one the table names.
  for (const FormatNeed& n : FormatNeeds()) {
    const std::vector<std::string> m =
        MissingFormatFeatures(DeviceLacking(n.format, n.buffer, n.features));
    ASSERT_EQ(m.size(), 1u) << n.format_name;
    EXPECT_EQ(m[0].rfind(n.format_name, 0), 0u) << m[0];
  }
}

}  // namespace
}  // namespace tessera::vk
