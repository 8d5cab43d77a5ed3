#include "clients/cli/cli_render_flags.h"

#include <cmath>
#include <utility>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "server/settings_wire.h"

namespace tessera::cli {

const char kCameraFlagsUsage[] = R"(camera (default: the server frames the scene bounds):
  --camera N          the file's camera N (SceneInfo.cameras)
  --frame             frame the scene bounds (the default)
  --eye X,Y,Z --target X,Y,Z --up X,Y,Z   explicit camera (world units; default eye 0,0,5,
                      target 0,0,0, up 0,1,0)
  --fov DEGREES       vertical field of view (default 45.8, or the scene camera's)
  --near N --far N    clip planes (far 0 = infinite, the default)
)";

std::string SettingsFlagsUsageText() {
  return absl::StrCat("settings (unset ones take the server's defaults):\n", SettingsFlagsUsage());
}

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
  // The settings table parses (the same flags as tessera-render); only the rows the command line
  // named go into the request, so the server's defaults fill in the rest.
  const absl::StatusOr<bool> parsed =
      ParseSettingFlag(args.current(), [&args] { return args.Value(); }, &parsed_, &named_);
  if (!parsed.ok()) args.Fail(parsed.status().message());
  if (!*parsed) return false;
  server::ToProto(parsed_, named_, &settings_);
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
