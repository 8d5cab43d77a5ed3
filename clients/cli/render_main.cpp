// tessera-render: renders a glTF scene (or the built-in demo scene) offline to a JPEG or PNG
// and prints the GPU time of every pass. The future `tessera render` talks to the daemon; this
// tool runs the same renderer in-process, for deploy/run.sh, benchmarks and debugging.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <cstdlib>
#include <glm/glm.hpp>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "clients/cli/json_float.h"
#include "renderer/renderer.h"
#include "renderer/scene/demo_scene.h"
#include "renderer/settings_table.h"

namespace {

constexpr char kUsage[] = R"(usage: tessera-render [options]
  --scene FILE        .gltf or .glb to render, or a directory with one (default: the demo scene)
  --out FILE          output image, .jpg/.jpeg or .png (default: tessera.jpg)
  --camera N          use the file's camera N (default: the file's first camera, else framed)
  --frame             frame the scene bounds even if the file has cameras
  --eye X,Y,Z --target X,Y,Z --up X,Y,Z   explicit camera (world units)
  --fov DEGREES       vertical field of view (default 45.8)
  --near N --far N    clip planes (far 0 = infinite, the default)
  --frames N          render N frames and report the last (default 1)
  --device NAME       pick a Vulkan device by (part of) its name
  --validation        enable Vulkan validation layers
  --json              print the result as JSON instead of a table
settings:
)";

[[noreturn]] void Fail(const std::string& msg) {
  std::fprintf(stderr, "tessera-render: %s\n", msg.c_str());
  std::exit(2);
}

glm::vec3 ParseVec3(const std::string& flag, const std::string& s) {
  std::vector<std::string> parts = absl::StrSplit(s, ',');
  glm::vec3 v;
  if (parts.size() != 3) Fail(flag + " wants X,Y,Z, got '" + s + "'");
  for (int i = 0; i < 3; ++i)
    if (!absl::SimpleAtof(parts[i], &v[i])) Fail(flag + ": not a number: '" + parts[i] + "'");
  return v;
}

float ParseFloat(const std::string& flag, const std::string& s) {
  float v;
  if (!absl::SimpleAtof(s, &v)) Fail(flag + ": not a number: '" + s + "'");
  return v;
}

uint32_t ParseUint(const std::string& flag, const std::string& s) {
  uint32_t v;
  if (!absl::SimpleAtoi(s, &v)) Fail(flag + ": not a non-negative integer: '" + s + "'");
  return v;
}

template <typename T>
T OrFail(absl::StatusOr<T> v) {
  if (!v.ok()) Fail(std::string(v.status().message()));
  return std::move(*v);
}

// The enum rows the command line left at "auto" (value 0) that bore on the frame: the renderer
// chose them for the device (vis_mlaa_coverage only when the frame ran vis_mlaa).
std::vector<const tessera::SettingRow*> AutoRows(const tessera::Settings& asked,
                                                 const tessera::Settings& ran) {
  using namespace tessera;
  std::vector<const SettingRow*> rows;
  for (const SettingRow& row : SettingsTable()) {
    if (!row.Chooses() || row.get(asked) != 0.0) continue;
    if (row.name == "vis_mlaa_coverage" && ran.aa != AaMode::kVisMlaa) continue;
    rows.push_back(&row);
  }
  return rows;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace tessera;
  std::string scene_path, out_path = "tessera.jpg", device;
  Settings settings;
  SettingMask named;  // the settings the command line gave (unused: every field has a default)
  Camera camera;
  bool explicit_camera = false, frame_bounds = false, json = false, validation = false;
  bool fov_set = false;
  int camera_index = -1;
  uint32_t frames = 1;
  std::optional<float> znear, zfar;

  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) Fail(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--help" || arg == "-h") {
      std::fputs(kUsage, stdout);
      std::fputs(SettingsFlagsUsage().c_str(), stdout);
      return 0;
    } else if (arg == "--scene")
      scene_path = value();
    else if (arg == "--out")
      out_path = value();
    else if (arg == "--camera")
      camera_index = int(ParseUint(arg, value()));
    else if (arg == "--frame")
      frame_bounds = true;
    else if (arg == "--eye") {
      camera.eye = ParseVec3(arg, value());
      explicit_camera = true;
    } else if (arg == "--target") {
      camera.target = ParseVec3(arg, value());
      explicit_camera = true;
    } else if (arg == "--up")
      camera.up = ParseVec3(arg, value());
    else if (arg == "--fov") {
      camera.yfov = glm::radians(ParseFloat(arg, value()));
      fov_set = true;
    } else if (arg == "--near")
      znear = ParseFloat(arg, value());
    else if (arg == "--far")
      zfar = ParseFloat(arg, value());
    else if (absl::StatusOr<bool> setting = ParseSettingFlag(arg, value, &settings, &named);
             !setting.ok())
      Fail(std::string(setting.status().message()));
    else if (*setting) {
      // a settings flag (renderer/settings_table.h)
    } else if (arg == "--frames")
      frames = std::max(1u, ParseUint(arg, value()));
    else if (arg == "--device")
      device = value();
    else if (arg == "--validation")
      validation = true;
    else if (arg == "--json")
      json = true;
    else
      Fail("unknown option '" + arg + "' (see --help)");
  }
  const bool png = out_path.size() >= 4 && out_path.substr(out_path.size() - 4) == ".png";

  std::unique_ptr<Renderer> renderer = OrFail(Renderer::Create({device, validation}));
  SceneHandle scene;
  if (scene_path.empty()) {
    scene = OrFail(renderer->LoadScene(BuildDemoScene()));
  } else {
    scene = OrFail(renderer->LoadScene(OrFail(LoadGltfSourceFromDisk(scene_path))));
  }
  const SceneInfo& info = scene->info();
  for (const std::string& w : info.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());

  const float aspect = float(settings.width) / float(std::max(1u, settings.height));
  if (!explicit_camera) {
    if (camera_index >= 0 && size_t(camera_index) >= info.cameras.size())
      Fail(absl::StrFormat("--camera %d: the scene has %d cameras", camera_index,
                           info.cameras.size()));
    if (!frame_bounds && !info.cameras.empty()) {
      const float fov = camera.yfov;
      camera = FromSceneCamera(info.cameras[std::max(camera_index, 0)], std::max(camera_index, 0));
      if (fov_set) camera.yfov = fov;
    } else {
      camera = FrameBounds(info.bounds, camera.yfov, aspect);
    }
  }
  if (znear) camera.znear = *znear;
  if (zfar) camera.zfar = *zfar;

  Frame frame;
  for (uint32_t f = 0; f < frames; ++f) frame = OrFail(renderer->Render(*scene, camera, settings));
  const std::vector<uint8_t> bytes =
      OrFail(EncodeFrame(frame, png ? ImageFormat::kPng : ImageFormat::kJpeg));
  // The output's directory is made if missing (tessera-render --out renders/shot.jpg).
  if (const std::filesystem::path dir = std::filesystem::path(out_path).parent_path();
      !dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) Fail("cannot create the directory " + dir.string() + ": " + ec.message());
  }
  if (absl::Status st = WriteFileBytes(out_path, bytes); !st.ok()) Fail(std::string(st.message()));

  const DeviceInfo& dev = renderer->device_info();
  if (json) {
    nlohmann::json j;
    j["device"] = {{"name", dev.name},
                   {"type", dev.type},
                   {"driver", dev.driver_info},
                   {"max_samples", dev.max_samples},
                   {"max_image_dimension", dev.max_image_dimension},
                   {"fallbacks", nlohmann::json::array()}};
    for (const DeviceFallback& f : dev.fallbacks)
      j["device"]["fallbacks"].push_back({{"missing", f.missing}, {"path", f.path}});
    j["scene"] = {{"name", info.name},
                  {"drawables", frame.stats.drawables},
                  {"triangles", info.counts.triangles},
                  {"bounds_min", {info.bounds.min.x, info.bounds.min.y, info.bounds.min.z}},
                  {"bounds_max", {info.bounds.max.x, info.bounds.max.y, info.bounds.max.z}}};
    j["output"] = {{"path", out_path},
                   {"bytes", bytes.size()},
                   {"width", frame.image.width},
                   {"height", frame.image.height}};
    for (const PassTiming& p : frame.passes)
      j["passes"].push_back(
          {{"pass", p.pass}, {"gpu_ms", p.gpu_ms}, {"timestamp_ms", p.timestamp_ms}});
    j["timing"] = ToString(frame.timing);
    j["gpu_total_ms"] = frame.gpu_total_ms;
    j["submissions"] = frame.cpu.submissions;
    j["cpu_ms"] = {{"record", frame.cpu.record_ms},
                   {"submit_wait", frame.cpu.submit_wait_ms},
                   {"readback", frame.cpu.readback_ms},
                   {"encode", frame.cpu.encode_ms}};
    j["stats"] = {{"draws", frame.stats.draws},
                  {"indirect_draws", frame.stats.indirect_draws},
                  {"triangles_submitted", frame.stats.triangles_submitted},
                  {"drawables", frame.stats.drawables},
                  {"drawables_in_frustum", frame.stats.drawables_in_frustum},
                  {"drawables_drawn", frame.stats.drawables_drawn},
                  {"drawables_culled", frame.stats.drawables_culled},
                  {"drawables_late", frame.stats.drawables_late},
                  {"drawables_stale", frame.stats.drawables_stale},
                  {"primitives_in", frame.stats.primitives_in},
                  {"fragment_invocations", frame.stats.fragment_invocations},
                  {"shaded_pixels", frame.stats.shaded_pixels},
                  {"shading_invocations", frame.stats.shading_invocations},
                  {"shading_dispatches", frame.stats.shading_dispatches},
                  {"edge_pixels", frame.stats.edge_pixels},
                  {"runner_up_pixels", frame.stats.runner_up_pixels},
                  {"blend_pixels", frame.stats.blend_pixels},
                  {"lights", frame.stats.lights},
                  {"local_lights", frame.stats.local_lights},
                  {"tile_lights_avg", frame.stats.tile_lights_avg},
                  {"tile_lights_p50", frame.stats.tile_lights_p50},
                  {"tile_lights_p95", frame.stats.tile_lights_p95},
                  {"tile_lights_max", frame.stats.tile_lights_max},
                  {"tile_overflows", frame.stats.tile_overflows}};
    j["notes"] = nlohmann::json::array();
    for (const SettingNote& n : frame.settings.notes)
      j["notes"].push_back({{"field", n.field}, {"message", n.message}});
    // The settings the frame ran with, every row of the settings table (auto resolved), and the
    // rows left at auto that bore on the frame.
    nlohmann::json& effective = j["settings"] = nlohmann::json::object();
    for (const SettingRow& row : SettingsTable()) {
      const double v = row.get(frame.settings.effective);
      nlohmann::json& out = effective[std::string(row.name)];
      if (row.type == SettingType::kBool) {
        out = v != 0.0;
      } else if (row.type == SettingType::kUint) {
        out = uint64_t(v);
      } else if (row.type == SettingType::kFloat) {
        out = cli::FloatForJson(float(v));  // 0.05, not 0.0500000007
      } else {
        out = row.Format(v);
      }
    }
    effective["animation"] = frame.settings.effective.animation;
    j["auto"] = nlohmann::json::array();
    for (const SettingRow* row : AutoRows(settings, frame.settings.effective))
      j["auto"].push_back(std::string(row->name));
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("device   %s (%s, %s), max %ux MSAA, max %u px\n", dev.name.c_str(),
                dev.type.c_str(), dev.driver_info.c_str(), dev.max_samples,
                dev.max_image_dimension);
    for (const DeviceFallback& f : dev.fallbacks)
      std::printf("fallback no %s: %s\n", f.missing.c_str(), f.path.c_str());
    std::printf("scene    %s: %u drawables, %llu triangles, %u culled\n", info.name.c_str(),
                frame.stats.drawables, (unsigned long long)info.counts.triangles,
                frame.stats.drawables_culled);
    if (info.bounds.empty()) {
      std::printf("bounds   (empty scene)\n");
    } else {
      std::printf("bounds   (%.3g, %.3g, %.3g) .. (%.3g, %.3g, %.3g)\n", info.bounds.min.x,
                  info.bounds.min.y, info.bounds.min.z, info.bounds.max.x, info.bounds.max.y,
                  info.bounds.max.z);
    }
    const glm::vec3 eye = CameraPosition(camera);
    if (camera.view) {
      const glm::vec3 forward = -glm::vec3(glm::inverse(*camera.view)[2]);
      std::printf("camera   eye (%.3g, %.3g, %.3g) looking along (%.3g, %.3g, %.3g)\n", eye.x,
                  eye.y, eye.z, forward.x, forward.y, forward.z);
    } else {
      std::printf("camera   eye (%.3g, %.3g, %.3g) target (%.3g, %.3g, %.3g)\n", eye.x, eye.y,
                  eye.z, camera.target.x, camera.target.y, camera.target.z);
    }
    std::printf("output   %s (%ux%u, %zu bytes)\n\n", out_path.c_str(), frame.image.width,
                frame.image.height, bytes.size());
    std::printf("%-20s %10s%s\n", "pass", "gpu ms",
                frame.timing == TimingSource::kPassWallClock
                    ? "   (CPU device: each pass submitted alone, timed by the wall clock)"
                : frame.timing == TimingSource::kFrameWallClock
                    ? "   (CPU device, one submission: the passes as its timestamps say, the "
                      "total by the wall clock)"
                    : "");
    for (const PassTiming& p : frame.passes)
      std::printf("%-20s %10.3f\n", p.pass.c_str(), p.gpu_ms);
    std::printf("%-20s %10.3f\n\n", "total", frame.gpu_total_ms);
    std::printf("%-20s %10s\n", "cpu stage", "ms");
    std::printf("%-20s %10.3f\n%-20s %10.3f\n%-20s %10.3f\n%-20s %10.3f\n", "record",
                frame.cpu.record_ms, "submit->fence", frame.cpu.submit_wait_ms, "readback",
                frame.cpu.readback_ms, "encode", frame.cpu.encode_ms);
    std::printf("\ndraws %u (%u indirect), triangles submitted %llu, lights %u\n",
                frame.stats.draws, frame.stats.indirect_draws,
                (unsigned long long)frame.stats.triangles_submitted, frame.stats.lights);
    std::printf("drawables %u: %u in the frustum, %u drawn (%u late, %u stale)\n",
                frame.stats.drawables, frame.stats.drawables_in_frustum,
                frame.stats.drawables_drawn, frame.stats.drawables_late,
                frame.stats.drawables_stale);
    if (frame.stats.pipeline_statistics)
      std::printf("device counted %llu primitives in, %llu rasterized, %llu fragment invocations\n",
                  (unsigned long long)frame.stats.primitives_in,
                  (unsigned long long)frame.stats.primitives_clipped,
                  (unsigned long long)frame.stats.fragment_invocations);
    if (frame.stats.shading_dispatches > 0)
      std::printf("visibility shading: %llu pixels in %u dispatch%s (%s), %llu invocations\n",
                  (unsigned long long)frame.stats.shaded_pixels, frame.stats.shading_dispatches,
                  frame.stats.shading_dispatches == 1 ? "" : "es",
                  renderer->device_info().shade_all_materials ? "one over every pixel"
                                                              : "one per material in view",
                  (unsigned long long)frame.stats.shading_invocations);
    if (frame.stats.local_lights > 0 && frame.settings.effective.light_culling)
      std::printf("lights per %upx tile: avg %.1f, p50 %u, p95 %u, max %u, overflows %u\n",
                  frame.settings.effective.tile_size, frame.stats.tile_lights_avg,
                  frame.stats.tile_lights_p50, frame.stats.tile_lights_p95,
                  frame.stats.tile_lights_max, frame.stats.tile_overflows);
    // What each setting left to the renderer ("auto") ran as on this device.
    std::string chosen;
    for (const SettingRow* row : AutoRows(settings, frame.settings.effective)) {
      absl::StrAppend(&chosen, chosen.empty() ? "" : ", ", std::string(row->name), " ",
                      row->Format(row->get(frame.settings.effective)));
    }
    if (!chosen.empty()) std::printf("auto: %s\n", chosen.c_str());
    for (const SettingNote& n : frame.settings.notes)
      std::printf("note: %s: %s\n", n.field.c_str(), n.message.c_str());
  }
  if (renderer->validation_message_count() > 0) {
    std::fprintf(stderr, "tessera-render: %llu Vulkan validation messages\n",
                 (unsigned long long)renderer->validation_message_count());
    return 1;
  }
  return 0;
}
