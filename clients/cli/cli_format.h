#pragma once
// Human-readable and JSON renderings of the service's messages, shared by the commands.
#include <cstdio>
#include <string>

#include "clients/cli/cli_common.h"
#include "tessera/v1/render_service.pb.h"

namespace tessera::cli {

std::string FormatVec3(const v1::Vec3& v);
// "1280x720, aa msaa x4, culling cpu_frustum, ..." from the fields that are set.
std::string SettingsSummary(const v1::RenderSettings& s);
// Breaks a ", "-separated list into lines of at most ~100 columns, continuation lines
// indented by `indent` spaces (the first line is assumed to start there too).
std::string WrapList(const std::string& text, size_t indent);
// "eye (..) target (..) up (..), fov 45.8 deg, near 0.05, far inf"
std::string CameraSummary(const v1::Frame& frame);

// The counts, bounds, cameras and warnings of a scene, indented, on `out`.
void PrintSceneInfo(FILE* out, const v1::SceneInfo& info);

// The per-pass table, the CPU stages, the stats and the setting notes of one frame.
void PrintFrameTimings(const v1::Frame& frame);

// Every field of the frame except the image, plus its size as "bytes".
Json FrameJson(const v1::Frame& frame);

}  // namespace tessera::cli
