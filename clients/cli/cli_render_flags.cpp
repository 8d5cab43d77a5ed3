#include "clients/cli/cli_render_flags.h"

#include <cmath>
#include <utility>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"

namespace tessera::cli {

const char kCameraFlagsUsage[] = R"(camera (default: the server frames the scene bounds):
  --camera N          the file's camera N (SceneInfo.cameras)
  --frame             frame the scene bounds (the default)
  --eye X,Y,Z --target X,Y,Z --up X,Y,Z   explicit camera (world units; default eye 0,0,5,
                      target 0,0,0, up 0,1,0)
  --fov DEGREES       vertical field of view (default 45.8, or the scene camera's)
  --near N --far N    clip planes (far 0 = infinite, the default)
)";

const char kSettingsFlagsUsage[] = R"(settings (unset ones take the server's defaults):
  --width N --height N          frame size in pixels (default 1280x720)
  --aa MODE           none|msaa|fxaa|taa|vis_mlaa          --samples N   1|2|4|8
  --culling MODE      none|cpu_frustum|gpu_frustum|gpu_occlusion
  --lights N          N synthetic point lights in the scene bounds   --light-seed N
  --no-scene-lights   ignore the file's KHR_lights_punctual lights (--scene-lights: use them)
  --tile-size N       light-culling tile, 8|16|32 pixels
  --no-light-culling  shade every light at every pixel (brute force; --light-culling: tiles)
  --light-radius MIN,MAX   synthetic light range in world units (default 1%..4% of the scene)
  --animate-lights    synthetic lights circle around   --light-time SECONDS  where they are
  --no-tile-depth-mask     cull with per-tile depth bounds only (no 2.5D mask)
  --shadows --ssao --bloom --ibl   turn effects on (--no-shadows etc.: off)
  --shadow-atlas N    shadow atlas side, a power of two 512..8192 (default 4096)
  --shadow-lights N   point/spot lights with shadows besides the sun, 0..32 (default 16)
  --no-shadow-cache   re-render every shadow map every frame (for comparison)
  --ssao-radius R     SSAO radius in world units (default 1.5% of the scene diagonal)
  --ssao-strength S   0..4 (default 1)        --ssao-full-res  SSAO at full resolution
  --bloom-strength S  0..1 (default 0.05): what is brighter than white glows
  --exposure EV       fixed exposure in stops (default 0)
  --auto-exposure     adapt to the frame's average luma (--exposure then compensates)
  --tonemapper T      pbr_neutral|photographic (default pbr_neutral)
  --debug VIEW        none|normals|depth|base_color|light_heatmap|culling_overlay|aa_mask|
                      shadow_atlas|cascades|ssao|bloom
  --quality Q         JPEG quality 1..100 (default 90)       --chroma 420|444
)";

namespace {

v1::Vec3 Vec3(float x, float y, float z) {
  v1::Vec3 v;
  v.set_x(x);
  v.set_y(y);
  v.set_z(z);
  return v;
}

// N comma-separated numbers (N = 2 or 3); unused components are 0.
v1::Vec3 ParseNumbers(ArgReader& args, size_t n, const char* form) {
  const std::string flag = args.current();
  const std::string s = args.Value();
  std::vector<std::string> parts = absl::StrSplit(s, ',');
  if (parts.size() != n) args.Fail(absl::StrCat(flag, " wants ", form, ", got '", s, "'"));
  float v[3] = {0.0f, 0.0f, 0.0f};
  for (size_t i = 0; i < n; ++i) {
    if (!absl::SimpleAtof(parts[i], &v[i]) || !std::isfinite(v[i])) {
      args.Fail(absl::StrCat(flag, ": not a number: '", parts[i], "'"));
    }
  }
  return Vec3(v[0], v[1], v[2]);
}

v1::Vec3 ParseVec3(ArgReader& args) { return ParseNumbers(args, 3, "X,Y,Z"); }

// An enum setting by its lower-case name ("msaa" -> AA_MSAA).
int ParseEnum(ArgReader& args, const google::protobuf::EnumDescriptor* type) {
  const std::string flag = args.current();
  const std::string name = args.Value();
  const int value = ParseEnumShortName(type, name);
  if (value < 0) {
    args.Fail(absl::StrCat(flag, ": '", name, "' is not one of ", EnumChoices(type)));
  }
  return value;
}

// The on/off settings: --NAME turns one on, --no-NAME off.
bool ParseToggle(ArgReader& args, v1::RenderSettings* settings) {
  using Setter = void (v1::RenderSettings::*)(bool);
  static constexpr std::pair<const char*, Setter> kToggles[] = {
      {"scene-lights", &v1::RenderSettings::set_scene_lights},
      {"shadows", &v1::RenderSettings::set_shadows},
      {"ssao", &v1::RenderSettings::set_ssao},
      {"bloom", &v1::RenderSettings::set_bloom},
      {"ibl", &v1::RenderSettings::set_ibl},
      {"light-culling", &v1::RenderSettings::set_light_culling},
      {"tile-depth-mask", &v1::RenderSettings::set_tile_depth_mask},
      {"animate-lights", &v1::RenderSettings::set_lights_animated},
      {"shadow-cache", &v1::RenderSettings::set_shadow_cache},
  };
  for (const auto& [name, set] : kToggles) {
    if (args.Is(absl::StrCat("--", name))) {
      (settings->*set)(true);
      return true;
    }
    if (args.Is(absl::StrCat("--no-", name))) {
      (settings->*set)(false);
      return true;
    }
  }
  return false;
}

}  // namespace

bool RenderFlags::Parse(ArgReader& args) { return ParseCamera(args) || ParseSettings(args); }

bool RenderFlags::ParseCamera(ArgReader& args) {
  if (args.Is("--camera")) {
    camera_.set_scene_camera(args.Uint());
  } else if (args.Is("--frame")) {
    camera_.mutable_frame();
  } else if (args.Is("--eye")) {
    eye_ = ParseVec3(args);
    eye_set_ = true;
  } else if (args.Is("--target")) {
    target_ = ParseVec3(args);
    target_set_ = true;
  } else if (args.Is("--up")) {
    up_ = ParseVec3(args);
    up_set_ = true;
  } else if (args.Is("--fov")) {
    const float degrees = args.Float();
    if (degrees <= 0 || degrees >= 180) args.Fail("--fov wants degrees in (0, 180)");
    camera_.set_yfov(degrees * static_cast<float>(M_PI) / 180.0f);
  } else if (args.Is("--near")) {
    camera_.set_znear(args.Float());
  } else if (args.Is("--far")) {
    camera_.set_zfar(args.Float());
  } else {
    return false;
  }
  return true;
}

bool RenderFlags::ParseSettings(ArgReader& args) {
  v1::RenderSettings& s = settings_;
  if (args.Is("--width")) {
    s.set_width(args.Uint());
  } else if (args.Is("--height")) {
    s.set_height(args.Uint());
  } else if (args.Is("--aa")) {
    s.set_aa(static_cast<v1::AaMode>(ParseEnum(args, v1::AaMode_descriptor())));
  } else if (args.Is("--samples")) {
    s.set_samples(args.Uint());
  } else if (args.Is("--culling")) {
    s.set_culling(static_cast<v1::CullingMode>(ParseEnum(args, v1::CullingMode_descriptor())));
  } else if (args.Is("--lights")) {
    s.set_synthetic_lights(args.Uint());
  } else if (args.Is("--light-seed")) {
    s.set_light_seed(args.Uint());
  } else if (args.Is("--tile-size")) {
    s.set_tile_size(args.Uint());
  } else if (args.Is("--light-radius")) {
    const v1::Vec3 r = ParseNumbers(args, 2, "MIN,MAX");
    s.set_light_radius_min(r.x());
    s.set_light_radius_max(r.y());
  } else if (args.Is("--light-time")) {
    s.set_light_time(args.Float());
  } else if (ParseToggle(args, &s)) {
    // done
  } else if (args.Is("--shadow-atlas")) {
    s.set_shadow_atlas_size(args.Uint());
  } else if (args.Is("--shadow-lights")) {
    s.set_shadow_lights(args.Uint());
  } else if (args.Is("--ssao-radius")) {
    s.set_ssao_radius(args.Float());
  } else if (args.Is("--ssao-strength")) {
    s.set_ssao_strength(args.Float());
  } else if (args.Is("--ssao-full-res")) {
    s.set_ssao_half_res(false);
  } else if (args.Is("--bloom-strength")) {
    s.set_bloom_strength(args.Float());
  } else if (args.Is("--exposure")) {
    if (s.exposure_mode() != v1::EXPOSURE_AUTO) s.set_exposure_mode(v1::EXPOSURE_FIXED);
    s.set_exposure_ev(args.Float());
  } else if (args.Is("--tonemapper")) {
    s.set_tonemapper(static_cast<v1::Tonemapper>(ParseEnum(args, v1::Tonemapper_descriptor())));
  } else if (args.Is("--auto-exposure")) {
    s.set_exposure_mode(v1::EXPOSURE_AUTO);
  } else if (args.Is("--debug")) {
    s.set_debug_view(static_cast<v1::DebugView>(ParseEnum(args, v1::DebugView_descriptor())));
  } else if (args.Is("--quality")) {
    s.set_jpeg_quality(args.Uint());
  } else if (args.Is("--chroma")) {
    const std::string c = args.Value();
    if (c != "420" && c != "444") args.Fail("--chroma wants 420 or 444");
    s.set_jpeg_444(c == "444");
  } else {
    return false;
  }
  return true;
}

void RenderFlags::Finish(ArgReader& args) {
  const bool look_at = eye_set_ || target_set_;
  if (look_at && has_placement()) {
    args.Fail("--eye/--target cannot be combined with --camera or --frame");
  }
  if (up_set_ && !look_at) args.Fail("--up needs --eye and/or --target");
  if (!look_at) return;
  v1::LookAt* l = camera_.mutable_look_at();
  *l->mutable_eye() = eye_set_ ? eye_ : Vec3(0, 0, 5);
  *l->mutable_target() = target_set_ ? target_ : Vec3(0, 0, 0);
  *l->mutable_up() = up_set_ ? up_ : Vec3(0, 1, 0);
}

}  // namespace tessera::cli
