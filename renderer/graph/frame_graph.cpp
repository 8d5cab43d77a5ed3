#include "renderer/graph/frame_graph.h"

#include <array>

namespace tessera {

std::string_view PassName(PassId id) {
  switch (id) {
    case PassId::kSkinning:
      return "skinning";
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
    case PassId::kVisClassify:
      return "vis_classify";
    case PassId::kShade:
      return "shade";
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
    case PassId::kGeometricAa:
      return "geometric_aa";
    case PassId::kMotion:
      return "motion";
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

namespace {
bool Writes(Access a) {
  return a == Access::kDepthWrite || a == Access::kColorWrite || a == Access::kComputeWrite ||
         a == Access::kDepthResolve || a == Access::kHostWrite;
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
    case Access::kSampledGeneral:
    case Access::kComputeReadGeneral:
      return 5;
    case Access::kIndirectRead:
    case Access::kGeometryRead:
      return 6;
    case Access::kHostWrite:
    case Access::kHostRead:
      return 7;
    case Access::kNone:
      return 0;
  }
  return 0;
}
bool NeedsTransition(Access current, Access next) {
  const bool layout_change = LayoutClass(current) != LayoutClass(next);
  const bool other_stage = current != next;  // e.g. a compute read, then a fragment one
  return layout_change || other_stage || Writes(current) || Writes(next);
}
}  // namespace

GraphBuilder& GraphBuilder::Pass(PassId id) {
  passes_.push_back({id, {}, {}});
  return *this;
}

GraphBuilder& GraphBuilder::Use(Resource r, Access access) {
  passes_.back().uses.push_back({r, access});
  return *this;
}

GraphBuilder& GraphBuilder::UseIfPresent(Resource r, Access access) {
  return Written(r) || Imported(r) ? Use(r, access) : *this;
}

GraphBuilder& GraphBuilder::Import(Resource r, Access initial, Access final) {
  imports_.push_back({r, initial, final});
  return *this;
}

bool GraphBuilder::Imported(Resource r) const {
  for (const ResourceImport& i : imports_)
    if (i.resource == r) return true;
  return false;
}

bool GraphBuilder::Written(Resource r) const {
  for (const PlannedPass& p : passes_)
    for (const ResourceUse& u : p.uses)
      if (u.resource == r && Writes(u.access)) return true;
  return false;
}

Resource GraphBuilder::SceneColor() const {
  return Written(Resource::kPostHdr) ? Resource::kPostHdr : Resource::kHdrColor;
}

FramePlan GraphBuilder::Build() && {
  std::array<Access, static_cast<size_t>(Resource::kCount)> state;
  state.fill(Access::kNone);
  for (const ResourceImport& i : imports_) state[static_cast<size_t>(i.resource)] = i.initial;
  for (PlannedPass& pass : passes_) {
    for (const ResourceUse& use : pass.uses) {
      Access& current = state[static_cast<size_t>(use.resource)];
      if (NeedsTransition(current, use.access))
        pass.before.push_back({use.resource, current, use.access});
      current = use.access;
    }
  }
  const Resource scene_color = SceneColor();
  FramePlan plan{std::move(passes_), std::move(imports_), {}, scene_color};
  // Imports leave in the access the next frame expects.
  for (const ResourceImport& i : plan.imports) {
    const Access current = state[static_cast<size_t>(i.resource)];
    if (current != i.final && NeedsTransition(current, i.final))
      plan.after.push_back({i.resource, current, i.final});
  }
  return plan;
}

std::vector<PassId> FramePlan::ids() const {
  std::vector<PassId> out;
  for (const PlannedPass& p : passes) out.push_back(p.id);
  return out;
}

bool FramePlan::Has(PassId id) const {
  for (const PlannedPass& p : passes)
    if (p.id == id) return true;
  return false;
}

Access FramePlan::FinalAccess(Resource r) const {
  Access last = Access::kNone;
  for (const ResourceImport& i : imports)
    if (i.resource == r) last = i.initial;
  for (const PlannedPass& p : passes)
    for (const ResourceUse& u : p.uses)
      if (u.resource == r) last = u.access;
  for (const Transition& t : after)
    if (t.resource == r) last = t.to;
  return last;
}

std::vector<PassId> SelectPasses(const Settings& settings, const FrameFeatures& features) {
  return PlanFrame(settings, features).ids();
}

}  // namespace tessera
