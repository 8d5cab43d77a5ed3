#include "renderer/settings.h"

#include <bit>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "common/status_macros.h"
#include "renderer/settings_table.h"

namespace tessera {

// The names of each enum, indexed by value (the enums count from 0 without gaps).
template <>
const std::vector<std::string_view>& EnumNames<AaMode>() {
  static const std::vector<std::string_view> names{"none", "msaa", "fxaa", "taa", "vis_mlaa"};
  return names;
}
template <>
const std::vector<std::string_view>& EnumNames<CullingMode>() {
  static const std::vector<std::string_view> names{"none", "cpu_frustum", "gpu_frustum",
                                                   "gpu_occlusion"};
  return names;
}
template <>
const std::vector<std::string_view>& EnumNames<ExposureMode>() {
  static const std::vector<std::string_view> names{"fixed", "auto"};
  return names;
}
template <>
const std::vector<std::string_view>& EnumNames<Tonemapper>() {
  static const std::vector<std::string_view> names{"pbr_neutral", "photographic"};
  return names;
}
template <>
const std::vector<std::string_view>& EnumNames<DebugView>() {
  static const std::vector<std::string_view> names{
      "none",          "normals", "depth",    "base_color", "light_heatmap", "culling_overlay",
      "aa_mask",       "shadow_atlas", "cascades", "ssao",   "bloom"};
  return names;
}

template <>
const std::vector<std::string_view>& EnumNames<Pipeline>() {
  static const std::vector<std::string_view> names{"auto", "forward", "visibility"};
  return names;
}
template <>
const std::vector<std::string_view>& EnumNames<PostStage>() {
  static const std::vector<std::string_view> names{"auto", "fragment", "compute"};
  return names;
}
template <>
const std::vector<std::string_view>& EnumNames<LightBinning>() {
  static const std::vector<std::string_view> names{"auto", "cpu", "gpu"};
  return names;
}
template <>
const std::vector<std::string_view>& EnumNames<VisMlaaCoverage>() {
  static const std::vector<std::string_view> names{"auto", "raster", "analytic"};
  return names;
}

namespace {

template <typename E>
std::string_view NameOf(E v) {
  const std::vector<std::string_view>& names = EnumNames<E>();
  const auto i = static_cast<size_t>(v);
  return i < names.size() ? names[i] : "invalid";
}

template <typename E>
absl::StatusOr<E> Parse(std::string_view field, std::string_view s) {
  const std::vector<std::string_view>& names = EnumNames<E>();
  for (size_t i = 0; i < names.size(); ++i)
    if (names[i] == s) return static_cast<E>(i);
  return absl::InvalidArgumentError(absl::StrCat(
      std::string(field), ": unknown value '", std::string(s), "' (one of: ",
      absl::StrJoin(names, ", ",
                    [](std::string* out, std::string_view name) { out->append(name); }),
      ")"));
}

}  // namespace

std::string_view ToString(AaMode v) { return NameOf(v); }
std::string_view ToString(CullingMode v) { return NameOf(v); }
std::string_view ToString(ExposureMode v) { return NameOf(v); }
std::string_view ToString(DebugView v) { return NameOf(v); }
std::string_view ToString(Tonemapper v) { return NameOf(v); }
std::string_view ToString(Pipeline v) { return NameOf(v); }
std::string_view ToString(PostStage v) { return NameOf(v); }
std::string_view ToString(LightBinning v) { return NameOf(v); }
std::string_view ToString(VisMlaaCoverage v) { return NameOf(v); }
absl::StatusOr<Tonemapper> ParseTonemapper(std::string_view s) {
  return Parse<Tonemapper>("tonemapper", s);
}
absl::StatusOr<AaMode> ParseAaMode(std::string_view s) { return Parse<AaMode>("aa", s); }
absl::StatusOr<CullingMode> ParseCullingMode(std::string_view s) {
  return Parse<CullingMode>("culling", s);
}
absl::StatusOr<ExposureMode> ParseExposureMode(std::string_view s) {
  return Parse<ExposureMode>("exposure_mode", s);
}
absl::StatusOr<DebugView> ParseDebugView(std::string_view s) {
  return Parse<DebugView>("debug_view", s);
}

absl::Status ValidateSettings(const Settings& s) {
  for (const SettingRow& row : SettingsTable()) RETURN_IF_ERROR(row.Validate(s));
  if (s.animation.size() > kMaxAnimationNameBytes) {
    return absl::InvalidArgumentError(absl::StrCat("settings.animation: ", s.animation.size(),
                                                   " bytes is too long (at most ",
                                                   kMaxAnimationNameBytes, ")"));
  }
  // Rules between fields, after each field is known to be in its own range.
  if (s.light_radius_max > 0.0f && s.light_radius_max < s.light_radius_min) {
    return absl::InvalidArgumentError(absl::StrCat("settings.light_radius_max: ",
                                                   s.light_radius_max,
                                                   " is out of range (>= light_radius_min)"));
  }
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
    not_applied("aa", "vis_mlaa needs the visibility buffer, which this device cannot draw (its "
                      "fallbacks say why); rendered with msaa");
    e.aa = AaMode::kMsaa;
  }
  // The pipeline that runs, as the effective settings report it: msaa shades forward, vis_mlaa
  // its visibility buffer; auto picks what measured faster on the device (README, "The
  // visibility pipeline": on lavapipe the forward path for plain frames, its rasterizer skipping
  // hidden fragments cheaply and interpolation being cheaper than rebuilding each pixel's
  // surface from its id; on GPUs the visibility pipeline). A request the mode or the device
  // cannot honour is noted.
  const bool asked = e.pipeline != Pipeline::kAuto;
  if (e.aa == AaMode::kMsaa) {
    if (e.pipeline == Pipeline::kVisibility)
      not_applied("pipeline", "msaa shades forward (vis_mlaa is the multisampled visibility buffer)");
    e.pipeline = Pipeline::kForward;
  } else if (e.aa == AaMode::kVisMlaa) {
    if (e.pipeline == Pipeline::kForward)
      not_applied("pipeline", "vis_mlaa shades its visibility buffer");
    e.pipeline = Pipeline::kVisibility;
  } else if (!asked) {
    e.pipeline = caps.cpu || !caps.visibility_buffer ? Pipeline::kForward : Pipeline::kVisibility;
  }
  if (e.post_stage == PostStage::kAuto) {
    // Measured (README, "The visibility pipeline"): GPUs run full-screen fragment work on their
    // graphics part only (an H200's TAA at 4K: 6.0 ms as a fragment pass, 0.x in compute).
    e.post_stage = caps.cpu ? PostStage::kFragment : PostStage::kCompute;
  }
  if (e.vis_mlaa_coverage == VisMlaaCoverage::kAuto) {
    // Measured (README, "Anti-aliasing" and "The visibility pipeline"): on an H200 analytic
    // halves vis_mlaa's 4K frame (Sponza, full stack with 20000 lights: 0.50x raster's; plain
    // 0.43x; 720p 0.63x), rasterizing one sample where raster's 4-sample visibility pass took
    // 19.3 ms, with edges within 0.04 dB of raster's on Sponza and the helmet (0.9 dB below on
    // the wire scene; measured before the resolve stopped listing the pixels inside a surface,
    // which halved it on lavapipe). On lavapipe its resolve costs more than the samples it
    // saves (the frame 1.45-1.6x raster's; 1.38x on plain Sponza since the surface test moved to
    // the scene's upload, 2026-11-28), so CPU devices keep raster.
    e.vis_mlaa_coverage = caps.cpu ? VisMlaaCoverage::kRaster : VisMlaaCoverage::kAnalytic;
  }
  if (e.light_binning == LightBinning::kAuto) {
    // Measured on lavapipe (README, "Forward+"): the two compute steps cost more GPU time than
    // BoundLight and BinLightsByRow cost the CPU. On GPUs the CPU work they replace was 8-9 ms
    // of record at 20000 lights (H200 machine); the GPU steps are not measured there yet.
    e.light_binning = caps.cpu ? LightBinning::kCpu : LightBinning::kGpu;
  }
  if (ShadesVisibility(e) && !caps.visibility_buffer) {
    not_applied("pipeline", "this device cannot draw the visibility buffer (its fallbacks say "
                            "why); shaded forward");
    e.pipeline = Pipeline::kForward;
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
