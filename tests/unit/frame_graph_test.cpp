// Renderer planning logic that needs no device: the frame graph's pass selection and barrier
// plan, and the texture bucketing of GpuScene.
#include "renderer/graph/frame_graph.h"
#include "renderer/features/features.h"
#include "renderer/features/pass.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <bit>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "renderer/scene/cpu_scene.h"
#include "renderer/scene/gpu_scene.h"
#include "renderer/settings.h"

namespace tessera {
namespace {

constexpr size_t kResourceCount = static_cast<size_t>(Resource::kCount);
constexpr int kPassCount = static_cast<int>(PassId::kCount);

std::string Name(PassId id) { return std::string(PassName(id)); }

int IndexOf(const std::vector<PassId>& passes, PassId id) {
  const auto it = std::find(passes.begin(), passes.end(), id);
  return it == passes.end() ? -1 : static_cast<int>(it - passes.begin());
}

bool IsWrite(Access a) {
  return a == Access::kDepthWrite || a == Access::kColorWrite || a == Access::kComputeWrite ||
         a == Access::kDepthResolve || a == Access::kHostWrite;
}
bool IsRead(Access a) {
  return a == Access::kDepthTest || a == Access::kSampled || a == Access::kTransferSrc ||
         a == Access::kComputeRead || a == Access::kSampledGeneral ||
         a == Access::kComputeReadGeneral || a == Access::kIndirectRead ||
         a == Access::kGeometryRead || a == Access::kHostRead;
}

// The access `r` enters the frame in: its import's, else none.
Access InitialAccess(const FramePlan& plan, Resource r) {
  for (const ResourceImport& i : plan.imports)
    if (i.resource == r) return i.initial;
  return Access::kNone;
}

// Every combination of AA mode, culling mode and the effects that add passes or change what
// passes read (shadows, ssao, bloom, auto exposure, a debug view that stops exposure), with and
// without local lights to cull.
std::vector<Settings> SettingsVariants() {
  std::vector<Settings> out;
  // Each AA mode with both pipelines and both post stages.
  for (uint32_t aa = 0; aa < 20; ++aa) {
    for (uint32_t c = 0; c < 4; ++c) {
      for (uint32_t effects = 0; effects < 64; ++effects) {
        Settings s;
        s.aa = static_cast<AaMode>(aa % 5);
        s.pipeline = (aa / 5) % 2 == 0 ? Pipeline::kForward : Pipeline::kVisibility;
        s.post_stage = aa < 10 ? PostStage::kFragment : PostStage::kCompute;
        // vis_mlaa ignores the pipeline: the same bit picks its coverage.
        s.vis_mlaa_coverage =
            (aa / 5) % 2 == 0 ? VisMlaaCoverage::kRaster : VisMlaaCoverage::kAnalytic;
        s.culling = static_cast<CullingMode>(c);
        s.shadows = effects & 1;
        s.ssao = effects & 2;
        s.bloom = effects & 4;
        s.exposure_mode = (effects & 8) ? ExposureMode::kAuto : ExposureMode::kFixed;
        s.debug_view = (effects & 16) ? DebugView::kNormals : DebugView::kNone;
        s.synthetic_lights = (effects & 32) ? 8 : 0;
        s.light_culling = true;
        out.push_back(s);
      }
    }
  }
  return out;
}

// The plan of every variant above, with and without transparency, and with the long-lived
// resources holding earlier frames or new.
struct PlanCase {
  Settings settings;
  FrameFeatures features;
  FramePlan plan;
  std::vector<PassId> passes;
};
std::vector<PlanCase> AllPlans() {
  std::vector<PlanCase> out;
  for (const Settings& s : SettingsVariants()) {
    for (int variant = 0; variant < 4; ++variant) {
      FrameFeatures f;
      f.has_transparent = variant & 1;
      f.pose_pending = variant & 1;  // an animated scene's new pose: the skinning pass
      f.object_motion = variant & 1;  // ... that moved since the view's last frame (taa)
      f.local_lights = s.synthetic_lights;
      f.shadow_atlas_valid = f.taa_history_valid = f.exposure_valid = variant & 2;
      FramePlan plan = PlanFrame(s, f);
      std::vector<PassId> passes = plan.ids();
      out.push_back({s, f, std::move(plan), std::move(passes)});
    }
  }
  return out;
}

std::string Describe(const std::vector<PassId>& passes) {
  std::string out;
  for (PassId p : passes) out += Name(p) + " ";
  return out;
}

const std::vector<ResourceUse>& UsesOf(const FramePlan& plan, PassId id) {
  for (const PlannedPass& p : plan.passes)
    if (p.id == id) return p.uses;
  static const std::vector<ResourceUse> kNone;
  return kNone;
}

// ---------------------------------------------------------------------------------------------
// Passes

TEST(PassTest, NamesAreUniqueAndNonEmpty) {
  std::set<std::string> names;
  for (int i = 0; i < kPassCount; ++i) {
    const std::string name = Name(static_cast<PassId>(i));
    EXPECT_FALSE(name.empty()) << i;
    EXPECT_NE(name, "invalid") << i;
    EXPECT_TRUE(names.insert(name).second) << "duplicate pass name " << name;
  }
}

TEST(PassTest, EveryPassDeclaresItsUses) {
  std::set<PassId> planned;
  for (const PlanCase& c : AllPlans()) {
    for (const PlannedPass& p : c.plan.passes) {
      planned.insert(p.id);
      EXPECT_FALSE(p.uses.empty()) << Name(p.id);
      std::set<Resource> seen;
      for (const ResourceUse& u : p.uses) {
        EXPECT_LT(static_cast<size_t>(u.resource), kResourceCount) << Name(p.id);
        EXPECT_NE(u.access, Access::kNone) << Name(p.id);
        // One access per resource per pass: the plan moves a resource to a single state.
        EXPECT_TRUE(seen.insert(u.resource).second) << Name(p.id) << " uses a resource twice";
      }
    }
  }
  // Some combination plans every pass the renderer has.
  EXPECT_EQ(planned.size(), static_cast<size_t>(kPassCount));
}

TEST(SelectPassesTest, OrderIsFixed) {
  for (const PlanCase& c : AllPlans()) {
    const std::vector<PassId>& passes = c.passes;
    const std::string d = Describe(passes);
    // The visibility pass is the depth pass of vis_mlaa and of the visibility pipeline, their
    // shading passes the forward pass.
    const int prepass = std::max(IndexOf(passes, PassId::kDepthPrepass),
                                 IndexOf(passes, PassId::kVisibility));
    const int forward = std::max({IndexOf(passes, PassId::kForward),
                                  IndexOf(passes, PassId::kShade)});
    EXPECT_EQ(IndexOf(passes, PassId::kShade) >= 0,
              ShadesVisibility(c.settings) || c.settings.aa == AaMode::kVisMlaa)
        << d;
    const int transparent = IndexOf(passes, PassId::kTransparent);
    const int tonemap = IndexOf(passes, PassId::kTonemap);
    const int readback = IndexOf(passes, PassId::kReadback);
    ASSERT_GE(prepass, 0) << d;
    ASSERT_GE(forward, 0) << d;
    ASSERT_GE(tonemap, 0) << d;
    ASSERT_GE(readback, 0) << d;
    EXPECT_LT(prepass, forward) << d;
    EXPECT_LT(forward, tonemap) << d;
    EXPECT_LT(tonemap, readback) << d;
    EXPECT_EQ(transparent >= 0, c.features.has_transparent) << d;
    if (transparent >= 0) {
      EXPECT_LT(forward, transparent) << d;
      EXPECT_LT(transparent, tonemap) << d;
    }
    // Shadow maps and ambient obscurance exist before anything is shaded; ssao reads the depth.
    const int shadows = IndexOf(passes, PassId::kShadows);
    const int ao = IndexOf(passes, PassId::kSsao);
    EXPECT_EQ(shadows >= 0, c.settings.shadows) << d;
    if (shadows >= 0) {
      EXPECT_LT(shadows, forward) << d;
    }
    EXPECT_EQ(ao >= 0, c.settings.ssao) << d;
    if (ao >= 0) {
      EXPECT_LT(prepass, ao) << d;
      EXPECT_LT(ao, forward) << d;
    }
    EXPECT_EQ(IndexOf(passes, PassId::kLightCull) >= 0, c.features.local_lights > 0) << d;
    // Auto exposure and bloom read the final HDR colour (after AA and transparency), exposure
    // first: bloom thresholds in exposed units. Debug views do not move the exposure.
    const int exposure = IndexOf(passes, PassId::kExposure);
    const int bloom_pass = IndexOf(passes, PassId::kBloom);
    EXPECT_EQ(bloom_pass >= 0, c.settings.bloom) << d;
    EXPECT_EQ(exposure >= 0, c.settings.exposure_mode == ExposureMode::kAuto &&
                                 c.settings.debug_view == DebugView::kNone)
        << d;
    for (int p : {exposure, bloom_pass}) {
      if (p < 0) continue;
      EXPECT_LT(std::max({forward, transparent, IndexOf(passes, PassId::kTaa),
                          IndexOf(passes, PassId::kGeometricAa)}),
                p)
          << d;
      EXPECT_LT(p, tonemap) << d;
    }
    if (exposure >= 0 && bloom_pass >= 0) {
      EXPECT_LT(exposure, bloom_pass) << d;
    }
    // Optional inputs are read exactly when the effect that makes them runs.
    auto reads = [&](PassId id, Resource r) {
      const auto& uses = UsesOf(c.plan, id);
      return std::any_of(uses.begin(), uses.end(),
                         [&](const ResourceUse& u) { return u.resource == r; });
    };
    EXPECT_EQ(reads(PassId::kTonemap, Resource::kBloomUp), c.settings.bloom) << d;
    EXPECT_EQ(reads(PassId::kTonemap, Resource::kAo), c.settings.ssao) << d;
    EXPECT_EQ(reads(passes[forward], Resource::kAo), c.settings.ssao) << d;
    // The image is read back last, once everything has been drawn into it.
    EXPECT_EQ(readback, static_cast<int>(passes.size()) - 1) << d;
    // PassId is declared in the only order passes may run, and nothing runs twice.
    EXPECT_TRUE(std::is_sorted(passes.begin(), passes.end())) << d;
    EXPECT_EQ(std::adjacent_find(passes.begin(), passes.end()), passes.end()) << d;
  }
}

TEST(SelectPassesTest, DefaultFrame) {
  const std::vector<PassId> expected = {PassId::kDepthPrepass, PassId::kForward, PassId::kTonemap,
                                        PassId::kReadback};
  EXPECT_EQ(SelectPasses(Settings{}, FrameFeatures{}), expected);
}

TEST(SelectPassesTest, CullingModes) {
  Settings s;
  s.culling = CullingMode::kNone;
  const std::vector<PassId> cpu = {PassId::kDepthPrepass, PassId::kForward, PassId::kTonemap,
                                   PassId::kReadback};
  EXPECT_EQ(SelectPasses(s, {}), cpu);
  s.culling = CullingMode::kCpuFrustum;
  EXPECT_EQ(SelectPasses(s, {}), cpu);
  s.culling = CullingMode::kGpuFrustum;
  const std::vector<PassId> gpu_frustum = {PassId::kCull, PassId::kDepthPrepass, PassId::kForward,
                                           PassId::kTonemap, PassId::kReadback};
  EXPECT_EQ(SelectPasses(s, {}), gpu_frustum);
  s.culling = CullingMode::kGpuOcclusion;
  const std::vector<PassId> occlusion = {
      PassId::kCull,     PassId::kDepthPrepass,      PassId::kHizBuild,
      PassId::kCullLate, PassId::kDepthPrepassLate, PassId::kForward,
      PassId::kTonemap,  PassId::kReadback};
  EXPECT_EQ(SelectPasses(s, {}), occlusion);
}

TEST(SelectPassesTest, AaModes) {
  Settings s;
  s.aa = AaMode::kVisMlaa;
  const std::vector<PassId> vis = {PassId::kVisibility, PassId::kVisResolve, PassId::kVisClassify,
                                   PassId::kShade,      PassId::kGeometricAa, PassId::kTonemap,
                                   PassId::kReadback};
  EXPECT_EQ(SelectPasses(s, {}), vis);
  s.aa = AaMode::kTaa;
  const std::vector<PassId> taa = {PassId::kDepthPrepass, PassId::kForward, PassId::kTaa,
                                   PassId::kTonemap, PassId::kReadback};
  EXPECT_EQ(SelectPasses(s, {}), taa);
  s.aa = AaMode::kFxaa;
  const std::vector<PassId> fxaa = {PassId::kDepthPrepass, PassId::kForward, PassId::kTonemap,
                                    PassId::kFxaa, PassId::kReadback};
  EXPECT_EQ(SelectPasses(s, {}), fxaa);
  // msaa: the same passes, on multisampled targets resolved into the frame's depth and colour.
  s.aa = AaMode::kMsaa;
  EXPECT_EQ(SelectPasses(s, {}), SelectPasses(Settings{}, {}));
  const FramePlan msaa = PlanFrame(s, {});
  const std::vector<ResourceUse>& prepass = UsesOf(msaa, PassId::kDepthPrepass);
  EXPECT_TRUE(std::any_of(prepass.begin(), prepass.end(), [](const ResourceUse& u) {
    return u.resource == Resource::kDepth && u.access == Access::kDepthResolve;
  }));
  // Tonemapping reads what the last colour pass wrote.
  auto first_use = [](AaMode aa, PassId id) {
    Settings t;
    t.aa = aa;
    return UsesOf(PlanFrame(t, {}), id).at(0).resource;
  };
  // vis_mlaa's geometric AA changes the edge pixels of the HDR colour in place; its aa_mask
  // view draws every pixel into the post-AA colour.
  EXPECT_EQ(first_use(AaMode::kVisMlaa, PassId::kTonemap), Resource::kHdrColor);
  Settings mask;
  mask.aa = AaMode::kVisMlaa;
  mask.debug_view = DebugView::kAaMask;
  const FramePlan mask_plan = PlanFrame(mask, {});
  EXPECT_EQ(UsesOf(mask_plan, PassId::kTonemap).at(0).resource, Resource::kPostHdr);
  Settings edges;
  edges.aa = AaMode::kVisMlaa;
  const FramePlan edge_plan = PlanFrame(edges, {});
  const std::vector<ResourceUse>& geometric = UsesOf(edge_plan, PassId::kGeometricAa);
  EXPECT_TRUE(std::any_of(geometric.begin(), geometric.end(), [](const ResourceUse& u) {
    return u.resource == Resource::kShadeLists && u.access == Access::kIndirectRead;
  })) << "geometric AA dispatches over the resolve's edge list";
  // The runner-up surfaces: recorded by the resolve, listed by the classification, shaded (their
  // colours) by the shading, blended in by geometric AA, in that order.
  auto edge_surfaces = [&](PassId id) {
    for (const ResourceUse& u : UsesOf(edge_plan, id))
      if (u.resource == Resource::kEdgeSurfaces) return u.access;
    return Access::kNone;
  };
  EXPECT_EQ(edge_surfaces(PassId::kVisResolve), Access::kComputeWrite);
  EXPECT_EQ(edge_surfaces(PassId::kVisClassify), Access::kComputeRead);
  EXPECT_EQ(edge_surfaces(PassId::kShade), Access::kComputeWrite);
  EXPECT_EQ(edge_surfaces(PassId::kGeometricAa), Access::kComputeWrite);
  EXPECT_EQ(first_use(AaMode::kTaa, PassId::kTonemap), Resource::kPostHdr);
  EXPECT_EQ(first_use(AaMode::kMsaa, PassId::kTonemap), Resource::kHdrColor);
  EXPECT_EQ(first_use(AaMode::kFxaa, PassId::kReadback), Resource::kFxaaColor);
}

TEST(SelectPassesTest, ObjectMotionOnlyUnderTaa) {
  // Animated geometry that moved since the view's last frame: with taa the motion pass draws its
  // motion against the final depth, and TAA reads it; other AA modes need none.
  FrameFeatures moved;
  moved.object_motion = true;
  Settings s;
  EXPECT_EQ(IndexOf(SelectPasses(s, moved), PassId::kMotion), -1);
  s.aa = AaMode::kTaa;
  const std::vector<PassId> taa = {PassId::kDepthPrepass, PassId::kForward, PassId::kMotion,
                                   PassId::kTaa,          PassId::kTonemap, PassId::kReadback};
  EXPECT_EQ(SelectPasses(s, moved), taa);
  const FramePlan plan = PlanFrame(s, moved);
  auto uses = [&](PassId id, Resource r, Access a) {
    const std::vector<ResourceUse>& u = UsesOf(plan, id);
    return std::any_of(u.begin(), u.end(), [&](const ResourceUse& x) {
      return x.resource == r && x.access == a;
    });
  };
  EXPECT_TRUE(uses(PassId::kMotion, Resource::kDepth, Access::kDepthTest));
  EXPECT_TRUE(uses(PassId::kMotion, Resource::kMotion, Access::kColorWrite));
  EXPECT_TRUE(uses(PassId::kTaa, Resource::kMotion, Access::kSampled));
  EXPECT_FALSE(uses(PassId::kTaa, Resource::kMotion, Access::kComputeRead));
  // Nothing moved: TAA alone, reading no motion.
  const FramePlan still = PlanFrame(s, {});
  EXPECT_FALSE(still.Has(PassId::kMotion));
  for (const ResourceUse& u : UsesOf(still, PassId::kTaa)) EXPECT_NE(u.resource, Resource::kMotion);
}

TEST(SelectPassesTest, VisibilityPipeline) {
  Settings s;
  s.pipeline = Pipeline::kVisibility;
  const std::vector<PassId> plain = {PassId::kVisibility, PassId::kVisClassify, PassId::kShade,
                                     PassId::kTonemap, PassId::kReadback};
  EXPECT_EQ(SelectPasses(s, {}), plain);
  s.aa = AaMode::kTaa;
  const std::vector<PassId> taa = {PassId::kVisibility, PassId::kVisClassify, PassId::kShade,
                                   PassId::kTaa,        PassId::kTonemap,     PassId::kReadback};
  EXPECT_EQ(SelectPasses(s, {}), taa);
  s.aa = AaMode::kNone;
  s.culling = CullingMode::kGpuOcclusion;
  const std::vector<PassId> occlusion = {
      PassId::kCull,       PassId::kVisibility,      PassId::kHizBuild,
      PassId::kCullLate,   PassId::kVisibilityLate,  PassId::kVisClassify,
      PassId::kShade,      PassId::kTonemap,         PassId::kReadback};
  EXPECT_EQ(SelectPasses(s, {}), occlusion);
  // One sample, straight into the frame's depth; the shading reads the ids, writes the colour
  // in compute and dispatches from the classification's lists.
  const FramePlan plan = PlanFrame(s, {});
  auto uses = [&](PassId id, Resource r, Access a) {
    const std::vector<ResourceUse>& u = UsesOf(plan, id);
    return std::any_of(u.begin(), u.end(),
                       [&](const ResourceUse& x) { return x.resource == r && x.access == a; });
  };
  EXPECT_TRUE(uses(PassId::kVisibility, Resource::kDepth, Access::kDepthWrite));
  EXPECT_TRUE(uses(PassId::kVisibility, Resource::kVisId, Access::kColorWrite));
  EXPECT_TRUE(uses(PassId::kVisClassify, Resource::kShadeLists, Access::kComputeWrite));
  EXPECT_TRUE(uses(PassId::kVisClassify, Resource::kHdrColor, Access::kComputeWrite));  // sky
  EXPECT_TRUE(uses(PassId::kShade, Resource::kShadeLists, Access::kIndirectRead));
  EXPECT_TRUE(uses(PassId::kShade, Resource::kHdrColor, Access::kComputeWrite));
  // Where the shading is one dispatch over every pixel (DeviceInfo::shade_all_materials): no
  // classification; the shading writes the sky and counts in the entries (vis_mlaa: after its
  // resolve, and its runner-ups' colours for geometric AA).
  FrameFeatures one;
  one.shade_all_materials = true;
  s.culling = CullingMode::kNone;
  EXPECT_EQ(SelectPasses(s, one), (std::vector<PassId>{PassId::kVisibility, PassId::kShade,
                                                       PassId::kTonemap, PassId::kReadback}));
  for (AaMode aa : {AaMode::kNone, AaMode::kVisMlaa}) {
    Settings o = s;
    o.aa = aa;
    const FramePlan p = PlanFrame(o, one);
    EXPECT_FALSE(p.Has(PassId::kVisClassify));
    const std::vector<ResourceUse>& u = UsesOf(p, PassId::kShade);
    auto shade_uses = [&](Resource r, Access a) {
      return std::any_of(u.begin(), u.end(),
                         [&](const ResourceUse& x) { return x.resource == r && x.access == a; });
    };
    EXPECT_TRUE(shade_uses(Resource::kShadeLists, Access::kComputeWrite));
    EXPECT_TRUE(shade_uses(Resource::kHdrColor, Access::kComputeWrite));
    EXPECT_EQ(shade_uses(Resource::kEdgeSurfaces, Access::kComputeWrite), aa == AaMode::kVisMlaa);
    if (aa == AaMode::kVisMlaa) {
      EXPECT_TRUE(p.Has(PassId::kVisResolve));
      EXPECT_TRUE(p.Has(PassId::kGeometricAa));
    }
  }
  s.culling = CullingMode::kGpuOcclusion;
  // msaa and vis_mlaa are not changed by the setting.
  for (AaMode aa : {AaMode::kMsaa, AaMode::kVisMlaa}) {
    Settings f;
    f.aa = aa;
    Settings v = f;
    v.pipeline = Pipeline::kVisibility;
    EXPECT_EQ(SelectPasses(v, {}), SelectPasses(f, {})) << ToString(aa);
  }
}

// vis_mlaa_coverage: raster draws the samples into the multisampled targets and resolves the
// depth; analytic draws one sample straight into the frame's depth and its own id target, the
// same passes either way.
TEST(SelectPassesTest, VisMlaaCoverage) {
  Settings raster;
  raster.aa = AaMode::kVisMlaa;
  raster.vis_mlaa_coverage = VisMlaaCoverage::kRaster;
  Settings analytic = raster;
  analytic.vis_mlaa_coverage = VisMlaaCoverage::kAnalytic;
  EXPECT_EQ(SelectPasses(raster, {}), SelectPasses(analytic, {}));
  auto uses = [](const Settings& s, PassId id, Resource r, Access a) {
    const FramePlan plan = PlanFrame(s, {});
    const std::vector<ResourceUse>& u = UsesOf(plan, id);
    return std::any_of(u.begin(), u.end(),
                       [&](const ResourceUse& x) { return x.resource == r && x.access == a; });
  };
  EXPECT_TRUE(uses(raster, PassId::kVisibility, Resource::kDepthMs, Access::kDepthWrite));
  EXPECT_TRUE(uses(raster, PassId::kVisibility, Resource::kDepth, Access::kDepthResolve));
  EXPECT_FALSE(uses(analytic, PassId::kVisibility, Resource::kDepthMs, Access::kDepthWrite));
  EXPECT_TRUE(uses(analytic, PassId::kVisibility, Resource::kDepth, Access::kDepthWrite));
  for (const Settings& s : {raster, analytic}) {
    EXPECT_TRUE(uses(s, PassId::kVisibility, Resource::kVisMs, Access::kColorWrite));
    EXPECT_TRUE(uses(s, PassId::kVisResolve, Resource::kVisMs, Access::kComputeRead));
    EXPECT_TRUE(uses(s, PassId::kVisResolve, Resource::kVisId, Access::kComputeWrite));
  }
}

// ---------------------------------------------------------------------------------------------
// The plan's transitions

const Transition* FindTransition(const std::vector<Transition>& ts, Resource r) {
  for (const Transition& t : ts)
    if (t.resource == r) return &t;
  return nullptr;
}

const std::vector<Transition>& BeforeOf(const FramePlan& plan, PassId id) {
  for (const PlannedPass& p : plan.passes)
    if (p.id == id) return p.before;
  static const std::vector<Transition> kNone;
  return kNone;
}

TEST(PlanTransitionsTest, OcclusionCullingMovesDepthAndPyramid) {
  Settings s;
  s.culling = CullingMode::kGpuOcclusion;
  const FramePlan plan = PlanFrame(s, {});
  // The pyramid is written in the general layout, then read by the late cull.
  const Transition* hiz = FindTransition(BeforeOf(plan, PassId::kHizBuild), Resource::kHiz);
  ASSERT_NE(hiz, nullptr);
  EXPECT_EQ(hiz->to, Access::kComputeWrite);
  hiz = FindTransition(BeforeOf(plan, PassId::kCullLate), Resource::kHiz);
  ASSERT_NE(hiz, nullptr);
  EXPECT_EQ(hiz->from, Access::kComputeWrite);
  EXPECT_EQ(hiz->to, Access::kComputeRead);
  // The first phase's depth is sampled for the pyramid, then written again by the late phase
  // (from a defined layout, so its contents are kept).
  const Transition* depth =
      FindTransition(BeforeOf(plan, PassId::kDepthPrepassLate), Resource::kDepth);
  ASSERT_NE(depth, nullptr);
  EXPECT_EQ(depth->from, Access::kComputeRead);
  EXPECT_EQ(depth->to, Access::kDepthWrite);
}

TEST(PlanTransitionsTest, BuilderDerivesTransitions) {
  Settings s;
  GraphBuilder b(s, {});
  EXPECT_TRUE(std::move(b).Build().passes.empty());
  GraphBuilder b2(s, {});
  b2.Pass(PassId::kDepthPrepass).Use(Resource::kDepth, Access::kDepthWrite);
  // An optional input nobody wrote is not used at all.
  b2.Pass(PassId::kForward)
      .Use(Resource::kDepth, Access::kDepthTest)
      .UseIfPresent(Resource::kAo, Access::kSampled);
  EXPECT_FALSE(b2.Written(Resource::kAo));
  EXPECT_TRUE(b2.Written(Resource::kDepth));
  const FramePlan plan = std::move(b2).Build();
  ASSERT_EQ(plan.passes.size(), 2u);
  EXPECT_EQ(plan.passes[1].uses.size(), 1u);
  EXPECT_EQ(plan.FinalAccess(Resource::kDepth), Access::kDepthTest);
  EXPECT_EQ(plan.FinalAccess(Resource::kAo), Access::kNone);
  ASSERT_EQ(plan.passes[0].before.size(), 1u);
  EXPECT_EQ(plan.passes[0].before[0].from, Access::kNone);
}

TEST(PlanTransitionsTest, FirstUseTransitionsFromTheImportOrNone) {
  for (const PlanCase& c : AllPlans()) {
    std::array<bool, kResourceCount> used{};
    for (const PlannedPass& p : c.plan.passes) {
      for (const ResourceUse& u : p.uses) {
        const size_t r = static_cast<size_t>(u.resource);
        if (used[r]) continue;
        used[r] = true;
        const Access initial = InitialAccess(c.plan, u.resource);
        const Transition* t = FindTransition(p.before, u.resource);
        if (initial == u.access && IsRead(u.access)) {  // already readable as it comes in
          EXPECT_EQ(t, nullptr) << Describe(c.passes) << " " << Name(p.id);
          continue;
        }
        ASSERT_NE(t, nullptr) << Describe(c.passes) << ": no first-use transition in "
                              << Name(p.id);
        EXPECT_EQ(t->from, initial) << Describe(c.passes) << " " << Name(p.id);
        EXPECT_EQ(t->to, u.access) << Describe(c.passes) << " " << Name(p.id);
      }
    }
  }
}

// The long-lived resources enter each frame as the last one left them and leave as the next
// one expects: taa's history (last frame's read, this frame's written then readable), the
// shadow atlas (sampled between frames), auto exposure's state (general layout).
TEST(PlanTransitionsTest, ImportsEnterAndLeaveInTheirStates) {
  for (const PlanCase& c : AllPlans()) {
    const std::string d = Describe(c.passes);
    auto imported = [&](Resource r) {
      return InitialAccess(c.plan, r) != Access::kNone || c.plan.FinalAccess(r) != Access::kNone;
    };
    EXPECT_EQ(imported(Resource::kShadowAtlas), c.settings.shadows) << d;
    EXPECT_EQ(imported(Resource::kTaaHistoryNext), c.settings.aa == AaMode::kTaa) << d;
    EXPECT_EQ(imported(Resource::kExposureState), c.settings.exposure_mode == ExposureMode::kAuto)
        << d;
    EXPECT_TRUE(imported(Resource::kDrawLists)) << d;  // every frame draws from the lists
    EXPECT_EQ(imported(Resource::kVisibilityBits), c.settings.culling == CullingMode::kGpuOcclusion)
        << d;
    EXPECT_EQ(imported(Resource::kLightLists), c.features.local_lights > 0) << d;
    EXPECT_EQ(imported(Resource::kEdgeSurfaces), c.settings.aa == AaMode::kVisMlaa) << d;
    for (const ResourceImport& i : c.plan.imports) {
      EXPECT_EQ(c.plan.FinalAccess(i.resource), i.final) << d << int(i.resource);
      if (IsBuffer(i.resource)) continue;
      // What a frame imports holding earlier frames it keeps: nothing enters undefined unless
      // the features say it holds nothing (or, for this frame's output, will be overwritten).
      const bool valid = i.resource == Resource::kShadowAtlas     ? c.features.shadow_atlas_valid
                         : i.resource == Resource::kTaaHistory    ? c.features.taa_history_valid
                         : i.resource == Resource::kExposureState ? c.features.exposure_valid
                                                                  : false;
      EXPECT_EQ(i.initial != Access::kNone, valid) << d << int(i.resource);
    }
  }
  // The atlas is loaded (its cached faces kept): from the sampled layout into the attachment.
  Settings s;
  s.shadows = true;
  FrameFeatures f;
  f.shadow_atlas_valid = true;
  const FramePlan plan = PlanFrame(s, f);
  const Transition* t = FindTransition(BeforeOf(plan, PassId::kShadows), Resource::kShadowAtlas);
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->from, Access::kSampled);
  EXPECT_EQ(t->to, Access::kDepthWrite);
}

TEST(PlanTransitionsTest, NoBarrierForReadAfterReadInTheSameLayout) {
  // Forward then transparent both depth-test: the depth buffer stays as it is.
  FrameFeatures f;
  f.has_transparent = true;
  const FramePlan plan = PlanFrame(Settings{}, f);
  const std::vector<PassId> expected = {PassId::kDepthPrepass, PassId::kForward,
                                        PassId::kTransparent, PassId::kTonemap, PassId::kReadback};
  ASSERT_EQ(plan.ids(), expected);
  EXPECT_EQ(FindTransition(plan.passes[2].before, Resource::kDepth), nullptr);
  // But depth written by the prepass and then tested by forward is a read-after-write hazard.
  const Transition* t = FindTransition(plan.passes[1].before, Resource::kDepth);
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->from, Access::kDepthWrite);
  EXPECT_EQ(t->to, Access::kDepthTest);
}

TEST(PlanTransitionsTest, BarrierBetweenReadsInDifferentStages) {
  // Light culling reads the depth in a compute shader, ssao then samples it in a fragment
  // shader: the barrier after the prepass made its writes visible to compute only.
  Settings s;
  s.ssao = true;
  s.synthetic_lights = 4;
  FrameFeatures f;
  f.local_lights = 4;
  const FramePlan plan = PlanFrame(s, f);
  const std::vector<PassId> passes = plan.ids();
  ASSERT_GT(IndexOf(passes, PassId::kSsao), IndexOf(passes, PassId::kLightCull));
  const Transition* t = FindTransition(BeforeOf(plan, PassId::kSsao), Resource::kDepth);
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->from, Access::kComputeRead);
  EXPECT_EQ(t->to, Access::kSampled);
  // The same for the colour auto exposure reads in compute, then tonemap in a fragment shader.
  s.exposure_mode = ExposureMode::kAuto;
  const FramePlan plan2 = PlanFrame(s, f);
  t = FindTransition(BeforeOf(plan2, PassId::kTonemap), Resource::kHdrColor);
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->from, Access::kComputeRead);
}

TEST(PlanTransitionsTest, BarrierForWriteAfterWrite) {
  // Transparent blends over forward's HDR colour: same layout, but both write.
  FrameFeatures f;
  f.has_transparent = true;
  const FramePlan plan = PlanFrame(Settings{}, f);
  const Transition* t = FindTransition(BeforeOf(plan, PassId::kTransparent), Resource::kHdrColor);
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->from, Access::kColorWrite);
  EXPECT_EQ(t->to, Access::kColorWrite);
}

// Replays the plan on a state table: every transition starts from the resource's current
// state, and once a pass's transitions are applied every declared use is in its access.
TEST(PlanTransitionsTest, SimulatedPlanPutsEveryUseInItsState) {
  for (const PlanCase& c : AllPlans()) {
    const std::string d = Describe(c.passes);
    std::array<Access, kResourceCount> state;
    state.fill(Access::kNone);
    for (const ResourceImport& i : c.plan.imports)
      state[static_cast<size_t>(i.resource)] = i.initial;
    for (const PlannedPass& p : c.plan.passes) {
      std::set<Resource> moved;
      for (const Transition& t : p.before) {
        const size_t r = static_cast<size_t>(t.resource);
        ASSERT_LT(r, kResourceCount);
        EXPECT_EQ(t.from, state[r]) << d << Name(p.id) << ": stale 'from'";
        EXPECT_NE(t.to, Access::kNone) << d << Name(p.id);
        EXPECT_TRUE(moved.insert(t.resource).second) << d << Name(p.id) << ": twice";
        state[r] = t.to;
      }
      for (const ResourceUse& u : p.uses) {
        EXPECT_EQ(state[static_cast<size_t>(u.resource)], u.access)
            << d << "before " << Name(p.id) << " resource " << static_cast<int>(u.resource);
      }
      // Transitions only for what the pass uses.
      for (const Transition& t : p.before) {
        EXPECT_TRUE(std::any_of(p.uses.begin(), p.uses.end(),
                                [&](const ResourceUse& u) { return u.resource == t.resource; }))
            << d << Name(p.id) << " transitions a resource it does not use";
      }
    }
    for (const Transition& t : c.plan.after) {
      const size_t r = static_cast<size_t>(t.resource);
      EXPECT_EQ(t.from, state[r]) << d << "after: stale 'from'";
      state[r] = t.to;
    }
    for (size_t r = 0; r < kResourceCount; ++r)
      EXPECT_EQ(c.plan.FinalAccess(static_cast<Resource>(r)), state[r]) << d << r;
  }
}

TEST(PlanTransitionsTest, NothingIsReadBeforeItIsWritten) {
  for (const PlanCase& c : AllPlans()) {
    std::array<bool, kResourceCount> written{};
    for (const ResourceImport& i : c.plan.imports)  // imported holding earlier frames
      written[static_cast<size_t>(i.resource)] = i.initial != Access::kNone;
    for (const PlannedPass& p : c.plan.passes) {
      for (const ResourceUse& u : p.uses) {
        const size_t r = static_cast<size_t>(u.resource);
        // The first culling phase binds the pyramid (one pipeline for both phases) but never
        // reads it: only the late phase tests occlusion.
        if (p.id == PassId::kCull && u.resource == Resource::kHiz) continue;
        // taa binds the history a new view does not have yet; its shader then ignores it (the
        // push constant says the history is not valid).
        if (p.id == PassId::kTaa && u.resource == Resource::kTaaHistory) continue;
        // A debug view (other than bloom's) is not exposed, so no exposure pass fills a new
        // view's state; bloom and tonemap bind it, and what they compute from it is not shown.
        if (u.resource == Resource::kExposureState && c.settings.debug_view != DebugView::kNone &&
            c.settings.debug_view != DebugView::kBloom)
          continue;
        if (IsRead(u.access)) {
          EXPECT_TRUE(written[r]) << Describe(c.passes) << ": " << Name(p.id)
                                  << " reads resource " << r << " before any pass wrote it";
        }
      }
      for (const ResourceUse& u : p.uses)
        if (IsWrite(u.access)) written[static_cast<size_t>(u.resource)] = true;
    }
  }
}

TEST(PlanTransitionsTest, EveryHazardHasABarrier) {
  // Whenever a use follows a write, or changes the access class, the plan has a transition.
  for (const PlanCase& c : AllPlans()) {
    std::array<Access, kResourceCount> last;
    last.fill(Access::kNone);
    for (const ResourceImport& i : c.plan.imports)
      last[static_cast<size_t>(i.resource)] = i.initial;
    for (const PlannedPass& p : c.plan.passes) {
      for (const ResourceUse& u : p.uses) {
        const size_t r = static_cast<size_t>(u.resource);
        // Only read-after-read in the same access may skip the barrier.
        const bool same_read = last[r] == u.access && IsRead(u.access);
        if (!same_read) {
          EXPECT_NE(FindTransition(p.before, u.resource), nullptr)
              << Describe(c.passes) << Name(p.id) << " resource " << r;
        }
        last[r] = u.access;
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// PlanDraws

DrawItem Item(uint32_t drawable, AlphaMode alpha, bool double_sided, uint32_t material) {
  DrawItem d;
  d.drawable = drawable;
  d.alpha = alpha;
  d.double_sided = double_sided;
  d.material = material;
  d.index_count = 3 * (drawable + 1);
  return d;
}

TEST(PlanDrawsTest, SegmentsAndBatchesCoverTheItemsInOrder) {
  std::vector<DrawItem> draws;
  const AlphaMode modes[] = {AlphaMode::kOpaque, AlphaMode::kMask, AlphaMode::kBlend};
  for (uint32_t i = 0; i < 60; ++i)
    draws.push_back(Item(i, modes[(i * 7) % 3], (i % 5) == 0, (i * 13) % 4));
  const DrawPlan plan = PlanDraws(draws);
  ASSERT_EQ(plan.order.size(), draws.size());
  std::vector<uint32_t> sorted = plan.order;
  std::sort(sorted.begin(), sorted.end());
  for (uint32_t i = 0; i < sorted.size(); ++i) ASSERT_EQ(sorted[i], i) << "a permutation";
  // Segments tile the items in order, each with one state; group order opaque, mask, blend.
  uint32_t next = 0;
  for (const DrawSegment& seg : plan.segments) {
    EXPECT_EQ(seg.first_item, next);
    ASSERT_GT(seg.item_count, 0u);
    for (uint32_t i = seg.first_item; i < seg.first_item + seg.item_count; ++i) {
      const DrawItem& d = draws[plan.order[i]];
      EXPECT_EQ(d.alpha, seg.group);
      if (seg.group != AlphaMode::kBlend) {
        EXPECT_EQ(d.double_sided, seg.double_sided);
        EXPECT_EQ(d.material, seg.material);
      }
      if (i > 0) {
        EXPECT_LE(static_cast<uint32_t>(draws[plan.order[i - 1]].alpha),
                  static_cast<uint32_t>(d.alpha));
      }
    }
    // Blending is sorted per frame: each blended draw is its own segment.
    if (seg.group == AlphaMode::kBlend) {
      EXPECT_EQ(seg.item_count, 1u);
    }
    next += seg.item_count;
  }
  EXPECT_EQ(next, draws.size());
  // Adjacent non-blend segments differ in state (no needless split).
  for (size_t k = 1; k < plan.segments.size(); ++k) {
    const DrawSegment& a = plan.segments[k - 1];
    const DrawSegment& b = plan.segments[k];
    if (b.group != AlphaMode::kBlend) {
      EXPECT_TRUE(a.group != b.group || a.double_sided != b.double_sided ||
                  a.material != b.material);
    }
  }
  // Batches: exactly the opaque items, one per cull mode.
  uint32_t opaque = 0;
  for (const DrawItem& d : draws) opaque += d.alpha == AlphaMode::kOpaque;
  uint32_t batched = 0;
  EXPECT_LE(plan.batches.size(), 2u);
  for (const DrawBatch& b : plan.batches) {
    for (uint32_t i = b.first_item; i < b.first_item + b.item_count; ++i) {
      EXPECT_EQ(draws[plan.order[i]].alpha, AlphaMode::kOpaque);
      EXPECT_EQ(draws[plan.order[i]].double_sided, b.double_sided);
    }
    batched += b.item_count;
  }
  EXPECT_EQ(batched, opaque);
}

TEST(PlanDrawsTest, EmptyScene) {
  const DrawPlan plan = PlanDraws({});
  EXPECT_TRUE(plan.order.empty());
  EXPECT_TRUE(plan.segments.empty());
  EXPECT_TRUE(plan.batches.empty());
}

// ---------------------------------------------------------------------------------------------
// PlanTextureBuckets

Texture MakeTexture(uint32_t w, uint32_t h, bool srgb) {
  auto image = std::make_shared<Image>();
  image->name = std::to_string(w) + "x" + std::to_string(h);
  image->width = w;
  image->height = h;
  Texture t;
  t.image = image;
  t.srgb = srgb;
  return t;
}

bool IsPow2(uint32_t v) { return v != 0 && std::has_single_bit(v); }

// The structural rules every plan must follow, whatever the inputs.
void ExpectValidPlan(const std::vector<Texture>& textures, const TextureBucketPlan& plan,
                     uint32_t max_size, const std::string& what) {
  EXPECT_LE(plan.buckets.size(), gpu::kMaxTextureBuckets) << what;
  ASSERT_EQ(plan.slots.size(), textures.size()) << what;
  for (const auto& b : plan.buckets) {
    EXPECT_TRUE(IsPow2(b.width)) << what << ": width " << b.width;
    EXPECT_TRUE(IsPow2(b.height)) << what << ": height " << b.height;
    EXPECT_LE(b.width, max_size) << what;
    EXPECT_LE(b.height, max_size) << what;
    EXPECT_GT(b.layers, 0u) << what << ": empty bucket";
  }
  std::vector<std::set<uint32_t>> layers(plan.buckets.size());
  for (size_t t = 0; t < textures.size(); ++t) {
    const auto& slot = plan.slots[t];
    ASSERT_LT(slot.bucket, plan.buckets.size()) << what << ": texture " << t;
    const auto& bucket = plan.buckets[slot.bucket];
    // One sampler2DArray has one format: sRGB and linear textures never share a bucket.
    EXPECT_EQ(bucket.srgb, textures[t].srgb) << what << ": texture " << t;
    EXPECT_LT(slot.layer, bucket.layers) << what << ": texture " << t;
    EXPECT_TRUE(layers[slot.bucket].insert(slot.layer).second)
        << what << ": layer " << slot.layer << " of bucket " << slot.bucket << " used twice";
  }
  // Layers 0..n-1 are all used: no holes in the arrays.
  for (size_t b = 0; b < plan.buckets.size(); ++b)
    EXPECT_EQ(layers[b].size(), plan.buckets[b].layers) << what << ": bucket " << b;
}

TEST(PlanTextureBucketsTest, FewSizesKeepTheirRoundedSize) {
  struct Input {
    uint32_t w, h;
    bool srgb;
    uint32_t expect_w, expect_h;
  };
  const std::vector<Input> inputs = {
      {1024, 1024, true, 1024, 1024},  {512, 512, true, 512, 512},
      {1000, 1000, true, 1024, 1024},  // nearest power of two
      {300, 200, false, 256, 256},     // 300 -> 256, 200 -> 256 (nearest in log space)
      {1024, 1024, false, 1024, 1024}, {512, 512, false, 512, 512},
      {2048, 512, true, 2048, 512},  // non-square stays non-square
  };
  std::vector<Texture> textures;
  for (const Input& in : inputs) textures.push_back(MakeTexture(in.w, in.h, in.srgb));
  const TextureBucketPlan plan = PlanTextureBuckets(textures, 4096);
  ExpectValidPlan(textures, plan, 4096, "few sizes");
  for (size_t i = 0; i < inputs.size(); ++i) {
    const auto& b = plan.buckets[plan.slots[i].bucket];
    EXPECT_EQ(b.width, inputs[i].expect_w) << "texture " << i;
    EXPECT_EQ(b.height, inputs[i].expect_h) << "texture " << i;
  }
  // 1000x1000 sRGB shares the 1024x1024 sRGB bucket; the linear 1024 does not.
  EXPECT_EQ(plan.slots[2].bucket, plan.slots[0].bucket);
  EXPECT_NE(plan.slots[4].bucket, plan.slots[0].bucket);
}

TEST(PlanTextureBucketsTest, SizesClampedToMaxSize) {
  const std::vector<Texture> textures = {MakeTexture(8192, 8192, true),
                                         MakeTexture(5000, 100, false)};
  for (uint32_t max_size : {4096u, 2048u, 3000u}) {
    const TextureBucketPlan plan = PlanTextureBuckets(textures, max_size);
    ExpectValidPlan(textures, plan, max_size, "max_size " + std::to_string(max_size));
  }
}

TEST(PlanTextureBucketsTest, TwentySizesFitInTheBucketLimit) {
  std::vector<Texture> textures;
  // 20 distinct rounded sizes, in both colour spaces, plus repeats.
  const std::vector<uint32_t> sides = {4, 8, 16, 32, 64, 128, 256, 512, 1024, 2048};
  for (size_t i = 0; i < sides.size(); ++i) {
    textures.push_back(MakeTexture(sides[i], sides[i], i % 2 == 0));
    textures.push_back(MakeTexture(sides[i], sides[(i + 3) % sides.size()], i % 2 == 1));
    textures.push_back(MakeTexture(sides[i] + 1, sides[i], true));  // rounds back to sides[i]
  }
  const TextureBucketPlan plan = PlanTextureBuckets(textures, 4096);
  ExpectValidPlan(textures, plan, 4096, "20 sizes");
  EXPECT_EQ(plan.buckets.size(), gpu::kMaxTextureBuckets);  // merged down to the limit exactly
}

TEST(PlanTextureBucketsTest, ManySizesOneColourSpaceAndMixed) {
  for (bool mixed : {false, true}) {
    std::vector<Texture> textures;
    for (uint32_t w = 4; w <= 4096; w *= 2)
      for (uint32_t h : {w, w / 2 + 1})  // several aspect ratios per width
        textures.push_back(MakeTexture(w, h, mixed ? (w / 4) % 3 == 0 : true));
    const TextureBucketPlan plan = PlanTextureBuckets(textures, 4096);
    ExpectValidPlan(textures, plan, 4096, mixed ? "mixed" : "srgb only");
  }
}

TEST(PlanTextureBucketsTest, EdgeCases) {
  // No textures: nothing to plan.
  const TextureBucketPlan empty = PlanTextureBuckets({}, 4096);
  EXPECT_TRUE(empty.buckets.empty());
  EXPECT_TRUE(empty.slots.empty());

  // Tiny, 1x1 and missing images still get a slot in a valid bucket.
  std::vector<Texture> textures = {MakeTexture(1, 1, true), MakeTexture(3, 7, false),
                                   MakeTexture(0, 0, false)};
  textures.push_back(Texture{});  // no image at all
  const TextureBucketPlan plan = PlanTextureBuckets(textures, 4096);
  ExpectValidPlan(textures, plan, 4096, "edge cases");
}

TEST(PlanTextureBucketsTest, SameInputSamePlan) {
  // Deterministic: the upload and the material table are built from separate calls.
  std::vector<Texture> textures;
  for (uint32_t i = 0; i < 40; ++i)
    textures.push_back(MakeTexture(17 * i + 5, 300 + 31 * i, i % 3 == 0));
  const TextureBucketPlan a = PlanTextureBuckets(textures, 4096);
  const TextureBucketPlan b = PlanTextureBuckets(textures, 4096);
  ASSERT_EQ(a.slots.size(), b.slots.size());
  for (size_t i = 0; i < a.slots.size(); ++i) {
    EXPECT_EQ(a.slots[i].bucket, b.slots[i].bucket);
    EXPECT_EQ(a.slots[i].layer, b.slots[i].layer);
  }
  ExpectValidPlan(textures, a, 4096, "40 textures");
}

}  // namespace
}  // namespace tessera

namespace tessera {
namespace {

// The shading passes key their pipelines on ShadingConstants::Key() and build them from
// FromKey(key).Values(): packing must lose nothing and keep distinct constants apart.
TEST(ShadingConstantsTest, KeysRoundTripAndNeverCollide) {
  std::set<uint32_t> keys;
  size_t count = 0;
  for (uint32_t effects = 0; effects < 32; ++effects)
    for (uint32_t textures = 0; textures <= gpu::kMaterialTexturesAll; ++textures)
      for (uint32_t debug : {gpu::kDebugNone, gpu::kDebugNormals, gpu::kDebugDepth,
                             gpu::kDebugBaseColor, gpu::kDebugLightHeatmap, gpu::kDebugCascades})
        for (uint32_t vis_texels = 0; vis_texels < 2; ++vis_texels)
          for (uint32_t light_texels = 0; light_texels < 2; ++light_texels) {
            const ShadingConstants c{effects, textures, debug, vis_texels, light_texels};
            const uint32_t key = c.Key();
            ASSERT_LT(key, 1u << kShadingKeyBits);
            const ShadingConstants back = ShadingConstants::FromKey(key);
            ASSERT_EQ(back.Values(), c.Values()) << key;
            keys.insert(key);
            ++count;
          }
  EXPECT_EQ(keys.size(), count);
  // Values() is in constant_id order: effects, textures, debug view, vis.glsl's texels, lights'.
  EXPECT_EQ((ShadingConstants{1, 2, 3, 0, 1}.Values()), (std::vector<uint32_t>{1, 2, 3, 0, 1}));
}

TEST(ShadingConstantsTest, FollowTheSettingsAndTheFrame) {
  Settings s;
  s.shadows = true;
  s.ibl = true;
  s.debug_view = DebugView::kNormals;
  FrameFeatures features;
  features.light_texels = true;
  const ShadingConstants c = ShadingConstantsFor(s, features, 5u);
  EXPECT_EQ(c.effects, gpu::kShadowsOn | gpu::kIblOn);
  EXPECT_EQ(c.textures, 5u);
  EXPECT_EQ(c.debug, gpu::kDebugNormals);
  EXPECT_EQ(c.light_texels, 1u);
  EXPECT_EQ(c.vis_texels, 0u);  // the visibility shading sets it from its scene
  features.light_texels = false;
  EXPECT_EQ(ShadingConstantsFor(Settings{}, features, 0u).Key(), 0u);
  // The tile lists' loop only in frames with local lights.
  features.local_lights = 3;
  EXPECT_EQ(ShadingConstantsFor(s, features, 5u).effects,
            gpu::kShadowsOn | gpu::kIblOn | gpu::kLocalLightsOn);
  EXPECT_EQ(ShadingConstantsFor(Settings{}, features, 0u).effects, gpu::kLocalLightsOn);
  // The global lights' loop only where it has lights: any without shadows; with shadows, more
  // than the one shaded on its own.
  features.local_lights = 0;
  features.global_lights = 1;
  EXPECT_EQ(ShadingConstantsFor(s, features, 5u).effects, gpu::kShadowsOn | gpu::kIblOn);
  EXPECT_EQ(ShadingConstantsFor(Settings{}, features, 0u).effects, gpu::kGlobalLightsOn);
  features.global_lights = 2;
  EXPECT_EQ(ShadingConstantsFor(s, features, 5u).effects,
            gpu::kShadowsOn | gpu::kIblOn | gpu::kGlobalLightsOn);
}

}  // namespace
}  // namespace tessera
