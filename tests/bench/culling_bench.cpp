// tessera-cull-bench: the geometry culling modes along fixed camera paths, as JSON on stdout.
//
// Sponza and the generated city (renderer/scene/city_scene.h) are walked along deterministic
// camera paths. Each frame is rendered once without culling with a drawable-id capture (the ids
// on top somewhere are the truly visible drawables), then once per culling mode, each mode in
// its own view so that gpu_occlusion carries its history along the path. Targets, reported and
// not enforced (the exit status is non-zero only on errors): inside Sponza gpu_occlusion submits
// <= 1.5x the triangles of the truly visible drawables; the city renders >= 3x faster with
// gpu_occlusion than without culling. A table goes to stderr. Compare ratios within one run.
//
//   tessera-cull-bench [--scene ../shared/assets/Sponza/glTF/Sponza.gltf] [--scenes sponza,city]
//       [--modes none,gpu_occlusion] [--frames 24] [--warmup 2] [--city-detail 2] [--smoke]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <glm/glm.hpp>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"
#include "bench_util.h"
#include "renderer/camera.h"
#include "renderer/renderer.h"
#include "renderer/scene/city_scene.h"
#include "renderer/scene/gltf_import.h"

#ifndef TESSERA_DEFAULT_ASSETS_DIR
#define TESSERA_DEFAULT_ASSETS_DIR "../shared/assets"
#endif

namespace tessera {
namespace {

using bench::Fail;
using bench::Median;
using bench::Percentile;
using Json = nlohmann::ordered_json;  // keeps keys in the order written

constexpr float kPi = 3.14159265f;
constexpr uint64_t kTruthView = 1;       // the unculled id frames
constexpr uint64_t kModeViewBase = 100;  // + mode: one view per mode

struct Options {
  std::string scene_path, device;  // scene_path empty: <assets>/Sponza/glTF/Sponza.gltf
  std::vector<std::string> scenes = {"sponza", "city"};
  std::vector<CullingMode> modes = {CullingMode::kNone, CullingMode::kCpuFrustum,
                                    CullingMode::kGpuFrustum, CullingMode::kGpuOcclusion};
  uint32_t width = 1280, height = 720, frames = 24, warmup = 2;
  CityParams city;
  bool smoke = false;
};

uint32_t ParseUint(const std::string& flag, const std::string& s) {
  uint32_t v = 0;
  if (!absl::SimpleAtoi(s, &v)) Fail(flag + ": not a number: " + s);
  return v;
}

Camera LookAlong(glm::vec3 eye, glm::vec3 dir, float distance) {
  Camera c;
  c.eye = eye;
  c.target = eye + distance * dir;
  c.yfov = 1.0f;
  c.znear = 0.1f;
  return c;
}

// Down the atrium at eye height looking along -x with a gentle sinusoidal yaw, then (the last
// quarter of the frames) turning on the spot to look back diagonally along the arcade.
std::vector<Camera> SponzaPath(uint32_t frames) {
  const uint32_t turn = frames / 4, walk = frames - turn;
  const glm::vec3 from(9.0f, 1.6f, -0.4f), to(-9.0f, 1.6f, 0.4f);
  auto dir = [](float yaw) {
    return glm::normalize(glm::vec3(-std::cos(yaw), 0.12f, std::sin(yaw)));
  };
  std::vector<Camera> path;
  for (uint32_t i = 0; i < walk; ++i) {
    const float t = walk > 1 ? float(i) / float(walk - 1) : 0.0f;
    path.push_back(LookAlong(glm::mix(from, to, t), dir(0.3f * std::sin(2.0f * kPi * t)), 10.0f));
  }
  for (uint32_t i = 1; i <= turn; ++i)
    path.push_back(LookAlong(to, dir(0.75f * kPi * float(i) / float(turn)), 10.0f));
  return path;
}

// Down the middle street from the city's +z edge towards -z at 1.7 m, 3 m a frame, looking
// ahead with a small yaw sweep.
std::vector<Camera> CityPath(const CityParams& p, uint32_t frames) {
  const float x = CityStreetX(p, p.blocks_x / 2), z0 = CityStreetZ(p, p.blocks_z) - 2.0f;
  std::vector<Camera> path;
  for (uint32_t i = 0; i < frames; ++i) {
    const float yaw = 0.15f * std::sin(2.0f * kPi * float(i) / float(frames));
    path.push_back(
        LookAlong({x, 1.7f, z0 - 3.0f * float(i)}, {std::sin(yaw), 0.0f, -std::cos(yaw)}, 100.0f));
  }
  return path;
}

// One scene on the device, with what the truly-visible reference needs from its CpuScene.
struct BenchScene {
  std::string name, file;
  SceneHandle handle;
  // Per drawable, in CpuScene order (the order of FrameCapture::ids and ::drawn): its triangles,
  // and what triangles_submitted counts for it when a frame draws it. triangles_submitted sums
  // every geometry pass: an opaque or masked drawable is submitted by the depth prepass (early
  // or late phase) and again by the forward pass, hence 2x its triangles; a blended one only by
  // the transparent pass, 1x (shadows are off). So a frame drawing exactly the truly visible
  // drawables submits the sum of `submitted` over them, and no culling can do better.
  std::vector<uint64_t> triangles, submitted;
  std::vector<Camera> path;
};

BenchScene Upload(Renderer& r, const std::string& name, const CpuScene& cpu) {
  BenchScene s;
  s.name = name;
  absl::StatusOr<SceneHandle> handle = r.LoadScene(cpu);
  if (!handle.ok()) Fail(name + ": " + std::string(handle.status().message()));
  s.handle = *handle;
  for (const Drawable& d : cpu.drawables) {
    const Primitive& p = cpu.primitives[d.primitive];
    const uint64_t tris = p.index_count / 3;
    s.triangles.push_back(tris);
    s.submitted.push_back(cpu.materials[p.material].alpha_mode == AlphaMode::kBlend ? tris
                                                                                    : 2 * tris);
  }
  return s;
}

// The measured frames of one mode.
struct ModeRun {
  std::vector<double> frame_ms;
  std::vector<std::string> pass_order;
  std::map<std::string, std::vector<double>> pass_ms;
  std::vector<FrameStats> stats;
  uint64_t missed = 0;  // truly visible drawables not drawn (0 unless culling is wrong)
};

// The mean of one FrameStats field over frames.
template <typename T>
double Mean(const std::vector<FrameStats>& frames, T FrameStats::*field) {
  double sum = 0.0;
  for (const FrameStats& s : frames) sum += double(s.*field);
  return frames.empty() ? 0.0 : sum / double(frames.size());
}

// a / b, or null when b is 0.
Json Ratio(double a, double b) { return b > 0.0 ? Json(a / b) : Json(); }

Json RunScene(Renderer& r, const BenchScene& sc, const Options& o) {
  auto render = [&](CullingMode mode, const Camera& cam, uint64_t view, FrameCapture* capture) {
    Settings s;
    s.width = o.width;
    s.height = o.height;
    s.culling = mode;
    absl::StatusOr<Frame> frame = r.Render(*sc.handle, cam, s, view, capture);
    if (!frame.ok())
      Fail(sc.name + " " + std::string(ToString(mode)) + ": " +
           std::string(frame.status().message()));
    return std::move(*frame);
  };
  // Warm-up at the path's first camera, so that gpu_occlusion starts the path with history.
  for (CullingMode m : o.modes)
    for (uint32_t i = 0; i < o.warmup; ++i)
      render(m, sc.path[0], kModeViewBase + uint64_t(m), nullptr);

  const size_t n = sc.triangles.size();
  std::vector<ModeRun> runs(o.modes.size());
  uint64_t visible_drawables = 0, visible_triangles = 0, visible_submitted = 0;
  TimingSource timing = TimingSource::kGpuTimestamps;
  for (const Camera& cam : sc.path) {
    // The reference frame (its own view, so it does not disturb the modes' history).
    FrameCapture truth;
    truth.want_ids = true;
    render(CullingMode::kNone, cam, kTruthView, &truth);
    std::vector<bool> visible(n, false);
    for (uint32_t id : truth.ids)
      if (id != 0 && id <= n) visible[id - 1] = true;
    for (size_t d = 0; d < n; ++d) {
      if (!visible[d]) continue;
      visible_drawables++;
      visible_triangles += sc.triangles[d];
      visible_submitted += sc.submitted[d];
    }
    for (size_t i = 0; i < o.modes.size(); ++i) {
      FrameCapture cap;  // for the drawn list; copied out after the frame, so not timed
      const Frame frame = render(o.modes[i], cam, kModeViewBase + uint64_t(o.modes[i]), &cap);
      ModeRun& run = runs[i];
      timing = frame.timing;
      run.frame_ms.push_back(frame.gpu_total_ms);
      for (const PassTiming& p : frame.passes) {
        if (!run.pass_ms.count(p.pass)) run.pass_order.push_back(p.pass);
        run.pass_ms[p.pass].push_back(p.gpu_ms);
      }
      run.stats.push_back(frame.stats);
      std::vector<bool> drawn(n, false);
      for (uint32_t d : cap.drawn)
        if (d < n) drawn[d] = true;
      for (size_t d = 0; d < n; ++d) run.missed += visible[d] && !drawn[d];
    }
  }

  const double frames = double(sc.path.size());
  auto per_frame = [&](uint64_t sum) { return double(sum) / frames; };
  uint64_t total_triangles = 0;
  for (uint64_t t : sc.triangles) total_triangles += t;
  Json out;
  out["name"] = sc.name;
  if (!sc.file.empty()) out["file"] = sc.file;
  out["drawables"] = n;
  out["triangles"] = total_triangles;
  out["resolution"] = std::to_string(o.width) + "x" + std::to_string(o.height);
  out["frames"] = sc.path.size();
  out["warmup"] = o.warmup;
  out["timing"] = ToString(timing);
  out["truly_visible"] = {{"drawables_per_frame", per_frame(visible_drawables)},
                          {"triangles_per_frame", per_frame(visible_triangles)},
                          {"triangles_submitted_if_exact_per_frame", per_frame(visible_submitted)}};
  const ModeRun* none = nullptr;
  for (size_t i = 0; i < o.modes.size(); ++i)
    if (o.modes[i] == CullingMode::kNone) none = &runs[i];

  std::fprintf(stderr, "%s %s, %zu frames, %zu drawables, truly visible %.1f drawables/frame\n",
               sc.name.c_str(), out["resolution"].get<std::string>().c_str(), sc.path.size(), n,
               per_frame(visible_drawables));
  std::fprintf(stderr, "  %-14s %10s %8s %14s %20s\n", "mode", "median ms", "x none",
               "triangles/fr", "drawn/frustum");
  Json modes;
  for (size_t i = 0; i < o.modes.size(); ++i) {
    ModeRun& run = runs[i];
    const std::string name(ToString(o.modes[i]));
    auto mean = [&](auto field) { return Mean(run.stats, field); };
    const double triangles = mean(&FrameStats::triangles_submitted);
    const bool pipeline_stats = !run.stats.empty() && run.stats[0].pipeline_statistics;
    Json m;
    m["frame_ms_median"] = Median(run.frame_ms);
    m["frame_ms_p95"] = Percentile(run.frame_ms, 95.0);
    Json passes = Json::object();
    for (const std::string& p : run.pass_order) passes[p] = Median(run.pass_ms[p]);
    m["pass_ms_median"] = passes;
    m["triangles_submitted_per_frame"] = triangles;
    m["drawables_drawn_per_frame"] = mean(&FrameStats::drawables_drawn);
    m["drawables_in_frustum_per_frame"] = mean(&FrameStats::drawables_in_frustum);
    m["drawables_late_per_frame"] = mean(&FrameStats::drawables_late);
    m["drawables_stale_per_frame"] = mean(&FrameStats::drawables_stale);
    m["draws_per_frame"] = mean(&FrameStats::draws);
    m["indirect_draws_per_frame"] = mean(&FrameStats::indirect_draws);
    // Device counters, null where the device has no pipeline statistics queries.
    m["primitives_in_per_frame"] = pipeline_stats ? Json(mean(&FrameStats::primitives_in)) : Json();
    m["fragment_invocations_per_frame"] =
        pipeline_stats ? Json(mean(&FrameStats::fragment_invocations)) : Json();
    m["visible_drawables_missed"] = run.missed;
    // Speed-up: median frame time without culling over this mode's (> 1 is faster).
    m["ratio_ms_vs_none"] = none ? Ratio(Median(none->frame_ms), Median(run.frame_ms)) : Json();
    // Fraction of the unculled triangles this mode still submits.
    m["ratio_triangles_vs_none"] =
        none ? Ratio(triangles, Mean(none->stats, &FrameStats::triangles_submitted)) : Json();
    // Submitted over what drawing exactly the truly visible drawables would submit (see
    // BenchScene::submitted: 2x their triangles, one for the prepass and one for forward).
    m["triangles_vs_truly_visible"] = Ratio(triangles, per_frame(visible_submitted));
    char speedup[32] = "-";
    if (m["ratio_ms_vs_none"].is_number())
      std::snprintf(speedup, sizeof(speedup), "%.2f", m["ratio_ms_vs_none"].get<double>());
    std::fprintf(stderr, "  %-14s %10.3f %8s %14.0f %9.1f/%-10.1f\n", name.c_str(),
                 Median(run.frame_ms), speedup, triangles, mean(&FrameStats::drawables_drawn),
                 mean(&FrameStats::drawables_in_frustum));
    modes[name] = m;
  }
  out["modes"] = modes;
  return out;
}

// A target on the figure at `pointer` in the output: its value where it was measured (else
// null) and whether it is met (null when not measured).
Json Target(const Json& out, const std::string& pointer, const char* text, bool at_most,
            double goal) {
  const Json::json_pointer p(pointer);
  const Json v = out.contains(p) ? out.at(p) : Json();
  const bool met = v.is_number() && (at_most ? v.get<double>() <= goal : v.get<double>() >= goal);
  return {{"value", v}, {"target", text}, {"met", v.is_number() ? Json(met) : Json()}};
}

Options ParseOptions(int argc, char** argv) {
  Options o;
  // --smoke sets small defaults first, so later flags can still change them.
  for (int i = 1; i < argc; ++i) {
    if (std::string(argv[i]) != "--smoke") continue;
    o.smoke = true;
    o.width = 96;
    o.height = 54;
    o.frames = 4;
    o.city.blocks_x = o.city.blocks_z = 3;
    o.city.buildings_per_side = 4;
  }
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) Fail(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--smoke") continue;
    if (arg == "--scene")
      o.scene_path = value();
    else if (arg == "--device")
      o.device = value();
    else if (arg == "--city")
      o.scenes = {"city"};
    else if (arg == "--scenes") {
      o.scenes = std::vector<std::string>(absl::StrSplit(value(), ','));
      for (const std::string& s : o.scenes)
        if (s != "sponza" && s != "city") Fail("--scenes: want sponza and/or city, got " + s);
    } else if (arg == "--city-detail")
      o.city.facade_detail = ParseUint(arg, value());
    else if (arg == "--width")
      o.width = ParseUint(arg, value());
    else if (arg == "--height")
      o.height = ParseUint(arg, value());
    else if (arg == "--frames")
      o.frames = std::max(1u, ParseUint(arg, value()));
    else if (arg == "--warmup")
      o.warmup = ParseUint(arg, value());
    else if (arg == "--modes") {
      o.modes.clear();
      for (const std::string& m : std::vector<std::string>(absl::StrSplit(value(), ','))) {
        absl::StatusOr<CullingMode> c = ParseCullingMode(m);
        if (!c.ok()) Fail(std::string(c.status().message()));
        if (std::find(o.modes.begin(), o.modes.end(), *c) == o.modes.end()) o.modes.push_back(*c);
      }
    } else {
      Fail("unknown option " + arg +
           " (--scene F --scenes sponza,city --city --city-detail N --width N --height N "
           "--frames N --warmup N --modes MODE,.. --smoke --device NAME)");
    }
  }
  return o;
}

}  // namespace
}  // namespace tessera

int main(int argc, char** argv) {
  using namespace tessera;
  const Options o = ParseOptions(argc, argv);
  absl::StatusOr<std::unique_ptr<Renderer>> renderer = Renderer::Create({o.device, false});
  if (!renderer.ok()) Fail(std::string(renderer.status().message()));

  Json out;
  const DeviceInfo& dev = (*renderer)->device_info();
  out["device"] = {{"name", dev.name}, {"type", dev.type}, {"driver", dev.driver_info}};
  out["scenes"] = Json::object();  // by name: sponza, city
  for (const std::string& name : o.scenes) {
    BenchScene sc;
    if (name == "sponza") {
      std::string path = o.scene_path;
      if (path.empty()) {
        const char* env = std::getenv("TESSERA_ASSETS_DIR");
        path = std::string(env && *env ? env : TESSERA_DEFAULT_ASSETS_DIR) +
               "/Sponza/glTF/Sponza.gltf";
      }
      if (o.smoke && !std::filesystem::exists(path)) {
        std::fprintf(stderr, "sponza skipped: no %s\n", path.c_str());
        out["skipped"].push_back(name);
        continue;
      }
      absl::StatusOr<GltfSource> source = LoadGltfSourceFromDisk(path);
      if (!source.ok()) Fail(std::string(source.status().message()));
      absl::StatusOr<CpuScene> cpu = ImportGltf(*source);
      if (!cpu.ok()) Fail(std::string(cpu.status().message()));
      sc = Upload(**renderer, name, *cpu);
      sc.file = path;
      sc.path = SponzaPath(o.frames);
    } else {
      sc = Upload(**renderer, name, BuildCityScene(o.city));
      sc.path = CityPath(o.city, o.frames);
    }
    out["scenes"][name] = RunScene(**renderer, sc, o);
  }
  out["targets"] = {
      {"sponza_occlusion_triangles_vs_visible",
       Target(out, "/scenes/sponza/modes/gpu_occlusion/triangles_vs_truly_visible", "<= 1.5", true,
              1.5)},
      {"city_occlusion_speedup_vs_none",
       Target(out, "/scenes/city/modes/gpu_occlusion/ratio_ms_vs_none", ">= 3", false, 3.0)}};
  std::printf("%s\n", out.dump(2).c_str());
  // With TESSERA_VALIDATION=1 (as in the smoke test) any validation message is a failure.
  if ((*renderer)->validation_message_count() > 0) {
    for (const std::string& m : (*renderer)->validation_messages())
      std::fprintf(stderr, "validation: %s\n", m.c_str());
    return 1;
  }
  return 0;
}
