// tessera-lights-bench: forward+ light culling against brute-force shading, as JSON.
// For each light count: the light-culling pass, the shading (forward) pass and the frame with
// tile lists (medians over --frames), the same frame shading every light at every pixel (one
// frame; skipped above --brute-max lights, where it takes minutes on lavapipe), the frame with
// no synthetic lights (to separate the cost of the lights from the rest of shading), and the
// lights-per-tile statistics.
#include <cstdio>
#include <glm/glm.hpp>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"
#include "bench_scene.h"
#include "bench_util.h"
#include "renderer/camera.h"
#include "renderer/renderer.h"
#include "renderer/scene/demo_scene.h"

namespace {

using tessera::bench::Fail;
using tessera::bench::Median;
using tessera::bench::ParseVec3;

uint32_t ParseUint(const std::string& flag, const std::string& s) {
  uint32_t v = 0;
  if (!absl::SimpleAtoi(s, &v)) Fail(flag + ": not a number: " + s);
  return v;
}

struct Measured {
  double light_cull = 0, forward = 0, frame = 0;
  tessera::FrameStats stats;
};

Measured Measure(tessera::Renderer& r, const tessera::Scene& scene, const tessera::Camera& cam,
                 const tessera::Settings& s, uint32_t warmup, uint32_t frames) {
  std::vector<double> cull, fwd, total;
  Measured m;
  for (uint32_t f = 0; f < warmup + frames; ++f) {
    absl::StatusOr<tessera::Frame> frame = r.Render(scene, cam, s);
    if (!frame.ok()) Fail(std::string(frame.status().message()));
    if (f < warmup) continue;
    double c = 0.0, fw = 0.0;
    for (const tessera::PassTiming& p : frame->passes) {
      if (p.pass == "light_cull") c = p.gpu_ms;
      if (p.pass == "forward") fw = p.gpu_ms;
    }
    cull.push_back(c);
    fwd.push_back(fw);
    total.push_back(frame->gpu_total_ms);
    m.stats = frame->stats;
  }
  m.light_cull = Median(cull);
  m.forward = Median(fwd);
  m.frame = Median(total);
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace tessera;
  std::string scene_path, device;
  std::vector<uint32_t> counts = {256, 1024, 4096, 20000};
  uint32_t width = 1280, height = 720, frames = 5, warmup = 2, brute_max = 4096, tile = 16;
  std::optional<glm::vec3> eye, target;
  float fov_deg = 0.0f;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) Fail(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--scene")
      scene_path = value();
    else if (arg == "--device")
      device = value();
    else if (arg == "--width")
      width = ParseUint(arg, value());
    else if (arg == "--height")
      height = ParseUint(arg, value());
    else if (arg == "--frames")
      frames = std::max(1u, ParseUint(arg, value()));
    else if (arg == "--warmup")
      warmup = ParseUint(arg, value());
    else if (arg == "--brute-max")
      brute_max = ParseUint(arg, value());
    else if (arg == "--tile-size")
      tile = ParseUint(arg, value());
    else if (arg == "--eye")
      eye = ParseVec3(value());
    else if (arg == "--target")
      target = ParseVec3(value());
    else if (arg == "--fov") {
      if (!absl::SimpleAtof(value(), &fov_deg)) Fail("--fov");
    } else if (arg == "--lights") {
      counts.clear();
      for (const std::string& c : std::vector<std::string>(absl::StrSplit(value(), ',')))
        counts.push_back(ParseUint(arg, c));
    } else {
      Fail("unknown option " + arg +
           " (--scene F --width N --height N --lights N,N.. --frames N --warmup N --brute-max N "
           "--tile-size N --eye X,Y,Z --target X,Y,Z --fov DEG --device NAME)");
    }
  }
  absl::StatusOr<std::unique_ptr<Renderer>> renderer = Renderer::Create({device, false});
  if (!renderer.ok()) Fail(std::string(renderer.status().message()));
  const SceneHandle scene = bench::LoadSceneOrDemo(**renderer, scene_path);
  const SceneInfo& info = scene->info();
  Camera cam = !info.cameras.empty() ? FromSceneCamera(info.cameras[0])
                                     : FrameBounds(info.bounds, 0.8f, float(width) / height);
  if (eye && target) {
    cam = Camera{};
    cam.eye = *eye;
    cam.target = *target;
    cam.znear = 0.05f;
  }
  if (fov_deg > 0.0f) cam.yfov = glm::radians(fov_deg);

  Settings s;
  s.width = width;
  s.height = height;
  s.tile_size = tile;
  s.synthetic_lights = 0;
  const Measured base = Measure(**renderer, *scene, cam, s, warmup, frames);

  nlohmann::json out;
  const DeviceInfo& dev = (*renderer)->device_info();
  out["device"] = {{"name", dev.name}, {"type", dev.type}, {"driver", dev.driver_info}};
  out["scene"] = info.name;
  out["width"] = width;
  out["height"] = height;
  out["tile_size"] = tile;
  out["frames"] = frames;
  out["no_synthetic_lights"] = {{"forward_ms", base.forward}, {"frame_ms", base.frame}};
  for (uint32_t n : counts) {
    s.synthetic_lights = n;
    s.light_culling = true;
    const Measured tiled = Measure(**renderer, *scene, cam, s, warmup, frames);
    nlohmann::json r;
    r["lights"] = n;
    r["tiled"] = {{"light_cull_ms", tiled.light_cull},
                  {"forward_ms", tiled.forward},
                  {"frame_ms", tiled.frame},
                  {"light_cull_share_of_frame", tiled.light_cull / tiled.frame},
                  {"lights_per_tile",
                   {{"avg", tiled.stats.tile_lights_avg},
                    {"p50", tiled.stats.tile_lights_p50},
                    {"p95", tiled.stats.tile_lights_p95},
                    {"max", tiled.stats.tile_lights_max},
                    {"overflows", tiled.stats.tile_overflows}}}};
    // The same with per-tile depth bounds only (no 2.5D mask), to measure what the mask buys.
    s.tile_depth_mask = false;
    const Measured bounds_only = Measure(**renderer, *scene, cam, s, warmup, frames);
    s.tile_depth_mask = true;
    r["tiled_depth_bounds_only"] = {{"light_cull_ms", bounds_only.light_cull},
                                    {"forward_ms", bounds_only.forward},
                                    {"frame_ms", bounds_only.frame},
                                    {"lights_per_tile_avg", bounds_only.stats.tile_lights_avg},
                                    {"lights_per_tile_max", bounds_only.stats.tile_lights_max}};
    if (n <= brute_max) {
      s.light_culling = false;
      const Measured brute = Measure(**renderer, *scene, cam, s, 0, 1);
      r["brute_force"] = {{"forward_ms", brute.forward}, {"frame_ms", brute.frame}};
      // Shading of the lights alone: the forward pass minus what it costs without them.
      const double tiled_lights = std::max(1e-3, tiled.forward - base.forward);
      const double brute_lights = std::max(1e-3, brute.forward - base.forward);
      r["forward_speedup"] = brute.forward / std::max(1e-3, tiled.forward);
      r["light_shading_speedup"] = brute_lights / tiled_lights;
    } else {
      r["brute_force"] = nullptr;
    }
    out["results"].push_back(r);
    std::fprintf(stderr, "lights %u done\n", n);
  }
  std::printf("%s\n", out.dump(2).c_str());
  if ((*renderer)->validation_message_count() > 0) {
    for (const std::string& m : (*renderer)->validation_messages())
      std::fprintf(stderr, "validation: %s\n", m.c_str());
    return 1;
  }
  return 0;
}
