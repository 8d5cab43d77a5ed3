#include "renderer/frame_graph.h"

#include <array>

namespace tessera {

// What a pass uses apart from ssao's result.
static std::vector<ResourceUse> PassUsesWithoutAo(PassId id, AaMode aa);

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
    case PassId::kShadows:
      return "shadows";
    case PassId::kSsao:
      return "ssao";
    case PassId::kForward:
      return "forward";
    case PassId::kTransparent:
      return "transparent";
    case PassId::kTonemap:
      return "tonemap";
    case PassId::kReadback:
      return "readback";
    case PassId::kVisibility:
      return "visibility";
    case PassId::kVisibilityLate:
      return "visibility_late";
    case PassId::kVisResolve:
      return "vis_resolve";
    case PassId::kVisShade:
      return "vis_shade";
    case PassId::kGeometricAa:
      return "geometric_aa";
    case PassId::kTaa:
      return "taa";
    case PassId::kExposure:
      return "exposure";
    case PassId::kBloom:
      return "bloom";
    case PassId::kFxaa:
      return "fxaa";
    case PassId::kCount:
      break;
  }
  return "invalid";
}

std::vector<ResourceUse> PassUses(PassId id, AaMode aa, bool ssao, bool bloom) {
  std::vector<ResourceUse> uses = PassUsesWithoutAo(id, aa);
  const bool shades = id == PassId::kForward || id == PassId::kVisShade ||
                      id == PassId::kTransparent || id == PassId::kTonemap;
  if (ssao && shades) uses.push_back({Resource::kAo, Access::kSampled});
  if (bloom && id == PassId::kTonemap) uses.push_back({Resource::kBloomUp, Access::kSampled});
  return uses;
}

static std::vector<ResourceUse> PassUsesWithoutAo(PassId id, AaMode aa) {
  using R = Resource;
  using A = Access;
  const bool msaa = aa == AaMode::kMsaa;
  const bool vis = aa == AaMode::kVisMlaa;
  // The colour the opaque result ends in, and the one tonemapping reads.
  const R post = vis || aa == AaMode::kTaa ? R::kPostHdr : R::kHdrColor;
  switch (id) {
    // The first culling phase does not read the pyramid, but its pipeline binds it.
    case PassId::kCull:
      return {{R::kHiz, A::kComputeRead}};
    case PassId::kDepthPrepass:
    case PassId::kDepthPrepassLate:
      if (msaa) return {{R::kDepthMs, A::kDepthWrite}, {R::kDepth, A::kDepthResolve}};
      return {{R::kDepth, A::kDepthWrite}};
    case PassId::kVisibility:
    case PassId::kVisibilityLate:
      return {{R::kDepthMs, A::kDepthWrite},
              {R::kVisMs, A::kColorWrite},
              {R::kDepth, A::kDepthResolve}};
    case PassId::kHizBuild:
      return {{R::kDepth, A::kComputeRead}, {R::kHiz, A::kComputeWrite}};
    case PassId::kCullLate:
      return {{R::kHiz, A::kComputeRead}};
    case PassId::kLightCull:
      return {{R::kDepth, A::kComputeRead}};
    case PassId::kShadows:
      return {};
    case PassId::kSsao:
      return {{R::kDepth, A::kSampled}, {R::kAo, A::kColorWrite}, {R::kAoTemp, A::kColorWrite}};
    case PassId::kVisResolve:
      return {{R::kVisMs, A::kSampled},
              {R::kVisId, A::kColorWrite},
              {R::kVisCoverage, A::kColorWrite},
              {R::kMaterialDepth, A::kDepthWrite}};
    case PassId::kVisShade:
      return {{R::kVisId, A::kSampled},
              {R::kVisCoverage, A::kSampled},
              {R::kVisMs, A::kSampled},
              {R::kMaterialDepth, A::kDepthTest},
              {R::kHdrColor, A::kColorWrite}};
    case PassId::kForward:
      if (msaa)
        return {{R::kDepthMs, A::kDepthTest}, {R::kHdrMs, A::kColorWrite},
                {R::kHdrColor, A::kColorWrite}};
      return {{R::kDepth, A::kDepthTest}, {R::kHdrColor, A::kColorWrite}};
    case PassId::kGeometricAa:
      return {{R::kHdrColor, A::kSampled},
              {R::kVisCoverage, A::kSampled},
              {R::kVisId, A::kSampled},
              {R::kPostHdr, A::kColorWrite}};
    case PassId::kTransparent:
      if (msaa)
        return {{R::kDepthMs, A::kDepthTest}, {R::kHdrMs, A::kColorWrite},
                {R::kHdrColor, A::kColorWrite}};
      // vis_mlaa: over the anti-aliased result, against the resolved depth.
      return {{R::kDepth, A::kDepthTest}, {vis ? R::kPostHdr : R::kHdrColor, A::kColorWrite}};
    case PassId::kTaa:
      return {{R::kHdrColor, A::kSampled}, {R::kDepth, A::kSampled}, {R::kPostHdr, A::kColorWrite}};
    case PassId::kExposure:
      return {{post, A::kComputeRead}};
    case PassId::kBloom:
      return {{post, A::kSampled}, {R::kBloomDown, A::kColorWrite}, {R::kBloomUp, A::kColorWrite}};
    case PassId::kTonemap:
      return {{post, A::kSampled}, {R::kLdrColor, A::kColorWrite}};
    case PassId::kFxaa:
      return {{R::kLdrColor, A::kSampled}, {R::kFxaaColor, A::kColorWrite}};
    case PassId::kReadback:
      return {{aa == AaMode::kFxaa ? R::kFxaaColor : R::kLdrColor, A::kTransferSrc}};
    case PassId::kCount:
      break;
  }
  return {};
}

std::vector<PassId> SelectPasses(const Settings& settings, const FrameFeatures& features) {
  std::vector<PassId> passes;
  const bool gpu_culling = settings.culling == CullingMode::kGpuFrustum ||
                           settings.culling == CullingMode::kGpuOcclusion;
  const bool vis = settings.aa == AaMode::kVisMlaa;
  if (gpu_culling) passes.push_back(PassId::kCull);
  // Depth first: forward shading then tests EQUAL-or-nearer against it and shades each pixel
  // once, which matters most on a CPU rasterizer where fragment work is the bill. vis_mlaa's
  // visibility pass is its depth pass.
  passes.push_back(vis ? PassId::kVisibility : PassId::kDepthPrepass);
  // Two-phase occlusion culling: what was visible last frame is drawn above; its depth becomes
  // the pyramid that every other drawable is tested against, and what passes is drawn now.
  if (settings.culling == CullingMode::kGpuOcclusion) {
    passes.push_back(PassId::kHizBuild);
    passes.push_back(PassId::kCullLate);
    passes.push_back(vis ? PassId::kVisibilityLate : PassId::kDepthPrepassLate);
  }
  // Forward+: per-tile light lists, unless there is nothing to cull or brute force was asked.
  if (settings.light_culling && features.local_lights > 0) passes.push_back(PassId::kLightCull);
  // Shadow maps and ambient obscurance, before the shading that reads them.
  if (settings.shadows) passes.push_back(PassId::kShadows);
  if (settings.ssao) passes.push_back(PassId::kSsao);
  if (vis) {
    passes.push_back(PassId::kVisResolve);
    passes.push_back(PassId::kVisShade);
    passes.push_back(PassId::kGeometricAa);
  } else {
    passes.push_back(PassId::kForward);
  }
  // Blended surfaces need the opaque colour underneath and must not write depth.
  if (features.has_transparent) passes.push_back(PassId::kTransparent);
  if (settings.aa == AaMode::kTaa) passes.push_back(PassId::kTaa);
  // Exposure before bloom: bloom's threshold is in exposed units. Debug views other than bloom's
  // are not exposed, and must not move a stream's adapted exposure.
  const bool exposed =
      settings.debug_view == DebugView::kNone || settings.debug_view == DebugView::kBloom;
  if (settings.exposure_mode == ExposureMode::kAuto && exposed)
    passes.push_back(PassId::kExposure);
  if (settings.bloom) passes.push_back(PassId::kBloom);
  passes.push_back(PassId::kTonemap);
  if (settings.aa == AaMode::kFxaa) passes.push_back(PassId::kFxaa);
  passes.push_back(PassId::kReadback);
  return passes;
}

namespace {
bool Writes(Access a) {
  return a == Access::kDepthWrite || a == Access::kColorWrite || a == Access::kComputeWrite ||
         a == Access::kDepthResolve;
}
// Accesses that share a layout (depth test and depth write are both attachment-optimal).
int LayoutClass(Access a) {
  switch (a) {
    case Access::kDepthWrite:
    case Access::kDepthTest:
    case Access::kDepthResolve:
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

std::vector<std::vector<Transition>> PlanTransitions(const std::vector<PassId>& passes,
                                                     AaMode aa, bool ssao, bool bloom) {
  std::array<Access, static_cast<size_t>(Resource::kCount)> state;
  state.fill(Access::kNone);
  std::vector<std::vector<Transition>> plan(passes.size());
  for (size_t i = 0; i < passes.size(); ++i) {
    for (const ResourceUse& use : PassUses(passes[i], aa, ssao, bloom)) {
      Access& current = state[static_cast<size_t>(use.resource)];
      const bool layout_change = LayoutClass(current) != LayoutClass(use.access);
      const bool other_stage = current != use.access;  // e.g. a compute read, then a fragment one
      if (layout_change || other_stage || Writes(current) || Writes(use.access)) {
        plan[i].push_back({use.resource, current, use.access});
      }
      current = use.access;
    }
  }
  return plan;
}

}  // namespace tessera
