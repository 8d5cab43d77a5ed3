// The embedded SPIR-V of the visibility pipeline's per-pixel compute shaders holds no workgroup
// barrier and no shared memory: SwiftShader runs every workgroup of a shader with barriers as
// coroutines, whether a specialization constant leaves them reachable or not (the
// classification's fill cost 2.8x as much while it shared a shader with the scan:
// common/vis_classify.glsl). The classification's scan, which needs both, has its own shader.
#include <gtest/gtest.h>

#include <cstdint>
#include <span>
#include <string>

#include "shaders/shader_registry.h"

namespace tessera {
namespace {

struct SpirvUse {
  bool valid = false;      // a SPIR-V module whose instructions end where the words do
  int barriers = 0;        // OpControlBarrier
  int shared = 0;          // OpVariable in the Workgroup storage class
};

SpirvUse Scan(std::span<const uint32_t> words) {
  constexpr uint32_t kMagic = 0x07230203, kOpVariable = 59, kOpControlBarrier = 224;
  constexpr uint32_t kWorkgroup = 4;  // StorageClass Workgroup
  SpirvUse use;
  if (words.size() < 5 || words[0] != kMagic) return use;
  size_t i = 5;  // after the header
  while (i < words.size()) {
    const uint32_t count = words[i] >> 16, op = words[i] & 0xffffu;
    if (count == 0 || i + count > words.size()) return use;
    if (op == kOpControlBarrier) use.barriers++;
    if (op == kOpVariable && count >= 4 && words[i + 3] == kWorkgroup) use.shared++;
    i += count;
  }
  use.valid = true;
  return use;
}

TEST(ShaderRegistryTest, PerPixelVisibilityShadersHaveNoWorkgroupBarriers) {
  for (const char* name :
       {"vis_classify.comp", "vis_classify_atomic.comp", "vis_classify_mlaa.comp",
        "vis_classify_atomic_mlaa.comp", "vis_resolve.comp", "vis_resolve_atomic.comp",
        "vis_resolve_analytic.comp", "vis_resolve_analytic_atomic.comp", "vis_shade.comp",
        "vis_shade_mlaa.comp", "vis_sky_mlaa.comp"}) {
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

}  // namespace
}  // namespace tessera
