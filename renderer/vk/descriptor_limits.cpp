#include "renderer/vk/descriptor_limits.h"

#include <algorithm>
#include <utility>

#include "absl/strings/cord.h"
#include "absl/strings/str_cat.h"

namespace tessera::vk {

uint32_t DescriptorCounts::Resources() const {
  // A combined image sampler counts in samplers and sampled images but is one resource.
  return sampled_images + uniform_buffers + storage_buffers + storage_images + input_attachments;
}

DescriptorCounts& DescriptorCounts::operator+=(const DescriptorCounts& o) {
  samplers += o.samplers;
  uniform_buffers += o.uniform_buffers;
  storage_buffers += o.storage_buffers;
  sampled_images += o.sampled_images;
  storage_images += o.storage_images;
  input_attachments += o.input_attachments;
  uniform_buffers_dynamic += o.uniform_buffers_dynamic;
  storage_buffers_dynamic += o.storage_buffers_dynamic;
  uncounted += o.uncounted;
  return *this;
}

DescriptorCounts CountDescriptors(const std::vector<VkDescriptorSetLayoutBinding>& bindings,
                                  VkShaderStageFlags stages) {
  DescriptorCounts c;
  for (const VkDescriptorSetLayoutBinding& b : bindings) {
    if ((b.stageFlags & stages) == 0) continue;
    const uint32_t n = b.descriptorCount;
    switch (b.descriptorType) {
      case VK_DESCRIPTOR_TYPE_SAMPLER:
        c.samplers += n;
        break;
      case VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER:
        c.samplers += n;
        c.sampled_images += n;
        break;
      case VK_DESCRIPTOR_TYPE_SAMPLED_IMAGE:
      case VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER:
        c.sampled_images += n;
        break;
      case VK_DESCRIPTOR_TYPE_STORAGE_IMAGE:
      case VK_DESCRIPTOR_TYPE_STORAGE_TEXEL_BUFFER:
        c.storage_images += n;
        break;
      case VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER_DYNAMIC:
        c.uniform_buffers_dynamic += n;
        [[fallthrough]];
      case VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER:
        c.uniform_buffers += n;
        break;
      case VK_DESCRIPTOR_TYPE_STORAGE_BUFFER_DYNAMIC:
        c.storage_buffers_dynamic += n;
        [[fallthrough]];
      case VK_DESCRIPTOR_TYPE_STORAGE_BUFFER:
        c.storage_buffers += n;
        break;
      case VK_DESCRIPTOR_TYPE_INPUT_ATTACHMENT:
        c.input_attachments += n;
        break;
      default:
        c.uncounted += n;
        break;  // none the renderer uses
    }
  }
  return c;
}

namespace {

struct Limit {
  const char* what;
  uint32_t DescriptorCounts::*count;
  uint32_t VkPhysicalDeviceLimits::*per_stage;  // null: a limit of the layout only
  uint32_t VkPhysicalDeviceLimits::*per_layout;
};

constexpr Limit kLimits[] = {
    {"samplers", &DescriptorCounts::samplers,
     &VkPhysicalDeviceLimits::maxPerStageDescriptorSamplers,
     &VkPhysicalDeviceLimits::maxDescriptorSetSamplers},
    {"uniform buffers", &DescriptorCounts::uniform_buffers,
     &VkPhysicalDeviceLimits::maxPerStageDescriptorUniformBuffers,
     &VkPhysicalDeviceLimits::maxDescriptorSetUniformBuffers},
    {"storage buffers", &DescriptorCounts::storage_buffers,
     &VkPhysicalDeviceLimits::maxPerStageDescriptorStorageBuffers,
     &VkPhysicalDeviceLimits::maxDescriptorSetStorageBuffers},
    {"sampled images", &DescriptorCounts::sampled_images,
     &VkPhysicalDeviceLimits::maxPerStageDescriptorSampledImages,
     &VkPhysicalDeviceLimits::maxDescriptorSetSampledImages},
    {"storage images", &DescriptorCounts::storage_images,
     &VkPhysicalDeviceLimits::maxPerStageDescriptorStorageImages,
     &VkPhysicalDeviceLimits::maxDescriptorSetStorageImages},
    {"input attachments", &DescriptorCounts::input_attachments,
     &VkPhysicalDeviceLimits::maxPerStageDescriptorInputAttachments,
     &VkPhysicalDeviceLimits::maxDescriptorSetInputAttachments},
    {"dynamic buffers", &DescriptorCounts::uniform_buffers_dynamic, nullptr,
     &VkPhysicalDeviceLimits::maxDescriptorSetUniformBuffersDynamic},
    {"dynamic buffers", &DescriptorCounts::storage_buffers_dynamic, nullptr,
     &VkPhysicalDeviceLimits::maxDescriptorSetStorageBuffersDynamic},
};

struct Stage {
  VkShaderStageFlagBits bit;
  const char* name;
};
constexpr Stage kStages[] = {
    {VK_SHADER_STAGE_VERTEX_BIT, "vertex"},
    {VK_SHADER_STAGE_TESSELLATION_CONTROL_BIT, "tessellation control"},
    {VK_SHADER_STAGE_TESSELLATION_EVALUATION_BIT, "tessellation evaluation"},
    {VK_SHADER_STAGE_GEOMETRY_BIT, "geometry"},
    {VK_SHADER_STAGE_FRAGMENT_BIT, "fragment"},
    {VK_SHADER_STAGE_COMPUTE_BIT, "compute"}};

// Every limit the check reads, named as the spec spells it.
struct NamedLimit {
  const char* name;
  uint32_t VkPhysicalDeviceLimits::*limit;
  uint32_t minimum;  // Vulkan's required minimum
};
#define TESSERA_LIMIT(field, minimum) \
  { #field, &VkPhysicalDeviceLimits::field, minimum }
constexpr NamedLimit kNamedLimits[] = {
    TESSERA_LIMIT(maxBoundDescriptorSets, 4),
    TESSERA_LIMIT(maxPushConstantsSize, 128),
    TESSERA_LIMIT(maxPerStageDescriptorSamplers, 16),
    TESSERA_LIMIT(maxPerStageDescriptorUniformBuffers, 12),
    TESSERA_LIMIT(maxPerStageDescriptorStorageBuffers, 4),
    TESSERA_LIMIT(maxPerStageDescriptorSampledImages, 16),
    TESSERA_LIMIT(maxPerStageDescriptorStorageImages, 4),
    TESSERA_LIMIT(maxPerStageDescriptorInputAttachments, 4),
    TESSERA_LIMIT(maxPerStageResources, 128),
    TESSERA_LIMIT(maxDescriptorSetSamplers, 96),
    TESSERA_LIMIT(maxDescriptorSetUniformBuffers, 72),
    TESSERA_LIMIT(maxDescriptorSetStorageBuffers, 24),
    TESSERA_LIMIT(maxDescriptorSetSampledImages, 96),
    TESSERA_LIMIT(maxDescriptorSetStorageImages, 24),
    TESSERA_LIMIT(maxDescriptorSetInputAttachments, 4),
    TESSERA_LIMIT(maxDescriptorSetUniformBuffersDynamic, 8),
    TESSERA_LIMIT(maxDescriptorSetStorageBuffersDynamic, 4),
};
#undef TESSERA_LIMIT

const char* LimitName(uint32_t VkPhysicalDeviceLimits::*limit) {
  for (const NamedLimit& l : kNamedLimits)
    if (l.limit == limit) return l.name;
  return "?";
}

constexpr char kLimitPayload[] = "tessera.vk/descriptor-limits";

}  // namespace

absl::Status CheckDescriptorLimits(
    const VkPhysicalDeviceLimits& limits,
    const std::vector<std::vector<VkDescriptorSetLayoutBinding>>& sets, uint32_t push_bytes,
    const std::string& name) {
  auto over = [&](auto... what) {
    absl::Status s = absl::FailedPreconditionError(absl::StrCat(name, ": ", what...));
    s.SetPayload(kLimitPayload, absl::Cord("1"));
    return s;
  };
  DescriptorCounts all;
  for (const auto& set : sets) all += CountDescriptors(set, VK_SHADER_STAGE_ALL);
  if (all.uncounted > 0) {
    return absl::InternalError(absl::StrCat(
        name, ": a descriptor type whose limits vk::CheckDescriptorLimits does not check"));
  }
  if (sets.size() > limits.maxBoundDescriptorSets) {
    return over(sets.size(), " descriptor sets exceed the device's maxBoundDescriptorSets (",
                limits.maxBoundDescriptorSets, ")");
  }
  if (push_bytes > limits.maxPushConstantsSize) {
    return over(push_bytes, " bytes of push constants exceed the device's maxPushConstantsSize (",
                limits.maxPushConstantsSize, ")");
  }
  for (const Stage& stage : kStages) {
    DescriptorCounts c;
    for (const auto& set : sets) c += CountDescriptors(set, stage.bit);
    for (const Limit& l : kLimits) {
      if (l.per_stage != nullptr && c.*l.count > limits.*l.per_stage) {
        return over(c.*l.count, " ", l.what, " in the ", stage.name, " stage exceed the device's ",
                    LimitName(l.per_stage), " (", limits.*l.per_stage, ")");
      }
    }
    if (c.Resources() > limits.maxPerStageResources) {
      return over(c.Resources(), " resources in the ", stage.name,
                  " stage exceed the device's maxPerStageResources (", limits.maxPerStageResources,
                  ")");
    }
  }
  for (const Limit& l : kLimits) {
    if (all.*l.count > limits.*l.per_layout) {
      return over(all.*l.count, " ", l.what, " in the layout exceed the device's ",
                  LimitName(l.per_layout), " (", limits.*l.per_layout, ")");
    }
  }
  return absl::OkStatus();
}

bool IsDescriptorLimitError(const absl::Status& status) {
  return status.GetPayload(kLimitPayload).has_value();
}

VkPhysicalDeviceLimits MinimumDescriptorLimits(VkPhysicalDeviceLimits limits) {
  for (const NamedLimit& l : kNamedLimits) limits.*l.limit = std::min(limits.*l.limit, l.minimum);
  return limits;
}

absl::Status CapDescriptorLimit(VkPhysicalDeviceLimits& limits, const std::string& name,
                                uint32_t cap) {
  for (const NamedLimit& l : kNamedLimits) {
    if (name == l.name) {
      limits.*l.limit = std::min(limits.*l.limit, cap);
      return absl::OkStatus();
    }
  }
  std::string known;
  for (const NamedLimit& l : kNamedLimits)
    absl::StrAppend(&known, known.empty() ? "" : ", ", l.name);
  return absl::InvalidArgumentError(
      absl::StrCat("unknown descriptor limit \"", name, "\" (known: ", known, ")"));
}

}  // namespace tessera::vk
