#include "renderer/settings.h"

#include <array>
#include <bit>
#include <cmath>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace tessera {

namespace {

constexpr std::array<std::pair<AaMode, std::string_view>, 5> kAaNames{
    {{AaMode::kNone, "none"},
     {AaMode::kMsaa, "msaa"},
     {AaMode::kFxaa, "fxaa"},
     {AaMode::kTaa, "taa"},
     {AaMode::kVisMlaa, "vis_mlaa"}}};
constexpr std::array<std::pair<CullingMode, std::string_view>, 4> kCullingNames{
    {{CullingMode::kNone, "none"},
     {CullingMode::kCpuFrustum, "cpu_frustum"},
     {CullingMode::kGpuFrustum, "gpu_frustum"},
     {CullingMode::kGpuOcclusion, "gpu_occlusion"}}};
constexpr std::array<std::pair<ExposureMode, std::string_view>, 2> kExposureNames{
    {{ExposureMode::kFixed, "fixed"}, {ExposureMode::kAuto, "auto"}}};
constexpr std::array<std::pair<Tonemapper, std::string_view>, 2> kTonemapperNames{
    {{Tonemapper::kPbrNeutral, "pbr_neutral"}, {Tonemapper::kPhotographic, "photographic"}}};
constexpr std::array<std::pair<DebugView, std::string_view>, 11> kDebugNames{
    {{DebugView::kNone, "none"},
     {DebugView::kNormals, "normals"},
     {DebugView::kDepth, "depth"},
     {DebugView::kBaseColor, "base_color"},
     {DebugView::kLightHeatmap, "light_heatmap"},
     {DebugView::kCullingOverlay, "culling_overlay"},
     {DebugView::kAaMask, "aa_mask"},
     {DebugView::kShadowAtlas, "shadow_atlas"},
     {DebugView::kCascades, "cascades"},
     {DebugView::kSsao, "ssao"},
     {DebugView::kBloom, "bloom"}}};

template <typename E, size_t N>
std::string_view NameOf(const std::array<std::pair<E, std::string_view>, N>& table, E v) {
  for (const auto& [e, name] : table)
    if (e == v) return name;
  return "invalid";
}

template <typename E, size_t N>
absl::StatusOr<E> Parse(const std::array<std::pair<E, std::string_view>, N>& table,
                        std::string_view field, std::string_view s) {
  std::vector<std::string> names;
  for (const auto& [e, name] : table) {
    if (name == s) return e;
    names.emplace_back(name);
  }
  return absl::InvalidArgumentError(absl::StrCat(std::string(field), ": unknown value '",
                                                 std::string(s),
                                                 "' (one of: ", absl::StrJoin(names, ", "), ")"));
}

template <typename E, size_t N>
bool Known(const std::array<std::pair<E, std::string_view>, N>& table, E v) {
  return NameOf(table, v) != "invalid";
}

}  // namespace

std::string_view ToString(AaMode v) { return NameOf(kAaNames, v); }
std::string_view ToString(CullingMode v) { return NameOf(kCullingNames, v); }
std::string_view ToString(ExposureMode v) { return NameOf(kExposureNames, v); }
std::string_view ToString(DebugView v) { return NameOf(kDebugNames, v); }
std::string_view ToString(Tonemapper v) { return NameOf(kTonemapperNames, v); }
absl::StatusOr<Tonemapper> ParseTonemapper(std::string_view s) {
  return Parse(kTonemapperNames, "tonemapper", s);
}
absl::StatusOr<AaMode> ParseAaMode(std::string_view s) { return Parse(kAaNames, "aa", s); }
absl::StatusOr<CullingMode> ParseCullingMode(std::string_view s) {
  return Parse(kCullingNames, "culling", s);
}
absl::StatusOr<ExposureMode> ParseExposureMode(std::string_view s) {
  return Parse(kExposureNames, "exposure_mode", s);
}
absl::StatusOr<DebugView> ParseDebugView(std::string_view s) {
  return Parse(kDebugNames, "debug_view", s);
}

absl::Status ValidateSettings(const Settings& s) {
  auto bad = [](const char* field, auto value, const char* range) {
    return absl::InvalidArgumentError(
        absl::StrCat("settings.", field, ": ", value, " is out of range (", range, ")"));
  };
  if (s.width < 1 || s.width > 16384) return bad("width", s.width, "1..16384");
  if (s.height < 1 || s.height > 16384) return bad("height", s.height, "1..16384");
  if (!Known(kAaNames, s.aa)) return bad("aa", static_cast<uint32_t>(s.aa), "an AaMode");
  if (s.samples == 0 || s.samples > kMaxSamples || (s.samples & (s.samples - 1)) != 0)
    return bad("samples", s.samples, "1, 2, 4 or 8");
  if (!Known(kCullingNames, s.culling))
    return bad("culling", static_cast<uint32_t>(s.culling), "a CullingMode");
  if (s.synthetic_lights > 65536) return bad("synthetic_lights", s.synthetic_lights, "0..65536");
  if (!std::isfinite(s.light_radius_min) || s.light_radius_min < 0.0f || s.light_radius_min > 1e6f)
    return bad("light_radius_min", s.light_radius_min, "0..1e6 world units, 0 = auto");
  if (!std::isfinite(s.light_radius_max) || s.light_radius_max < 0.0f || s.light_radius_max > 1e6f)
    return bad("light_radius_max", s.light_radius_max, "0..1e6 world units, 0 = auto");
  if (s.light_radius_max > 0.0f && s.light_radius_max < s.light_radius_min)
    return bad("light_radius_max", s.light_radius_max, ">= light_radius_min");
  if (!std::isfinite(s.light_time) || std::abs(s.light_time) > 1e6f)
    return bad("light_time", s.light_time, "-1e6..1e6 seconds");
  if (s.tile_size != 8 && s.tile_size != 16 && s.tile_size != 32)
    return bad("tile_size", s.tile_size, "8, 16 or 32");
  if (s.shadow_atlas_size < 512 || s.shadow_atlas_size > 8192 ||
      (s.shadow_atlas_size & (s.shadow_atlas_size - 1)) != 0)
    return bad("shadow_atlas_size", s.shadow_atlas_size, "a power of two, 512..8192");
  if (s.shadow_lights > 32) return bad("shadow_lights", s.shadow_lights, "0..32");
  if (!std::isfinite(s.ssao_radius) || s.ssao_radius < 0.0f || s.ssao_radius > 1e6f)
    return bad("ssao_radius", s.ssao_radius, "0..1e6 world units, 0 = auto");
  if (!std::isfinite(s.ssao_strength) || s.ssao_strength < 0.0f || s.ssao_strength > 4.0f)
    return bad("ssao_strength", s.ssao_strength, "0..4");
  if (!std::isfinite(s.bloom_strength) || s.bloom_strength < 0.0f || s.bloom_strength > 1.0f)
    return bad("bloom_strength", s.bloom_strength, "0..1");
  if (!Known(kExposureNames, s.exposure_mode))
    return bad("exposure_mode", static_cast<uint32_t>(s.exposure_mode), "an ExposureMode");
  if (!std::isfinite(s.exposure_ev) || s.exposure_ev < -20.0f || s.exposure_ev > 20.0f)
    return bad("exposure_ev", s.exposure_ev, "-20..20 stops");
  if (!Known(kTonemapperNames, s.tonemapper))
    return bad("tonemapper", static_cast<uint32_t>(s.tonemapper), "a Tonemapper");
  if (!Known(kDebugNames, s.debug_view))
    return bad("debug_view", static_cast<uint32_t>(s.debug_view), "a DebugView");
  if (s.jpeg_quality < 1 || s.jpeg_quality > 100)
    return bad("jpeg_quality", s.jpeg_quality, "1..100");
  return absl::OkStatus();
}

absl::StatusOr<ResolvedSettings> ResolveSettings(const Settings& settings, const DeviceCaps& caps) {
  if (absl::Status st = ValidateSettings(settings); !st.ok()) return st;
  ResolvedSettings r{settings, {}};
  Settings& e = r.effective;
  auto note = [&r](std::string field, std::string message) {
    r.notes.push_back({std::move(field), std::move(message)});
  };
  auto not_applied = [&](std::string field, const std::string& why) {
    note(std::move(field), absl::StrCat("not applied: ", why));
  };

  if (e.width > caps.max_image_dimension) {
    note("width", absl::StrCat("clamped from ", e.width, " to ", caps.max_image_dimension,
                               " (device maxImageDimension2D)"));
    e.width = caps.max_image_dimension;
  }
  if (e.height > caps.max_image_dimension) {
    note("height", absl::StrCat("clamped from ", e.height, " to ", caps.max_image_dimension,
                                " (device maxImageDimension2D)"));
    e.height = caps.max_image_dimension;
  }
  // The sample count the device can do nearest below the request (above it when there is none
  // below); the multisampled modes need at least 2.
  const uint32_t counts = caps.sample_counts != 0 ? caps.sample_counts : (caps.max_samples * 2 - 1);
  const bool multisampled = e.aa == AaMode::kMsaa || e.aa == AaMode::kVisMlaa;
  const uint32_t usable = multisampled ? (counts & ~1u) : counts;
  if (usable == 0) {
    not_applied("aa", absl::StrCat(std::string(ToString(e.aa)),
                                   " needs a multisampled target; the device has none"));
    e.aa = AaMode::kNone;
  } else if ((usable & e.samples) == 0) {
    uint32_t to = 0;
    for (uint32_t c = e.samples; c >= 1 && to == 0; c >>= 1)
      if (usable & c) to = c;
    for (uint32_t c = e.samples; c <= 64 && to == 0; c <<= 1)
      if (usable & c) to = c;
    std::string why;
    if (e.samples > caps.max_samples) {
      why = " (device maximum)";
    } else if (e.samples == 1) {
      why = absl::StrCat(" (", std::string(ToString(e.aa)), " needs at least 2)");
    } else {
      why = absl::StrCat(" (the device has no ", e.samples, "x)");
    }
    note("samples", absl::StrCat(to > e.samples ? "raised from " : "clamped from ", e.samples,
                                 " to ", to, why));
    e.samples = to;
  }
  if (e.aa == AaMode::kVisMlaa && !caps.visibility_buffer) {
    not_applied("aa", "vis_mlaa needs gl_PrimitiveID in fragment shaders (geometryShader) and "
                      "standard sample locations; rendered with msaa");
    e.aa = AaMode::kMsaa;
  }
  if (e.shadows && e.shadow_atlas_size > caps.max_image_dimension) {
    note("shadow_atlas_size",
         absl::StrCat("clamped from ", e.shadow_atlas_size, " to ",
                      std::bit_floor(caps.max_image_dimension), " (device maxImageDimension2D)"));
    e.shadow_atlas_size = std::bit_floor(caps.max_image_dimension);
  }
  if (e.debug_view == DebugView::kAaMask && e.aa != AaMode::kVisMlaa) {
    not_applied("debug_view", "aa_mask shows vis_mlaa's coverage mask; aa is not vis_mlaa");
    e.debug_view = DebugView::kNone;
  }
  struct Needs {
    DebugView view;
    bool on;
    const char* what;
  };
  for (const Needs& n : {Needs{DebugView::kShadowAtlas, e.shadows, "shadows"},
                         Needs{DebugView::kCascades, e.shadows, "shadows"},
                         Needs{DebugView::kSsao, e.ssao, "ssao"},
                         Needs{DebugView::kBloom, e.bloom, "bloom"}}) {
    if (e.debug_view == n.view && !n.on) {
      not_applied("debug_view", absl::StrCat(std::string(ToString(n.view)), " needs ", n.what,
                                             " on"));
      e.debug_view = DebugView::kNone;
    }
  }
  if (e.debug_view == DebugView::kCullingOverlay) {
    not_applied("debug_view",
                absl::StrCat(std::string(ToString(e.debug_view)), " is not implemented yet"));
    e.debug_view = DebugView::kNone;
  }
  return r;
}

}  // namespace tessera
