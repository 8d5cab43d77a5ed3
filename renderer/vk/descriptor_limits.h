#pragma once
// What a pipeline layout's descriptors take of a device's limits: per shader stage (the
// maxPerStageDescriptor* limits and maxPerStageResources) and for the whole layout (the
// maxDescriptorSet* limits, maxBoundDescriptorSets, maxPushConstantsSize). Vulkan guarantees
// only small minimums (16 sampled images and 4 storage buffers in a stage), so a layout is
// checked against the device's own before it is created.
#include <vulkan/vulkan.h>

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"

namespace tessera::vk {

// The descriptors a stage (or a whole layout) reads, in the categories the limits count.
struct DescriptorCounts {
  uint32_t samplers = 0;         // SAMPLER, COMBINED_IMAGE_SAMPLER
  uint32_t uniform_buffers = 0;  // UNIFORM_BUFFER(_DYNAMIC)
  uint32_t storage_buffers = 0;  // STORAGE_BUFFER(_DYNAMIC)
  uint32_t sampled_images = 0;   // SAMPLED_IMAGE, COMBINED_IMAGE_SAMPLER, UNIFORM_TEXEL_BUFFER
  uint32_t storage_images = 0;   // STORAGE_IMAGE, STORAGE_TEXEL_BUFFER
  uint32_t input_attachments = 0;
  uint32_t uniform_buffers_dynamic = 0;  // also in uniform_buffers
  uint32_t storage_buffers_dynamic = 0;  // also in storage_buffers
  uint32_t uncounted = 0;  // of types the limits here do not cover (refused: see the .cpp)
  // What maxPerStageResources counts (a combined image sampler once; a fragment shader's colour
  // attachments, which a pipeline layout does not know, are not included).
  uint32_t Resources() const;
  DescriptorCounts& operator+=(const DescriptorCounts& o);
};

// What `bindings` hold for `stages` (any of them: every binding visible to one of the stages;
// pass one stage bit to count that stage).
DescriptorCounts CountDescriptors(const std::vector<VkDescriptorSetLayoutBinding>& bindings,
                                  VkShaderStageFlags stages);

// OK when a pipeline layout of the sets `sets` (each its bindings) and `push_bytes` of push
// constants fits `limits`; else FAILED_PRECONDITION naming `name`, the stage, the count and the
// limit, e.g. "vis_shade layout: 20 sampled images in the compute stage exceed the device's
// maxPerStageDescriptorSampledImages (16)". Layouts with flags (update-after-bind, push
// descriptors) have other limits and are not made through it (Context::CreateSetLayout takes
// none); a descriptor type it does not count (inline uniform blocks, acceleration structures)
// is INTERNAL, so that a new use cannot pass unchecked.
absl::Status CheckDescriptorLimits(
    const VkPhysicalDeviceLimits& limits,
    const std::vector<std::vector<VkDescriptorSetLayoutBinding>>& sets, uint32_t push_bytes,
    const std::string& name);

// Whether `status` is CheckDescriptorLimits' refusal (it carries a payload saying so).
bool IsDescriptorLimitError(const absl::Status& status);

// `limits` with every limit CheckDescriptorLimits reads lowered to Vulkan's minimum (the spec's
// "Required Limits" table).
VkPhysicalDeviceLimits MinimumDescriptorLimits(VkPhysicalDeviceLimits limits);

// Lowers the limit CheckDescriptorLimits reads named `name` (as the spec spells it, e.g.
// "maxPerStageDescriptorStorageBuffers") to at most `cap`, so that a device with smaller limits
// can be imitated; INVALID_ARGUMENT naming the known limits for another name.
absl::Status CapDescriptorLimit(VkPhysicalDeviceLimits& limits, const std::string& name,
                                uint32_t cap);

}  // namespace tessera::vk
