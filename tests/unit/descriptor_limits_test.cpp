// vk::CheckDescriptorLimits: what a pipeline layout takes of a device's descriptor limits, per
// stage and for the whole layout, and the message when it takes more.
#include "renderer/vk/descriptor_limits.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace tessera::vk {
namespace {

using Bindings = std::vector<VkDescriptorSetLayoutBinding>;

VkDescriptorSetLayoutBinding Binding(uint32_t binding, VkDescriptorType type,
                                     VkShaderStageFlags stages, uint32_t count = 1) {
  return {binding, type, count, stages, nullptr};
}

// Vulkan's minimums (every other limit generous).
VkPhysicalDeviceLimits Minimums() {
  VkPhysicalDeviceLimits l{};
  l.maxBoundDescriptorSets = l.maxPushConstantsSize = l.maxPerStageResources = 1000;
  l.maxPerStageDescriptorSamplers = l.maxPerStageDescriptorUniformBuffers = 1000;
  l.maxPerStageDescriptorStorageBuffers = l.maxPerStageDescriptorSampledImages = 1000;
  l.maxPerStageDescriptorStorageImages = l.maxPerStageDescriptorInputAttachments = 1000;
  l.maxDescriptorSetSamplers = l.maxDescriptorSetUniformBuffers = 1000;
  l.maxDescriptorSetStorageBuffers = l.maxDescriptorSetSampledImages = 1000;
  l.maxDescriptorSetStorageImages = l.maxDescriptorSetInputAttachments = 1000;
  l.maxDescriptorSetUniformBuffersDynamic = l.maxDescriptorSetStorageBuffersDynamic = 1000;
  return MinimumDescriptorLimits(l);
}

constexpr VkShaderStageFlags kFragment = VK_SHADER_STAGE_FRAGMENT_BIT;
constexpr VkShaderStageFlags kCompute = VK_SHADER_STAGE_COMPUTE_BIT;
constexpr VkShaderStageFlags kPixel = kFragment | kCompute;

TEST(DescriptorLimits, MinimumsAreTheSpecsRequiredLimits) {
  const VkPhysicalDeviceLimits l = Minimums();
  EXPECT_EQ(l.maxBoundDescriptorSets, 4u);
  EXPECT_EQ(l.maxPushConstantsSize, 128u);
  EXPECT_EQ(l.maxPerStageDescriptorSamplers, 16u);
  EXPECT_EQ(l.maxPerStageDescriptorUniformBuffers, 12u);
  EXPECT_EQ(l.maxPerStageDescriptorStorageBuffers, 4u);
  EXPECT_EQ(l.maxPerStageDescriptorSampledImages, 16u);
  EXPECT_EQ(l.maxPerStageDescriptorStorageImages, 4u);
  EXPECT_EQ(l.maxPerStageResources, 128u);
  EXPECT_EQ(l.maxDescriptorSetSamplers, 96u);
  EXPECT_EQ(l.maxDescriptorSetStorageBuffers, 24u);
  // A device above a minimum keeps it; one below (none should be) keeps its own.
  VkPhysicalDeviceLimits low = l;
  low.maxPerStageDescriptorSamplers = 8;
  EXPECT_EQ(MinimumDescriptorLimits(low).maxPerStageDescriptorSamplers, 8u);
}

TEST(DescriptorLimits, CountsEachTypeWhereTheLimitsCountIt) {
  const Bindings b = {
      Binding(0, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, kPixel, 3),
      Binding(1, VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, kCompute, 2),
      Binding(2, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, kFragment),
      Binding(3, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, kCompute),
      Binding(4, VK_DESCRIPTOR_TYPE_STORAGE_TEXEL_BUFFER, kCompute),
      Binding(5, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, VK_SHADER_STAGE_ALL),
      Binding(6, VK_DESCRIPTOR_TYPE_SAMPLER, kFragment),
  };
  const DescriptorCounts compute = CountDescriptors(b, kCompute);
  EXPECT_EQ(compute.samplers, 3u);
  EXPECT_EQ(compute.sampled_images, 5u);  // combined image samplers and uniform texel buffers
  EXPECT_EQ(compute.storage_images, 2u);  // storage images and storage texel buffers
  EXPECT_EQ(compute.storage_buffers, 0u);
  EXPECT_EQ(compute.uniform_buffers, 1u);
  EXPECT_EQ(compute.Resources(), 8u);  // a combined image sampler is one resource
  const DescriptorCounts fragment = CountDescriptors(b, kFragment);
  EXPECT_EQ(fragment.samplers, 4u);
  EXPECT_EQ(fragment.sampled_images, 3u);
  EXPECT_EQ(fragment.storage_buffers, 1u);
  EXPECT_EQ(CountDescriptors(b, VK_SHADER_STAGE_VERTEX_BIT).uniform_buffers, 1u);
  EXPECT_EQ(CountDescriptors(b, VK_SHADER_STAGE_VERTEX_BIT).samplers, 0u);
}

TEST(DescriptorLimits, APerStageLimitIsCheckedOverEverySet) {
  const VkPhysicalDeviceLimits l = Minimums();
  // 16 sampled images in the compute stage fit; the 17th, in another set, does not.
  const Bindings set0 = {Binding(0, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, kPixel, 10)};
  Bindings set1 = {Binding(0, VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, kCompute, 6)};
  EXPECT_TRUE(CheckDescriptorLimits(l, {set0, set1}, 0, "shade").ok());
  set1[0].descriptorCount = 7;
  const absl::Status s = CheckDescriptorLimits(l, {set0, set1}, 0, "shade");
  EXPECT_EQ(s.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(s.message(),
            "shade: 17 sampled images in the compute stage exceed the device's "
            "maxPerStageDescriptorSampledImages (16)");
  // The fragment stage alone holds 10: a layout for it is fine.
  EXPECT_TRUE(CheckDescriptorLimits(
                  l, {set0, {Binding(0, VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, kFragment, 6)}}, 0,
                  "shade")
                  .ok());
  // Five storage buffers in one stage: four is the minimum.
  const Bindings buffers = {Binding(0, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, kFragment, 2),
                            Binding(1, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER_DYNAMIC, kPixel, 3)};
  EXPECT_EQ(CheckDescriptorLimits(l, {buffers}, 0, "scene").message(),
            "scene: 5 storage buffers in the fragment stage exceed the device's "
            "maxPerStageDescriptorStorageBuffers (4)");
}

TEST(DescriptorLimits, TheWholeLayoutsLimits) {
  VkPhysicalDeviceLimits l = Minimums();
  const Bindings one = {Binding(0, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, kFragment)};
  EXPECT_EQ(CheckDescriptorLimits(l, {one, one, one, one, one}, 0, "p").message(),
            "p: 5 descriptor sets exceed the device's maxBoundDescriptorSets (4)");
  EXPECT_EQ(CheckDescriptorLimits(l, {one}, 132, "p").message(),
            "p: 132 bytes of push constants exceed the device's maxPushConstantsSize (128)");
  EXPECT_TRUE(CheckDescriptorLimits(l, {one}, 128, "p").ok());
  // 10 storage buffers in each of three stages fit a device with 10 per stage, but not its
  // 24 for the layout.
  l.maxPerStageDescriptorStorageBuffers = 10;
  const Bindings per_stage = {
      Binding(0, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, VK_SHADER_STAGE_VERTEX_BIT, 10),
      Binding(1, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, kFragment, 10),
      Binding(2, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, kCompute, 10)};
  EXPECT_EQ(CheckDescriptorLimits(l, {per_stage}, 0, "p").message(),
            "p: 30 storage buffers in the layout exceed the device's "
            "maxDescriptorSetStorageBuffers (24)");
  // maxPerStageResources counts every kind together.
  l = Minimums();
  l.maxPerStageResources = 20;
  const Bindings mixed = {Binding(0, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, kFragment, 16),
                          Binding(1, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, kFragment, 4),
                          Binding(2, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, kFragment, 1)};
  EXPECT_EQ(CheckDescriptorLimits(l, {mixed}, 0, "p").message(),
            "p: 21 resources in the fragment stage exceed the device's maxPerStageResources (20)");
}

TEST(DescriptorLimits, DynamicBuffersAndTypesItDoesNotCount) {
  const VkPhysicalDeviceLimits l = Minimums();
  // Dynamic buffers count as buffers, and against their own limit for the layout (4 storage).
  const Bindings dynamic = {
      Binding(0, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER_DYNAMIC, VK_SHADER_STAGE_VERTEX_BIT, 3),
      Binding(1, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER_DYNAMIC, kFragment, 2)};
  EXPECT_EQ(CountDescriptors(dynamic, kFragment).storage_buffers, 2u);
  EXPECT_EQ(CountDescriptors(dynamic, VK_SHADER_STAGE_ALL).storage_buffers_dynamic, 5u);
  EXPECT_EQ(CheckDescriptorLimits(l, {dynamic}, 0, "p").message(),
            "p: 5 dynamic buffers in the layout exceed the device's "
            "maxDescriptorSetStorageBuffersDynamic (4)");
  // A type the check does not count is refused, not passed unchecked.
  const absl::Status s = CheckDescriptorLimits(
      l, {{Binding(0, VK_DESCRIPTOR_TYPE_INLINE_UNIFORM_BLOCK, kFragment, 16)}}, 0, "p");
  EXPECT_EQ(s.code(), absl::StatusCode::kInternal);
  EXPECT_FALSE(IsDescriptorLimitError(s));
  // The refusals over a limit say so; others do not.
  EXPECT_TRUE(IsDescriptorLimitError(CheckDescriptorLimits(l, {dynamic}, 0, "p")));
  EXPECT_FALSE(IsDescriptorLimitError(absl::FailedPreconditionError("p")));
}

TEST(DescriptorLimits, CapsAreNamedAsTheSpecNamesThem) {
  VkPhysicalDeviceLimits l = Minimums();
  ASSERT_TRUE(CapDescriptorLimit(l, "maxPerStageDescriptorStorageBuffers", 2).ok());
  EXPECT_EQ(l.maxPerStageDescriptorStorageBuffers, 2u);
  ASSERT_TRUE(CapDescriptorLimit(l, "maxPerStageDescriptorStorageBuffers", 9).ok());
  EXPECT_EQ(l.maxPerStageDescriptorStorageBuffers, 2u);  // at most: never raised
  const absl::Status s = CapDescriptorLimit(l, "maxStorageBuffers", 2);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(std::string(s.message()).find("known: maxBoundDescriptorSets, "), std::string::npos)
      << s;
}

}  // namespace
}  // namespace tessera::vk
