// The embedded SPIR-V of the visibility pipeline's per-pixel compute shaders holds no workgroup
// barrier and no shared memory: SwiftShader runs every workgroup of a shader with barriers as
// coroutines, whether a specialization constant leaves them reachable or not (the
// classification's fill cost 2.8x as much while it shared a shader with the scan:
// common/vis_classify.glsl). The classification's scan, which needs both, has its own shader.
// And the host specialization SwiftShader gets (vk/spirv_specialize.h, DeviceInfo::
// host_specialization): constants frozen, each mode's module holding only its own code.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <span>
#include <string>

#include "renderer/vk/spirv_specialize.h"
#include "shaders/common/gpu_types.h"
#include "shaders/shader_registry.h"
#include "spirv-tools/libspirv.hpp"

namespace tessera {
namespace {

struct SpirvUse {
  bool valid = false;      // a SPIR-V module whose instructions end where the words do
  int barriers = 0;        // OpControlBarrier
  int shared = 0;          // OpVariable in the Workgroup storage class
  int spec_constants = 0;  // OpSpecConstant{True,False,,Composite,Op}
};

SpirvUse Scan(std::span<const uint32_t> words) {
  constexpr uint32_t kOpVariable = 59, kOpControlBarrier = 224;
  constexpr uint32_t kWorkgroup = 4;  // StorageClass Workgroup
  SpirvUse use;
  use.valid = vk::ForEachSpirvInstruction(words, [&](uint32_t op, std::span<const uint32_t> w) {
    if (op == kOpControlBarrier) use.barriers++;
    if (op >= 48 && op <= 52) use.spec_constants++;  // OpSpecConstantTrue .. OpSpecConstantOp
    if (op == kOpVariable && w.size() >= 4 && w[3] == kWorkgroup) use.shared++;
  });
  return use;
}

TEST(ShaderRegistryTest, PerPixelVisibilityShadersHaveNoWorkgroupBarriers) {
  for (const char* name :
       {"vis_classify.comp", "vis_classify_atomic.comp", "vis_classify_mlaa.comp",
        "vis_classify_atomic_mlaa.comp", "vis_resolve.comp", "vis_resolve_atomic.comp",
        "vis_resolve_analytic.comp", "vis_resolve_analytic_atomic.comp", "vis_shade.comp",
        "vis_shade_mlaa.comp", "vis_sky_mlaa.comp", "vis_shade_all.comp", "vis_shade_all_mlaa.comp",
        "vis_shade_all_runner_ups.comp"}) {
    SCOPED_TRACE(name);
    const SpirvUse use = Scan(EmbeddedShader(name));
    ASSERT_TRUE(use.valid) << "not embedded, or not SPIR-V";
    EXPECT_EQ(use.barriers, 0);
    EXPECT_EQ(use.shared, 0);
  }
}

// The scan keeps its barriers and shared sums (so the check above can see them where they are).
TEST(ShaderRegistryTest, TheClassificationScanHasItsBarriers) {
  const SpirvUse use = Scan(EmbeddedShader("vis_classify_scan.comp"));
  ASSERT_TRUE(use.valid);
  EXPECT_GT(use.barriers, 0);
  EXPECT_EQ(use.shared, 1);
}

TEST(ShaderRegistryTest, AnUnknownNameHasNoShader) {
  EXPECT_TRUE(EmbeddedShader("no_such_shader.comp").empty());
  EXPECT_FALSE(Scan(EmbeddedShader("no_such_shader.comp")).valid);
}

// Host specialization (DeviceInfo::host_specialization, for SwiftShader): the constants are
// frozen, the code they leave unreachable is gone, and the module is still valid SPIR-V.
bool ValidVulkanSpirv(const std::vector<uint32_t>& words) {
  spvtools::SpirvTools tools(SPV_ENV_VULKAN_1_3);
  spvtools::ValidatorOptions options;
  options.SetScalarBlockLayout(true);
  return tools.Validate(words.data(), words.size(), options);
}

TEST(SpecializeSpirvTest, EachModeKeepsOnlyItsOwnCode) {
  const std::span<const uint32_t> resolve = EmbeddedShader("vis_resolve_atomic.comp");
  ASSERT_FALSE(resolve.empty());
  ASSERT_TRUE(ValidVulkanSpirv({resolve.begin(), resolve.end()})) << "the build's own output";
  EXPECT_GT(Scan(resolve).spec_constants, 0);
  // vis_resolve's constants: samples, mode, (unused), texels.
  absl::StatusOr<std::vector<uint32_t>> uniform =
      vk::SpecializeSpirv(resolve, std::vector<uint32_t>{4u, gpu::kResolveUniform, 0u, 1u});
  absl::StatusOr<std::vector<uint32_t>> edges =
      vk::SpecializeSpirv(resolve, std::vector<uint32_t>{4u, gpu::kResolveEdges, 0u, 1u});
  ASSERT_TRUE(uniform.ok()) << uniform.status();
  ASSERT_TRUE(edges.ok()) << edges.status();
  EXPECT_TRUE(ValidVulkanSpirv(*uniform));
  EXPECT_TRUE(ValidVulkanSpirv(*edges));
  EXPECT_EQ(Scan(*uniform).spec_constants, 0);
  EXPECT_EQ(Scan(*edges).spec_constants, 0);
  // The uniform pass has none of the grouping, the triangle tests or the runner-ups: a fraction
  // of the whole shader, and of the edge grouping's.
  EXPECT_LT(uniform->size() * 3, resolve.size()) << uniform->size() << " of " << resolve.size();
  EXPECT_LT(uniform->size() * 2, edges->size()) << uniform->size() << " against " << edges->size();
}

TEST(SpecializeSpirvTest, BooleanConstantsTakeZeroOrOne) {
  const std::span<const uint32_t> classify = EmbeddedShader("vis_classify_atomic.comp");
  ASSERT_FALSE(classify.empty());
  // vis_classify's constants: mode, background from the IBL map (bool), count the sky (bool),
  // texels (bool). The IBL switch reaches the background through a function's parameter, so
  // its code stays until the driver inlines (SwiftShader does, then drops it); the modules
  // differ in that constant alone.
  absl::StatusOr<std::vector<uint32_t>> plain =
      vk::SpecializeSpirv(classify, std::vector<uint32_t>{gpu::kClassifyFill, 0u, 0u, 1u});
  absl::StatusOr<std::vector<uint32_t>> ibl =
      vk::SpecializeSpirv(classify, std::vector<uint32_t>{gpu::kClassifyFill, 1u, 0u, 1u});
  ASSERT_TRUE(plain.ok()) << plain.status();
  ASSERT_TRUE(ibl.ok()) << ibl.status();
  EXPECT_TRUE(ValidVulkanSpirv(*plain));
  EXPECT_TRUE(ValidVulkanSpirv(*ibl));
  EXPECT_EQ(Scan(*plain).spec_constants, 0);
  EXPECT_EQ(plain->size(), ibl->size());
  size_t differ = 0;
  for (size_t i = 0; i < std::min(plain->size(), ibl->size()); ++i)
    differ += (*plain)[i] != (*ibl)[i];
  EXPECT_EQ(differ, 1u) << "OpConstantFalse against OpConstantTrue";
  // Constants past the shader's own are ignored, as Vulkan ignores map entries it has no use for.
  absl::StatusOr<std::vector<uint32_t>> extra = vk::SpecializeSpirv(
      classify, std::vector<uint32_t>{gpu::kClassifyFill, 0u, 0u, 1u, 7u, 9u});
  ASSERT_TRUE(extra.ok()) << extra.status();
  EXPECT_EQ(*extra, *plain);
}

TEST(SpecializeSpirvTest, WordsThatAreNotSpirvAreAnError) {
  const std::vector<uint32_t> junk = {0x07230203u, 0x00010600u, 0u, 5u, 0u, 0xdeadbeefu, 3u};
  absl::StatusOr<std::vector<uint32_t>> out =
      vk::SpecializeSpirv(junk, std::vector<uint32_t>{1u});
  EXPECT_FALSE(out.ok());
  // The optimizer's own first message is passed on.
  EXPECT_EQ(out.status().message().find("no message"), std::string::npos) << out.status();
}

TEST(SpecializeSpirvTest, ShadersWithoutConstantsAreLeftAlone) {
  EXPECT_TRUE(vk::HasSpecializationConstants(EmbeddedShader("vis_resolve_atomic.comp")));
  EXPECT_TRUE(vk::HasSpecializationConstants(EmbeddedShader("tonemap.comp")));
  EXPECT_FALSE(vk::HasSpecializationConstants(EmbeddedShader("fxaa.frag")));
  EXPECT_FALSE(vk::HasSpecializationConstants(EmbeddedShader("fullscreen.vert")));
  EXPECT_FALSE(vk::HasSpecializationConstants(std::span<const uint32_t>()));
  absl::StatusOr<std::vector<uint32_t>> specialized =
      vk::SpecializeSpirv(EmbeddedShader("tonemap.comp"), std::vector<uint32_t>{1u, 0u, 0u, 0u});
  ASSERT_TRUE(specialized.ok()) << specialized.status();
  EXPECT_FALSE(vk::HasSpecializationConstants(*specialized));
}

}  // namespace
}  // namespace tessera
