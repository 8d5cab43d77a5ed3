#pragma once
// The format features Tessera needs of a device beyond what Vulkan requires of every device (or
// that it relies on having, required or not), checked when the device is made: a device without
// one is refused naming the format, the feature and what uses it.
#include <vulkan/vulkan.h>

#include <functional>
#include <string>
#include <vector>

namespace tessera::vk {

struct FormatNeed {
  VkFormat format;
  const char* format_name;  // "D32_SFLOAT"
  bool buffer;              // bufferFeatures, else optimalTilingFeatures
  VkFormatFeatureFlags features;
  const char* features_name;  // "depth attachment and sampled image"
  const char* use;            // "every depth buffer"
};

// Every need, in a fixed order.
const std::vector<FormatNeed>& FormatNeeds();

// The needs `properties` (a format's properties on the device) does not meet, each as
// "<format> <features> (<use>)".
std::vector<std::string> MissingFormatFeatures(
    const std::function<VkFormatProperties(VkFormat)>& properties);

}  // namespace tessera::vk
