// Renderer planning logic that needs no device: the frame graph's pass selection and barrier
// plan, and the texture bucketing of GpuScene.
#include "renderer/frame_graph.h"

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
         a == Access::kDepthResolve;
}
bool IsRead(Access a) {
  return a == Access::kDepthTest || a == Access::kSampled || a == Access::kTransferSrc ||
         a == Access::kComputeRead;
}

// Settings that select different features; pass selection must hold its invariants for all.
std::vector<Settings> SettingsVariants() {
  std::vector<Settings> out(1);
  for (uint32_t aa = 0; aa < 5; ++aa) {
    Settings s;
    s.aa = static_cast<AaMode>(aa);
    out.push_back(s);
  }
  for (uint32_t c = 0; c < 4; ++c) {
    for (uint32_t aa = 0; aa < 5; ++aa) {
      Settings s;
      s.culling = static_cast<CullingMode>(c);
      s.aa = static_cast<AaMode>(aa);
      out.push_back(s);
    }
  }
  for (uint32_t aa = 0; aa < 5; ++aa) {  // shadows and ssao with every AA mode
    Settings s;
    s.aa = static_cast<AaMode>(aa);
    s.shadows = s.ssao = true;
    s.synthetic_lights = 8;
    out.push_back(s);
    s.ssao = false;  // post effects with every AA mode
    s.bloom = true;
    out.push_back(s);
    s.exposure_mode = ExposureMode::kAuto;
    out.push_back(s);
  }
  Settings all;
  all.shadows = all.ssao = all.bloom = all.ibl = true;
  all.exposure_mode = ExposureMode::kAuto;
  all.synthetic_lights = 100;
  all.debug_view = DebugView::kNormals;
  out.push_back(all);
  return out;
}

// Every pass list SelectPasses produces for the variants above, with and without transparency,
// with the AA mode the resources depend on.
struct PassList {
  std::vector<PassId> passes;
  AaMode aa = AaMode::kNone;
  bool ssao = false;
  bool bloom = false;
};
std::vector<PassList> AllPassLists() {
  std::vector<PassList> lists;
  for (const Settings& s : SettingsVariants()) {
    for (bool transparent : {false, true}) {
      FrameFeatures f;
      f.has_transparent = transparent;
      lists.push_back({SelectPasses(s, f), s.aa, s.ssao, s.bloom});
    }
  }
  return lists;
}

std::string Describe(const std::vector<PassId>& passes) {
  std::string out;
  for (PassId p : passes) out += Name(p) + " ";
  return out;
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
  for (int i = 0; i < kPassCount; ++i) {
    const PassId id = static_cast<PassId>(i);
    const std::vector<ResourceUse> uses = PassUses(id);
    // The shadow pass's atlas lives across frames, outside the graph (its own barriers).
    if (id != PassId::kShadows) EXPECT_FALSE(uses.empty()) << Name(id);
    std::set<Resource> seen;
    for (const ResourceUse& u : uses) {
      EXPECT_LT(static_cast<size_t>(u.resource), kResourceCount) << Name(id);
      EXPECT_NE(u.access, Access::kNone) << Name(id);
      // One access per resource per pass: the plan moves a resource to a single state.
      EXPECT_TRUE(seen.insert(u.resource).second) << Name(id) << " uses a resource twice";
    }
  }
}

TEST(SelectPassesTest, OrderIsFixed) {
  for (const auto& [passes, aa, ssao, bloom] : AllPassLists()) {
    const std::string d = Describe(passes);
    // vis_mlaa's visibility pass is its depth pass, its shading pass its forward pass.
    const int prepass = std::max(IndexOf(passes, PassId::kDepthPrepass),
                                 IndexOf(passes, PassId::kVisibility));
    const int forward = std::max(IndexOf(passes, PassId::kForward), IndexOf(passes, PassId::kVisShade));
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
    if (transparent >= 0) {
      EXPECT_LT(forward, transparent) << d;
      EXPECT_LT(transparent, tonemap) << d;
    }
    // Shadow maps and ambient obscurance exist before anything is shaded; ssao reads the depth.
    const int shadows = IndexOf(passes, PassId::kShadows);
    const int ao = IndexOf(passes, PassId::kSsao);
    if (shadows >= 0) EXPECT_LT(shadows, forward) << d;
    EXPECT_EQ(ao >= 0, ssao) << d;
    if (ao >= 0) {
      EXPECT_LT(prepass, ao) << d;
      EXPECT_LT(ao, forward) << d;
    }
    // Auto exposure and bloom read the final HDR colour (after AA and transparency), exposure
    // first: bloom thresholds in exposed units.
    const int exposure = IndexOf(passes, PassId::kExposure);
    const int bloom_pass = IndexOf(passes, PassId::kBloom);
    EXPECT_EQ(bloom_pass >= 0, bloom) << d;
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
    // The image is read back last, once everything has been drawn into it.
    EXPECT_EQ(readback, static_cast<int>(passes.size()) - 1) << d;
    // PassId is declared in the only order passes may run, and nothing runs twice.
    EXPECT_TRUE(std::is_sorted(passes.begin(), passes.end())) << d;
    EXPECT_EQ(std::adjacent_find(passes.begin(), passes.end()), passes.end()) << d;
  }
}

TEST(SelectPassesTest, TransparentOnlyWhenTheSceneHasBlending) {
  for (const Settings& s : SettingsVariants()) {
    FrameFeatures f;
    f.has_transparent = false;
    EXPECT_EQ(IndexOf(SelectPasses(s, f), PassId::kTransparent), -1);
    f.has_transparent = true;
    EXPECT_GE(IndexOf(SelectPasses(s, f), PassId::kTransparent), 0);
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
  const std::vector<PassId> vis = {PassId::kVisibility, PassId::kVisResolve, PassId::kVisShade,
                                   PassId::kGeometricAa, PassId::kTonemap, PassId::kReadback};
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
  const std::vector<ResourceUse> prepass = PassUses(PassId::kDepthPrepass, AaMode::kMsaa);
  EXPECT_TRUE(std::any_of(prepass.begin(), prepass.end(), [](const ResourceUse& u) {
    return u.resource == Resource::kDepth && u.access == Access::kDepthResolve;
  }));
  // Tonemapping reads what the last colour pass wrote.
  EXPECT_EQ(PassUses(PassId::kTonemap, AaMode::kVisMlaa)[0].resource, Resource::kPostHdr);
  EXPECT_EQ(PassUses(PassId::kTonemap, AaMode::kTaa)[0].resource, Resource::kPostHdr);
  EXPECT_EQ(PassUses(PassId::kTonemap, AaMode::kMsaa)[0].resource, Resource::kHdrColor);
  EXPECT_EQ(PassUses(PassId::kReadback, AaMode::kFxaa)[0].resource, Resource::kFxaaColor);
}

// ---------------------------------------------------------------------------------------------
// PlanTransitions


const Transition* FindTransition(const std::vector<Transition>& ts, Resource r) {
  for (const Transition& t : ts)
    if (t.resource == r) return &t;
  return nullptr;
}

TEST(PlanTransitionsTest, OcclusionCullingMovesDepthAndPyramid) {
  Settings s;
  s.culling = CullingMode::kGpuOcclusion;
  const std::vector<PassId> passes = SelectPasses(s, {});
  const auto plan = PlanTransitions(passes);
  auto at = [&](PassId id) -> const std::vector<Transition>& { return plan[IndexOf(passes, id)]; };
  // The pyramid is written in the general layout, then read by the late cull.
  const Transition* hiz = FindTransition(at(PassId::kHizBuild), Resource::kHiz);
  ASSERT_NE(hiz, nullptr);
  EXPECT_EQ(hiz->to, Access::kComputeWrite);
  hiz = FindTransition(at(PassId::kCullLate), Resource::kHiz);
  ASSERT_NE(hiz, nullptr);
  EXPECT_EQ(hiz->from, Access::kComputeWrite);
  EXPECT_EQ(hiz->to, Access::kComputeRead);
  // The first phase's depth is sampled for the pyramid, then written again by the late phase
  // (from a defined layout, so its contents are kept).
  const Transition* depth = FindTransition(at(PassId::kDepthPrepassLate), Resource::kDepth);
  ASSERT_NE(depth, nullptr);
  EXPECT_EQ(depth->from, Access::kComputeRead);
  EXPECT_EQ(depth->to, Access::kDepthWrite);
}

TEST(PlanTransitionsTest, OnePlanEntryPerPass) {
  for (const auto& [passes, aa, ssao, bloom] : AllPassLists())
    EXPECT_EQ(PlanTransitions(passes, aa, ssao, bloom).size(), passes.size()) << Describe(passes);
  EXPECT_TRUE(PlanTransitions({}).empty());
}

TEST(PlanTransitionsTest, FirstUseTransitionsFromNone) {
  for (const auto& [passes, aa, ssao, bloom] : AllPassLists()) {
    const auto plan = PlanTransitions(passes, aa, ssao, bloom);
    std::array<bool, kResourceCount> used{};
    for (size_t i = 0; i < passes.size(); ++i) {
      for (const ResourceUse& u : PassUses(passes[i], aa, ssao, bloom)) {
        const size_t r = static_cast<size_t>(u.resource);
        if (used[r]) continue;
        used[r] = true;
        const Transition* t = FindTransition(plan[i], u.resource);
        ASSERT_NE(t, nullptr) << Describe(passes) << ": no first-use transition in "
                              << Name(passes[i]);
        EXPECT_EQ(t->from, Access::kNone) << Describe(passes) << " " << Name(passes[i]);
        EXPECT_EQ(t->to, u.access) << Describe(passes) << " " << Name(passes[i]);
      }
    }
  }
}

TEST(PlanTransitionsTest, NoBarrierForReadAfterReadInTheSameLayout) {
  // Forward then transparent both depth-test: the depth buffer stays as it is.
  const std::vector<PassId> passes = {PassId::kDepthPrepass, PassId::kForward, PassId::kTransparent,
                                      PassId::kTonemap, PassId::kReadback};
  const auto plan = PlanTransitions(passes);
  EXPECT_EQ(FindTransition(plan[2], Resource::kDepth), nullptr);
  // But depth written by the prepass and then tested by forward is a read-after-write hazard.
  const Transition* t = FindTransition(plan[1], Resource::kDepth);
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
  const std::vector<PassId> passes = SelectPasses(s, f);
  const auto plan = PlanTransitions(passes, s.aa, true);
  const int ssao = IndexOf(passes, PassId::kSsao);
  ASSERT_GT(ssao, IndexOf(passes, PassId::kLightCull));
  const Transition* t = FindTransition(plan[ssao], Resource::kDepth);
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->from, Access::kComputeRead);
  EXPECT_EQ(t->to, Access::kSampled);
  // The same for the colour auto exposure reads in compute, then tonemap in a fragment shader.
  s.exposure_mode = ExposureMode::kAuto;
  const std::vector<PassId> p2 = SelectPasses(s, f);
  const auto plan2 = PlanTransitions(p2, s.aa, true);
  t = FindTransition(plan2[IndexOf(p2, PassId::kTonemap)], Resource::kHdrColor);
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->from, Access::kComputeRead);
}

TEST(PlanTransitionsTest, BarrierForWriteAfterWrite) {
  // Transparent blends over forward's HDR colour: same layout, but both write.
  const std::vector<PassId> passes = {PassId::kDepthPrepass, PassId::kForward, PassId::kTransparent,
                                      PassId::kTonemap, PassId::kReadback};
  const auto plan = PlanTransitions(passes);
  const Transition* t = FindTransition(plan[2], Resource::kHdrColor);
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->from, Access::kColorWrite);
  EXPECT_EQ(t->to, Access::kColorWrite);
}

// Replays the plan on a state table: every transition starts from the resource's current
// state, and once a pass's transitions are applied every declared use is in its access.
TEST(PlanTransitionsTest, SimulatedPlanPutsEveryUseInItsState) {
  for (const auto& [passes, aa, ssao, bloom] : AllPassLists()) {
    const std::string d = Describe(passes);
    const auto plan = PlanTransitions(passes, aa, ssao, bloom);
    ASSERT_EQ(plan.size(), passes.size());
    std::array<Access, kResourceCount> state;
    state.fill(Access::kNone);
    for (size_t i = 0; i < passes.size(); ++i) {
      std::set<Resource> moved;
      for (const Transition& t : plan[i]) {
        const size_t r = static_cast<size_t>(t.resource);
        ASSERT_LT(r, kResourceCount);
        EXPECT_EQ(t.from, state[r]) << d << Name(passes[i]) << ": stale 'from'";
        EXPECT_NE(t.to, Access::kNone) << d << Name(passes[i]);
        EXPECT_TRUE(moved.insert(t.resource).second) << d << Name(passes[i]) << ": twice";
        state[r] = t.to;
      }
      for (const ResourceUse& u : PassUses(passes[i], aa, ssao, bloom)) {
        EXPECT_EQ(state[static_cast<size_t>(u.resource)], u.access)
            << d << "before " << Name(passes[i]) << " resource " << static_cast<int>(u.resource);
      }
      // Transitions only for what the pass uses.
      for (const Transition& t : plan[i]) {
        const auto uses = PassUses(passes[i], aa, ssao, bloom);
        EXPECT_TRUE(std::any_of(uses.begin(), uses.end(),
                                [&](const ResourceUse& u) { return u.resource == t.resource; }))
            << d << Name(passes[i]) << " transitions a resource it does not use";
      }
    }
  }
}

TEST(PlanTransitionsTest, NothingIsReadBeforeItIsWritten) {
  for (const auto& [passes, aa, ssao, bloom] : AllPassLists()) {
    std::array<bool, kResourceCount> written{};
    for (PassId p : passes) {
      for (const ResourceUse& u : PassUses(p, aa, ssao, bloom)) {
        const size_t r = static_cast<size_t>(u.resource);
        // The first culling phase binds the pyramid (one pipeline for both phases) but never
        // reads it: only the late phase tests occlusion.
        if (p == PassId::kCull && u.resource == Resource::kHiz) continue;
        if (IsRead(u.access)) {
          EXPECT_TRUE(written[r]) << Describe(passes) << ": " << Name(p) << " reads resource " << r
                                  << " before any pass wrote it";
        }
      }
      for (const ResourceUse& u : PassUses(p, aa, ssao, bloom))
        if (IsWrite(u.access)) written[static_cast<size_t>(u.resource)] = true;
    }
  }
}

TEST(PlanTransitionsTest, EveryHazardHasABarrier) {
  // Whenever a use follows a write, or changes the access class, the plan has a transition.
  for (const auto& [passes, aa, ssao, bloom] : AllPassLists()) {
    const auto plan = PlanTransitions(passes, aa, ssao, bloom);
    std::array<Access, kResourceCount> last;
    last.fill(Access::kNone);
    for (size_t i = 0; i < passes.size(); ++i) {
      for (const ResourceUse& u : PassUses(passes[i], aa, ssao, bloom)) {
        const size_t r = static_cast<size_t>(u.resource);
        // Only read-after-read in the same access may skip the barrier.
        const bool same_read = last[r] == u.access && IsRead(u.access);
        if (!same_read) {
          EXPECT_NE(FindTransition(plan[i], u.resource), nullptr)
              << Describe(passes) << Name(passes[i]) << " resource " << r;
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
    if (seg.group == AlphaMode::kBlend) EXPECT_EQ(seg.item_count, 1u);
    next += seg.item_count;
  }
  EXPECT_EQ(next, draws.size());
  // Adjacent non-blend segments differ in state (no needless split).
  for (size_t k = 1; k < plan.segments.size(); ++k) {
    const DrawSegment& a = plan.segments[k - 1];
    const DrawSegment& b = plan.segments[k];
    if (b.group != AlphaMode::kBlend)
      EXPECT_TRUE(a.group != b.group || a.double_sided != b.double_sided ||
                  a.material != b.material);
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
