// tessera-lighting-bench: what shadows and SSAO cost, as JSON. By default Sponza at 1280x720
// from the east end of the atrium, with the sun, --shadow-lights (16) shadowed point lights and
// --lights (1024) more unshadowed ones (synthetic, seeded), medians over --frames frames:
//  - shadows uncached (shadow_cache off: every face rendered every frame) against cached with
//    nothing moving (after one frame that fills the atlas): the shadows pass, the shading pass,
//    the frame, and how many faces were rendered. Target: cached <= 10% of uncached.
//  - SSAO at half resolution against full resolution: the ssao pass (obscurance + blur).
//    Target: half <= 40% of full.
//  - the frame without shadows or SSAO, for the cost of the lookups in the shading pass.
// Frames alternate between the configurations being compared, so machine noise hits both alike.
#include <cstdio>
#include <glm/glm.hpp>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "absl/strings/numbers.h"
#include "bench_scene.h"
#include "bench_util.h"
#include "renderer/camera.h"
#include "renderer/renderer.h"
#include "renderer/scene/demo_scene.h"

namespace {

using tessera::bench::Fail;
using tessera::bench::Median;

constexpr glm::vec3 kSponzaEye(9.0f, 1.6f, -1.0f), kSponzaTarget(-5.0f, 3.5f, 1.5f);

uint32_t ParseUint(const std::string& flag, const std::string& s) {
  uint32_t v = 0;
  if (!absl::SimpleAtoi(s, &v)) Fail(flag + ": not a number: " + s);
  return v;
}

double PassMs(const tessera::Frame& f, const char* name) {
  for (const tessera::PassTiming& p : f.passes)
    if (p.pass == name) return p.gpu_ms;
  return 0.0;
}

// Per-frame samples of one configuration.
struct Samples {
  std::vector<double> shadows, ssao, shading, frame;
  tessera::FrameStats stats;
  void Add(const tessera::Frame& f) {
    shadows.push_back(PassMs(f, "shadows"));
    ssao.push_back(PassMs(f, "ssao"));
    shading.push_back(PassMs(f, "forward"));
    frame.push_back(f.gpu_total_ms);
    stats = f.stats;
  }
  nlohmann::json Json() const {
    return {{"shadows_ms", Median(shadows)},
            {"ssao_ms", Median(ssao)},
            {"forward_ms", Median(shading)},
            {"frame_ms", Median(frame)},
            {"shadow_views", stats.shadow_views},
            {"shadow_faces_rendered", stats.shadow_faces_rendered},
            {"shadow_draws", stats.shadow_draws},
            {"shadowed_lights", stats.shadowed_lights}};
  }
};

}  // namespace

int main(int argc, char** argv) {
  using namespace tessera;
  std::string scene_path = std::string(TESSERA_DEFAULT_ASSETS_DIR) + "/Sponza/glTF/Sponza.gltf";
  uint32_t width = 1280, height = 720, lights = 1024, shadow_lights = 16, frames = 5;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) Fail(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--scene") {
      scene_path = value();
    } else if (arg == "--demo") {
      scene_path.clear();
    } else if (arg == "--width") {
      width = ParseUint(arg, value());
    } else if (arg == "--height") {
      height = ParseUint(arg, value());
    } else if (arg == "--lights") {
      lights = ParseUint(arg, value());
    } else if (arg == "--shadow-lights") {
      shadow_lights = ParseUint(arg, value());
    } else if (arg == "--frames") {
      frames = ParseUint(arg, value());
    } else {
      Fail("unknown argument " + arg +
           " (--scene F | --demo, --width N --height N --lights N --shadow-lights N --frames N)");
    }
  }
  if (frames == 0) Fail("--frames must be at least 1");
  absl::StatusOr<std::unique_ptr<Renderer>> renderer = Renderer::Create();
  if (!renderer.ok()) Fail(std::string(renderer.status().message()));
  const SceneHandle scene = bench::LoadSceneOrDemo(**renderer, scene_path);
  const SceneInfo& info = scene->info();
  Camera cam;
  if (scene_path.find("Sponza") != std::string::npos) {
    cam.eye = kSponzaEye;
    cam.target = kSponzaTarget;
  } else {
    cam = !info.cameras.empty() ? FromSceneCamera(info.cameras[0])
                                : FrameBounds(info.bounds, 0.8f, float(width) / height);
  }

  Settings base;
  base.width = width;
  base.height = height;
  base.synthetic_lights = lights + shadow_lights;  // the most important get the shadows
  base.shadow_lights = shadow_lights;
  Settings cached = base;
  cached.shadows = true;
  Settings uncached = cached;
  uncached.shadow_cache = false;
  Settings half = base;
  half.ssao = true;
  Settings full = half;
  full.ssao_half_res = false;

  auto render = [&](const Settings& s, uint64_t view) {
    absl::StatusOr<Frame> f = (*renderer)->Render(*scene, cam, s, view);
    if (!f.ok()) Fail(std::string(f.status().message()));
    return std::move(*f);
  };
  // One frame of each first: pipelines, targets, and the cached atlas filled.
  for (const Settings* s : {&base, &cached, &uncached, &half, &full}) render(*s, 1);
  Samples none, with_cache, without_cache, ssao_half, ssao_full;
  for (uint32_t f = 0; f < frames; ++f) {
    with_cache.Add(render(cached, 1));
    without_cache.Add(render(uncached, 2));
    ssao_half.Add(render(half, 1));
    ssao_full.Add(render(full, 1));
    none.Add(render(base, 1));
  }
  const double shadow_ratio =
      Median(with_cache.shadows) / std::max(Median(without_cache.shadows), 1e-9);
  const double ssao_ratio = Median(ssao_half.ssao) / std::max(Median(ssao_full.ssao), 1e-9);
  nlohmann::json out;
  out["device"] = (*renderer)->device_info().name;
  out["scene"] = info.name;
  out["width"] = width;
  out["height"] = height;
  out["frames"] = frames;
  out["lights"] = {{"sun", 1}, {"shadowed", shadow_lights}, {"unshadowed", lights}};
  out["no_effects"] = none.Json();
  out["shadows_uncached"] = without_cache.Json();
  out["shadows_cached_still"] = with_cache.Json();
  out["ssao_half_res"] = ssao_half.Json();
  out["ssao_full_res"] = ssao_full.Json();
  out["shadows_cached_over_uncached"] = shadow_ratio;
  out["shadows_target_met"] = shadow_ratio <= 0.10;
  out["ssao_half_over_full"] = ssao_ratio;
  out["ssao_target_met"] = ssao_ratio <= 0.40;
  std::printf("%s\n", out.dump(2).c_str());
  return 0;
}
