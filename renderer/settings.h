#pragma once
// Render settings: one struct, mirrored by the proto. Validation names the bad field;
// resolution against a device clamps what the device cannot do and says which fields were
// clamped or are not applied yet, so nothing is silently ignored.
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace tessera {

enum class AaMode : uint32_t { kNone = 0, kMsaa, kFxaa, kTaa, kVisMlaa };
enum class CullingMode : uint32_t { kNone = 0, kCpuFrustum, kGpuFrustum, kGpuOcclusion };
enum class ExposureMode : uint32_t { kFixed = 0, kAuto };
// The curve from exposed HDR to display: Khronos PBR Neutral (base colours come out as
// authored), or the photographic operator 1 - e^-L applied to luma (Tesseract's, after Humus).
enum class Tonemapper : uint32_t { kPbrNeutral = 0, kPhotographic };
// How opaque surfaces are shaded with aa none, fxaa or taa: a visibility buffer (the geometry
// drawn once into depth and triangle ids, then each pixel shaded once in compute), or the
// forward path (a depth prepass, then the geometry again with the full shader). auto: the one
// measured faster on the device (ResolveSettings: forward on CPU devices, visibility elsewhere).
// msaa always shades forward; vis_mlaa always uses its multisampled visibility buffer.
enum class Pipeline : uint32_t { kAuto = 0, kForward, kVisibility };
// Where the full-screen passes TAA, vis_mlaa's geometric AA, SSAO (and its blur), bloom, the
// tonemap and FXAA run: as fragment shaders or as compute shaders. auto: the one measured faster
// on the device (ResolveSettings).
enum class PostStage : uint32_t { kAuto = 0, kFragment, kCompute };
// Where forward+ projects the local lights into tile rectangles and bins them by tile row: on
// the CPU each frame (uploaded), or on the GPU (shaders/light_bounds.comp, light_bins.comp)
// from the lights alone. auto: cpu on CPU devices (the GPU steps cost lavapipe more than the
// CPU spends), gpu elsewhere.
enum class LightBinning : uint32_t { kAuto = 0, kCpu, kGpu };
// How vis_mlaa finds which triangle each of a pixel's samples sees: rasterized into a
// multisampled visibility buffer, or derived from a one-sample visibility buffer: where a
// pixel's 3x3 neighbourhood shows more than one surface, each sample position is tested in
// screen space against the triangles the neighbourhood shows and those one and two edges away,
// and the nearest covering one is the sample's (shaders/common/vis_resolve.glsl). auto:
// analytic on GPUs, raster on CPU devices (ResolveSettings says why).
enum class VisMlaaCoverage : uint32_t { kAuto = 0, kRaster, kAnalytic };
// Values match kDebug* in shaders/common/gpu_types.h.
enum class DebugView : uint32_t {
  kNone = 0,
  kNormals,
  kDepth,
  kBaseColor,
  kLightHeatmap,
  kCullingOverlay,
  kAaMask,
  kShadowAtlas,  // the shadow atlas's depths (needs shadows)
  kCascades,     // surfaces tinted by the sun cascade that covers them (needs shadows)
  kSsao,         // the blurred ambient obscurance (needs ssao)
  kBloom         // the bloom added to the frame (needs bloom)
};

struct Settings {
  uint32_t width = 1280;  // pixels, 1..16384 (clamped to the device's maxImageDimension2D)
  uint32_t height = 720;  // pixels, 1..16384
  AaMode aa = AaMode::kNone;
  uint32_t samples = 4;  // MSAA / visibility samples for aa = msaa | vis_mlaa: 1, 2, 4 or 8
  CullingMode culling = CullingMode::kCpuFrustum;
  bool scene_lights = true;       // use the file's KHR_lights_punctual lights
  uint32_t synthetic_lights = 0;  // random point lights added in the scene bounds, 0..65536
  uint32_t light_seed = 1;        // seed of the synthetic lights
  uint32_t tile_size = 16;        // light-culling tile, 8 | 16 | 32 pixels
  // Range of the synthetic lights in world units, min..max (0: 1% / 4% of the scene diagonal).
  float light_radius_min = 0.0f;
  float light_radius_max = 0.0f;
  bool lights_animated = false;  // synthetic lights circle around their place (see light_time)
  float light_time = 0.0f;       // seconds; where animated lights are (deterministic)
  bool light_culling = true;     // forward+ tile lists; false: every light for every pixel
  bool tile_depth_mask = true;   // 2.5D depth mask per tile (false: min/max depth bounds only)
  LightBinning light_binning = LightBinning::kAuto;
  VisMlaaCoverage vis_mlaa_coverage = VisMlaaCoverage::kAuto;
  // Shadows: the sun's cascades and the `shadow_lights` most important point and spot lights,
  // in one depth atlas of shadow_atlas_size^2 texels (a power of two, 512..8192; clamped to the
  // device). With shadow_cache, a map is re-rendered only when its view changed.
  bool shadows = false;
  uint32_t shadow_atlas_size = 4096;
  uint32_t shadow_lights = 16;  // 0..32
  bool shadow_cache = true;
  // SSAO (SAO): radius in world units (0: 1.5% of the scene diagonal), strength 0..4, computed
  // at half resolution (false: full, for comparison).
  bool ssao = false;
  float ssao_radius = 0.0f;
  float ssao_strength = 1.0f;
  bool ssao_half_res = true;
  // Bloom: what is brighter than 1 after exposure (soft knee), blurred by a 13-tap downsample
  // chain and a tent upsample, added at bloom_strength (0..1).
  bool bloom = false;
  float bloom_strength = 0.05f;
  bool ibl = false;
  // Exposure: fixed (x 2^exposure_ev), or auto: the frame's average log luma, adapted over a
  // view's frames (its first frame converges at once), mapped to middle grey; exposure_ev then
  // compensates.
  ExposureMode exposure_mode = ExposureMode::kFixed;
  float exposure_ev = 0.0f;  // stops, -20..20 (0 = x1)
  Tonemapper tonemapper = Tonemapper::kPbrNeutral;
  Pipeline pipeline = Pipeline::kAuto;
  PostStage post_stage = PostStage::kAuto;
  DebugView debug_view = DebugView::kNone;
  // Each pass timed on its own (Frame::passes): on CPU devices each pass is submitted and waited
  // for alone, timed by the wall clock (TimingSource::kPassWallClock). Off, the frame goes in
  // one submission with no wait between passes, and the passes carry the device's timestamps,
  // which lavapipe misattributes between passes (kFrameWallClock; the total is the wall time).
  // GPUs time every pass with timestamps in one submission either way.
  bool pass_timing = true;
  uint32_t jpeg_quality = 90;  // 1..100
  bool jpeg_444 = false;       // chroma 4:4:4 instead of 4:2:0
  // glTF animation (renderer/scene/animation.h): the scene is posed with `animation` at
  // `scene_time` seconds, wrapping at its duration with `loop` (else held at its ends). Skins and
  // morph targets apply in every pose, the rest pose included. `play` is a stream's: its time
  // then advances with the wall clock from `scene_time` (the renderer reads only scene_time).
  float scene_time = 0.0f;  // seconds, -1e6..1e6
  bool loop = true;
  bool play = false;
  // Not a row of the settings table (which holds numbers): the animation's name, or its index
  // in the file as decimal digits, or "none"; empty is none. At most kMaxAnimationNameBytes.
  std::string animation;
};

inline constexpr size_t kMaxAnimationNameBytes = 1024;

// The most samples `samples` may ask for (1, 2, 4 or 8); a device may offer more.
inline constexpr uint32_t kMaxSamples = 8;

// What the device can do, for clamping.
struct DeviceCaps {
  uint32_t max_samples = 1;
  uint32_t max_image_dimension = 16384;
  // Usable sample counts, bit n = 2^n samples; 0: every power of two up to max_samples.
  uint32_t sample_counts = 0;
  bool visibility_buffer = true;  // vis_mlaa can run (else it falls back to msaa)
  bool cpu = false;  // a CPU device (lavapipe, SwiftShader): pipeline auto -> forward, ...
};

// One field the renderer changed or could not honour.
struct SettingNote {
  std::string field;    // e.g. "samples"
  std::string message;  // e.g. "clamped from 8 to 4 (device maximum)" or "not applied: ..."
};

struct ResolvedSettings {
  Settings effective;
  std::vector<SettingNote> notes;
};

// INVALID_ARGUMENT naming the field when a value is out of its range in the settings table
// (renderer/settings_table.h): "settings.<field>: <value> is out of range (<range>)".
absl::Status ValidateSettings(const Settings& settings);

// Validates, then clamps to `caps` and lists every field that is clamped or not applied.
absl::StatusOr<ResolvedSettings> ResolveSettings(const Settings& settings, const DeviceCaps& caps);

// Every name of enum setting type E (AaMode, CullingMode, ExposureMode, Tonemapper, DebugView),
// indexed by value: the names the CLI, JSON output and the settings table use, and the proto's
// value names without their prefix, in lower case.
template <typename E>
const std::vector<std::string_view>& EnumNames();
template <>
const std::vector<std::string_view>& EnumNames<AaMode>();
template <>
const std::vector<std::string_view>& EnumNames<CullingMode>();
template <>
const std::vector<std::string_view>& EnumNames<ExposureMode>();
template <>
const std::vector<std::string_view>& EnumNames<Tonemapper>();
template <>
const std::vector<std::string_view>& EnumNames<DebugView>();
template <>
const std::vector<std::string_view>& EnumNames<Pipeline>();
template <>
const std::vector<std::string_view>& EnumNames<PostStage>();
template <>
const std::vector<std::string_view>& EnumNames<LightBinning>();
template <>
const std::vector<std::string_view>& EnumNames<VisMlaaCoverage>();

// Names used by the CLI, JSON output and the proto ("invalid" for a value out of range).
std::string_view ToString(AaMode v);
std::string_view ToString(CullingMode v);
std::string_view ToString(ExposureMode v);
std::string_view ToString(Tonemapper v);
std::string_view ToString(DebugView v);
std::string_view ToString(Pipeline v);
std::string_view ToString(PostStage v);
std::string_view ToString(LightBinning v);
std::string_view ToString(VisMlaaCoverage v);
absl::StatusOr<AaMode> ParseAaMode(std::string_view s);
absl::StatusOr<CullingMode> ParseCullingMode(std::string_view s);
absl::StatusOr<ExposureMode> ParseExposureMode(std::string_view s);
absl::StatusOr<Tonemapper> ParseTonemapper(std::string_view s);
absl::StatusOr<DebugView> ParseDebugView(std::string_view s);

// Whether the frame shades its opaque surfaces from a single-sampled visibility buffer
// (Pipeline::kVisibility with aa none, fxaa or taa; effective settings have no kAuto).
inline bool ShadesVisibility(const Settings& s) {
  return s.pipeline == Pipeline::kVisibility &&
         (s.aa == AaMode::kNone || s.aa == AaMode::kFxaa || s.aa == AaMode::kTaa);
}
// Whether the frame draws visibility ids and shades them: vis_mlaa (multisampled) or the
// visibility pipeline.
inline bool DrawsVisibility(const Settings& s) {
  return s.aa == AaMode::kVisMlaa || ShadesVisibility(s);
}
// Whether vis_mlaa rasterizes one sample and its resolve finds the others' ids analytically
// (vis_mlaa_coverage analytic; effective settings have no kAuto).
inline bool VisMlaaAnalytic(const Settings& s) {
  return s.aa == AaMode::kVisMlaa && s.vis_mlaa_coverage == VisMlaaCoverage::kAnalytic;
}

}  // namespace tessera
