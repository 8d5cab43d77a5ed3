#include "renderer/frame_graph.h"

#include <array>

namespace tessera {

std::string_view PassName(PassId id) {
  switch (id) {
    case PassId::kCull:
      return "cull";
    case PassId::kDepthPrepass:
      return "depth_prepass";
    case PassId::kHizBuild:
      return "hiz_build";
    case PassId::kCullLate:
      return "cull_late";
    case PassId::kDepthPrepassLate:
      return "depth_prepass_late";
    case PassId::kLightCull:
      return "light_cull";
    case PassId::kForward:
      return "forward";
    case PassId::kTransparent:
      return "transparent";
    case PassId::kTonemap:
      return "tonemap";
    case PassId::kReadback:
      return "readback";
    case PassId::kCount:
      break;
  }
  return "invalid";
}

std::vector<ResourceUse> PassUses(PassId id) {
  using R = Resource;
  using A = Access;
  switch (id) {
    // The first culling phase does not read the pyramid, but its pipeline binds it.
    case PassId::kCull:
      return {{R::kHiz, A::kComputeRead}};
    case PassId::kDepthPrepass:
    case PassId::kDepthPrepassLate:
      return {{R::kDepth, A::kDepthWrite}};
    case PassId::kHizBuild:
      return {{R::kDepth, A::kComputeRead}, {R::kHiz, A::kComputeWrite}};
    case PassId::kCullLate:
      return {{R::kHiz, A::kComputeRead}};
    case PassId::kLightCull:
      return {{R::kDepth, A::kComputeRead}};
    case PassId::kForward:
      return {{R::kDepth, A::kDepthTest}, {R::kHdrColor, A::kColorWrite}};
    case PassId::kTransparent:
      return {{R::kDepth, A::kDepthTest}, {R::kHdrColor, A::kColorWrite}};
    case PassId::kTonemap:
      return {{R::kHdrColor, A::kSampled}, {R::kLdrColor, A::kColorWrite}};
    case PassId::kReadback:
      return {{R::kLdrColor, A::kTransferSrc}};
    case PassId::kCount:
      break;
  }
  return {};
}

std::vector<PassId> SelectPasses(const Settings& settings, const FrameFeatures& features) {
  std::vector<PassId> passes;
  const bool gpu_culling = settings.culling == CullingMode::kGpuFrustum ||
                           settings.culling == CullingMode::kGpuOcclusion;
  if (gpu_culling) passes.push_back(PassId::kCull);
  // Depth first: forward shading then tests EQUAL-or-nearer against it and shades each pixel
  // once, which matters most on a CPU rasterizer where fragment work is the bill.
  passes.push_back(PassId::kDepthPrepass);
  // Two-phase occlusion culling: what was visible last frame is drawn above; its depth becomes
  // the pyramid that every other drawable is tested against, and what passes is drawn now.
  if (settings.culling == CullingMode::kGpuOcclusion) {
    passes.push_back(PassId::kHizBuild);
    passes.push_back(PassId::kCullLate);
    passes.push_back(PassId::kDepthPrepassLate);
  }
  // Forward+: per-tile light lists, unless there is nothing to cull or brute force was asked.
  if (settings.light_culling && features.local_lights > 0) passes.push_back(PassId::kLightCull);
  passes.push_back(PassId::kForward);
  // Blended surfaces need the opaque colour underneath and must not write depth.
  if (features.has_transparent) passes.push_back(PassId::kTransparent);
  passes.push_back(PassId::kTonemap);
  passes.push_back(PassId::kReadback);
  return passes;
}

namespace {
bool Writes(Access a) {
  return a == Access::kDepthWrite || a == Access::kColorWrite || a == Access::kComputeWrite;
}
// Accesses that share a layout (depth test and depth write are both attachment-optimal).
int LayoutClass(Access a) {
  switch (a) {
    case Access::kDepthWrite:
    case Access::kDepthTest:
      return 1;
    case Access::kColorWrite:
      return 2;
    case Access::kSampled:
    case Access::kComputeRead:
      return 3;
    case Access::kTransferSrc:
      return 4;
    case Access::kComputeWrite:
      return 5;
    case Access::kNone:
      return 0;
  }
  return 0;
}
}  // namespace

std::vector<std::vector<Transition>> PlanTransitions(const std::vector<PassId>& passes) {
  std::array<Access, static_cast<size_t>(Resource::kCount)> state;
  state.fill(Access::kNone);
  std::vector<std::vector<Transition>> plan(passes.size());
  for (size_t i = 0; i < passes.size(); ++i) {
    for (const ResourceUse& use : PassUses(passes[i])) {
      Access& current = state[static_cast<size_t>(use.resource)];
      const bool layout_change = LayoutClass(current) != LayoutClass(use.access);
      if (layout_change || Writes(current) || Writes(use.access)) {
        plan[i].push_back({use.resource, current, use.access});
      }
      current = use.access;
    }
  }
  return plan;
}

}  // namespace tessera
