#pragma once
// The camera and settings flags of `tessera render` and `tessera stream`, spelled as in the
// offline tool tessera-render so both feel the same.
#include <string>

#include "clients/cli/cli_common.h"
#include "renderer/settings_table.h"
#include "tessera/v1/render_service.pb.h"

namespace tessera::cli {

// Usage lines for the flags below.
extern const char kCameraFlagsUsage[];
// The settings flags, from the settings table (renderer/settings_table.h).
std::string SettingsFlagsUsageText();

class RenderFlags {
 public:
  // Takes the current argument of `args` (and its value) when it is a camera or settings
  // flag; false when it is not one of them.
  bool Parse(ArgReader& args);
  // Checks combinations (e.g. --camera with --eye) once every flag is read.
  void Finish(ArgReader& args);

  // Placement unset when no camera flag was given: the server frames the scene bounds.
  const v1::Camera& camera() const { return camera_; }
  // Only the fields named on the command line are set; the server fills in the rest.
  const v1::RenderSettings& settings() const { return settings_; }
  // For commands that vary settings on top of the command line (bench).
  v1::RenderSettings* mutable_settings() { return &settings_; }
  // --eye/--target/--up were given.
  bool has_look_at() const { return eye_set_ || target_set_; }
  // A placement was given: --camera N, --frame, or (after Finish) --eye/--target.
  bool has_placement() const { return camera_.placement_case() != v1::Camera::PLACEMENT_NOT_SET; }
  // --camera N or --frame was given: a placement other than a look-at.
  bool has_fixed_placement() const { return has_placement() && !has_look_at(); }

 private:
  bool ParseCamera(ArgReader& args);
  bool ParseSettings(ArgReader& args);

  v1::Camera camera_;
  v1::RenderSettings settings_;
  // The settings flags as parsed, and which rows they named (only those go into settings_).
  Settings parsed_;
  SettingMask named_;
  // tessera-render's defaults for a partly given look-at camera.
  v1::Vec3 eye_, target_, up_;
  bool eye_set_ = false, target_set_ = false, up_set_ = false;
};

}  // namespace tessera::cli
