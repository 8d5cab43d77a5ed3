// tessera-bench: renders a scene N times per frame size after a warm-up and prints JSON with
// the median GPU time of every pass and of the total, their spread over the timed frames (min
// and max), and the CPU stages. A program, not a timed test: compare figures as ratios within
// one run (the machines are noisy), and read the spread before reading a difference.
//
//   tessera-bench --scene ../shared/assets/Sponza/glTF/Sponza.gltf
//       --sizes 1280x720,1920x1080 --frames 20 --warmup 3 [--pipeline visibility --aa taa ...]
//
// A comparison in one run: --versus "FLAGS" renders every frame a second time, on a second
// renderer with its own copy of the scene, with FLAGS (settings flags, and --disable-features a,b
// for device features that renderer goes without) applied over the others, alternating which
// goes first, and adds "versus" to each result: the other side's figures and, per frame pair,
// the ratio other / this of the total and of every pass both have (median, min, max). The
// machine's drift between runs then cancels:
//   tessera-bench --scene ... --pipeline forward --versus "--pipeline visibility"
//   tessera-bench --scene ... --pipeline visibility --versus "--disable-features texel_buffers"
//
// Frames lend their pixels to the encoder where the device copied them, as the server's do
// (RendererOptions::lent_buffers; "pixels": "lent"); --copy-pixels copies them out of mapped
// memory first, as before (the readback figure is that copy). Both in one run:
//   tessera-bench --sizes 3840x2160 --versus "--copy-pixels"
//
// Animated scenes: --animation NAME [--time S] poses the scene; --play FPS advances the time by
// 1/FPS each frame, as a playing stream does, so every frame skins again (the skinning pass's
// share of the frame is in "skinning_share"). The skinned crowd:
//   tessera-bench --scene build/default/tests/animated/crowd.gltf --animation wave --play 30
//       --sizes 1280x720
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <glm/glm.hpp>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"
#include "bench_scene.h"
#include "bench_util.h"
#include "renderer/image_io.h"
#include "renderer/renderer.h"
#include "renderer/scene/demo_scene.h"
#include "renderer/settings_table.h"

namespace {

using tessera::bench::Fail;
using tessera::bench::Max;
using tessera::bench::Median;
using tessera::bench::Min;
using tessera::bench::ParseVec3;

// One side of a measurement: a renderer, its scene and view, the settings it renders with, and
// what its timed frames measured (Measured, reset per frame size).
struct Measured {
  std::map<std::string, std::vector<double>> pass_ms, pass_stamp_ms;
  std::vector<std::string> order;
  std::vector<double> total, record, submit_wait, readback, encode, encode_one, ratio,
      skinning_share;
  std::vector<std::map<std::string, double>> frame_passes;  // per timed frame: pass -> ms
};
struct Side : Measured {
  tessera::Renderer* renderer = nullptr;
  tessera::SceneHandle scene;
  tessera::Settings settings;
  uint64_t view = 0;
  float start_time = 0.0f;  // --play: the scene time of the first frame
  tessera::Frame last;

  void Reset() { static_cast<Measured&>(*this) = Measured{}; }

  // Renders and encodes one frame; a timed one (past the warm-up) is recorded.
  void RenderFrame(const tessera::Camera& camera, bool timed) {
    using namespace tessera;
    absl::StatusOr<Frame> frame = renderer->Render(*scene, camera, settings, view);
    if (!frame.ok()) Fail(std::string(frame.status().message()));
    if (absl::StatusOr<std::vector<uint8_t>> jpg = EncodeFrame(*frame, ImageFormat::kJpeg);
        !jpg.ok()) {
      Fail(std::string(jpg.status().message()));
    }
    // The same encode in one strip, for the ratio (EncodeFrame uses AutoJpegStrips).
    const auto t_one = std::chrono::steady_clock::now();
    if (!EncodeJpeg(frame->view(), int(settings.jpeg_quality), ChromaSubsampling::k420, 1).ok())
      Fail("EncodeJpeg");
    const double one_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_one)
            .count();
    if (!timed) return;
    std::map<std::string, double>& passes = frame_passes.emplace_back();
    for (const PassTiming& p : frame->passes) {
      if (!pass_ms.count(p.pass)) order.push_back(p.pass);
      pass_ms[p.pass].push_back(p.gpu_ms);
      pass_stamp_ms[p.pass].push_back(p.timestamp_ms);
      passes[p.pass] += p.gpu_ms;
    }
    total.push_back(frame->gpu_total_ms);
    for (const PassTiming& p : frame->passes)
      if (p.pass == "skinning") skinning_share.push_back(p.gpu_ms / frame->gpu_total_ms);
    record.push_back(frame->cpu.record_ms);
    submit_wait.push_back(frame->cpu.submit_wait_ms);
    readback.push_back(frame->cpu.readback_ms);
    encode.push_back(frame->cpu.encode_ms);
    encode_one.push_back(one_ms);
    double stamp_total = 0.0;
    for (const PassTiming& p : frame->passes) stamp_total += p.timestamp_ms;
    ratio.push_back(stamp_total / std::max(1e-6, frame->cpu.submit_wait_ms));
    renderer->ReleasePixels(last);  // as the server gives them back
    last = std::move(*frame);
  }

  nlohmann::json Result(uint32_t w, uint32_t h) const {
    using namespace tessera;
    nlohmann::json r;
    r["width"] = w;
    r["height"] = h;
    nlohmann::json passes = nlohmann::json::array();
    for (const std::string& name : order)
      passes.push_back({{"pass", name},
                        {"gpu_ms_median", Median(pass_ms.at(name))},
                        {"gpu_ms_min", Min(pass_ms.at(name))},
                        {"gpu_ms_max", Max(pass_ms.at(name))},
                        {"timestamp_ms_median", Median(pass_stamp_ms.at(name))}});
    r["passes"] = passes;
    r["gpu_total_ms_median"] = Median(total);
    r["gpu_total_ms_min"] = Min(total);
    r["gpu_total_ms_max"] = Max(total);
    r["cpu_ms_median"] = {{"record", Median(record)},
                          {"submit_wait", Median(submit_wait)},
                          {"readback", Median(readback)},
                          {"encode_jpeg", Median(encode)},
                          {"encode_jpeg_one_strip", Median(encode_one)}};
    r["jpeg_strips"] = AutoJpegStrips(last.view());
    r["pixels"] = last.lent ? "lent" : "copied";
    // Frame-total timestamps against the wall clock from submit to fence.
    r["timestamp_total_over_wall"] = Median(ratio);
    r["timing"] = ToString(last.timing);
    const double pixels = double(w) * h;
    r["pipeline"] = ToString(last.settings.effective.pipeline);
    r["aa"] = ToString(last.settings.effective.aa);
    r["stats"] = {
        {"draws", last.stats.draws},
        {"triangles_submitted", last.stats.triangles_submitted},
        {"drawables_culled", last.stats.drawables_culled},
        {"fragment_invocations_per_pixel", double(last.stats.fragment_invocations) / pixels},
        {"shaded_pixels", last.stats.shaded_pixels},
        {"shading_invocations_per_pixel", double(last.stats.shading_invocations) / pixels},
        {"shading_dispatches", last.stats.shading_dispatches},
        {"edge_pixels", last.stats.edge_pixels},
        {"runner_up_pixels", last.stats.runner_up_pixels},
        {"blend_pixels", last.stats.blend_pixels},
        {"animated_drawables", last.stats.animated_drawables},
        {"deformed_vertices", last.stats.deformed_vertices}};
    if (!skinning_share.empty()) {
      r["skinning_share_median"] = Median(skinning_share);
      r["skinning_share_min"] = Min(skinning_share);
      r["skinning_share_max"] = Max(skinning_share);
    }
    return r;
  }
};

// Per frame pair, b / a: the median, min and max of the ratios.
nlohmann::json PairRatios(const std::vector<double>& a, const std::vector<double>& b) {
  std::vector<double> r;
  for (size_t i = 0; i < std::min(a.size(), b.size()); ++i)
    if (a[i] > 0.0) r.push_back(b[i] / a[i]);
  return {{"median", Median(r)}, {"min", Min(r)}, {"max", Max(r)}};
}

}  // namespace

int main(int argc, char** argv) {
  using namespace tessera;
  std::string scene_path, device;
  std::vector<std::pair<uint32_t, uint32_t>> sizes = {{1280, 720}, {1920, 1080}};
  uint32_t frames = 20, warmup = 3;
  double play_fps = 0.0;
  std::optional<glm::vec3> eye, target;
  Settings base;
  SettingMask named;
  std::string versus;
  bool copy_pixels = false;  // frames copied out of mapped memory (the server lends them)
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
    else if (arg == "--frames") {
      if (!absl::SimpleAtoi(value(), &frames) || frames == 0) Fail("--frames");
    } else if (arg == "--warmup") {
      if (!absl::SimpleAtoi(value(), &warmup)) Fail("--warmup");
    } else if (arg == "--play") {
      if (!absl::SimpleAtod(value(), &play_fps) || !(play_fps > 0.0)) Fail("--play wants FPS > 0");
    } else if (arg == "--eye")
      eye = ParseVec3(value());
    else if (arg == "--target")
      target = ParseVec3(value());
    else if (arg == "--versus")
      versus = value();
    else if (arg == "--copy-pixels")
      copy_pixels = true;
    else if (absl::StatusOr<bool> setting = ParseSettingFlag(arg, value, &base, &named);
             !setting.ok()) {
      Fail(std::string(setting.status().message()));
    } else if (*setting) {
      // a settings flag (renderer/settings_table.h): --culling, --pipeline, --aa, --shadows ...
    } else if (arg == "--sizes") {
      sizes.clear();
      const std::vector<std::string> items = absl::StrSplit(value(), ',');
      for (const std::string& s : items) {
        std::vector<std::string> wh = absl::StrSplit(s, 'x');
        uint32_t w, h;
        if (wh.size() != 2 || !absl::SimpleAtoi(wh[0], &w) || !absl::SimpleAtoi(wh[1], &h))
          Fail("--sizes wants WxH[,WxH...], got " + s);
        sizes.emplace_back(w, h);
      }
    } else {
      Fail("unknown option " + arg +
           " (--scene F --sizes WxH,.. --frames N --warmup N --eye X,Y,Z --target X,Y,Z "
           "--play FPS --device NAME --copy-pixels --versus \"FLAGS\", and the settings flags "
           "of tessera-render)");
    }
  }
  // The other side of --versus: the settings with its flags applied over them, and the device
  // features its renderer goes without.
  Settings other = base;
  std::vector<std::string> other_disabled;
  bool other_copy_pixels = copy_pixels;
  if (!versus.empty()) {
    const std::vector<std::string> args = absl::StrSplit(versus, ' ', absl::SkipEmpty());
    SettingMask other_named = named;  // as on the command line: a row set once stays set
    for (size_t i = 0; i < args.size(); ++i) {
      const std::string& arg = args[i];
      auto value = [&]() -> std::string {
        if (i + 1 >= args.size()) Fail("--versus: " + arg + " needs a value");
        return args[++i];
      };
      if (arg == "--disable-features") {
        other_disabled = absl::StrSplit(value(), ',', absl::SkipEmpty());
        continue;
      }
      if (arg == "--copy-pixels") {
        other_copy_pixels = true;
        continue;
      }
      absl::StatusOr<bool> setting = ParseSettingFlag(arg, value, &other, &other_named);
      if (!setting.ok()) Fail("--versus: " + std::string(setting.status().message()));
      if (!*setting)
        Fail("--versus: " + arg +
             " is neither a settings flag nor --disable-features or --copy-pixels");
    }
    if (other.width != base.width || other.height != base.height)
      Fail("--versus: the frame sizes come from --sizes, for both sides");
  }

  // Frames lend their pixels to the encoder, as the server's do (RendererOptions::lent_buffers:
  // the frame a side keeps as `last` until the next is encoded, and the one rendering).
  constexpr uint32_t kLentBuffers = 2;
  absl::StatusOr<std::unique_ptr<Renderer>> renderer =
      Renderer::Create({.device_name = device, .lent_buffers = copy_pixels ? 0u : kLentBuffers});
  if (!renderer.ok()) Fail(std::string(renderer.status().message()));
  const auto t0 = std::chrono::steady_clock::now();
  const SceneHandle scene = bench::LoadSceneOrDemo(**renderer, scene_path);
  const double load_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  const SceneInfo& info = scene->info();
  // The sides: this one, and --versus's on a renderer and scene of its own (without the features
  // it names): nothing one side keeps between frames (the animation's pose, the shadow atlas,
  // histories) is reused or invalidated by the other.
  Side a, b;
  a.renderer = renderer->get();
  a.scene = scene;
  a.settings = base;
  a.view = 1;
  a.start_time = base.scene_time;
  std::unique_ptr<Renderer> other_renderer;
  if (!versus.empty()) {
    absl::StatusOr<std::unique_ptr<Renderer>> r2 =
        Renderer::Create({.device_name = device,
                          .disable_features = other_disabled,
                          .lent_buffers = other_copy_pixels ? 0u : kLentBuffers});
    if (!r2.ok()) Fail("--versus: " + std::string(r2.status().message()));
    other_renderer = std::move(*r2);
    b.renderer = other_renderer.get();
    b.scene = bench::LoadSceneOrDemo(*other_renderer, scene_path);
    b.settings = other;
    b.view = 2;
    b.start_time = other.scene_time;
  }

  nlohmann::json out;
  const DeviceInfo& dev = (*renderer)->device_info();
  out["device"] = {{"name", dev.name},
                   {"type", dev.type},
                   {"driver", dev.driver_info},
                   {"appends", dev.subgroup_appends ? "subgroup" : "pixel"},
                   // the visibility pass's (DeviceInfo::vertex_pulling)
                   {"vertices", dev.vertex_pulling ? "pulled" : "indexed"},
                   // who applies the specialization constants (DeviceInfo::host_specialization)
                   {"specialization", dev.host_specialization ? "host" : "driver"},
                   // the visibility shading's dispatches (DeviceInfo::shade_all_materials)
                   {"shading", dev.shade_all_materials ? "all_materials" : "per_material"}};
  out["scene"] = {{"name", info.name},
                  {"triangles", info.counts.triangles},
                  {"primitives", info.counts.primitives},
                  {"load_ms", load_ms},
                  {"device_mib", double(info.device_bytes) / (1 << 20)}};
  out["frames"] = frames;
  out["warmup"] = warmup;
  for (const auto& [w, h] : sizes) {
    const float aspect = float(w) / float(h);
    Camera camera = !info.cameras.empty() ? FromSceneCamera(info.cameras[0])
                                          : FrameBounds(info.bounds, 0.8f, aspect);
    if (eye && target) {
      camera = Camera{};
      camera.eye = *eye;
      camera.target = *target;
      camera.znear = 0.05f;
    }
    std::vector<Side*> sides = {&a};
    if (!versus.empty()) sides.push_back(&b);
    for (Side* side : sides) {
      side->Reset();
      side->settings.width = w;
      side->settings.height = h;
    }
    for (uint32_t f = 0; f < warmup + frames; ++f) {
      // --versus: the two sides take turns going first, so neither always follows the other.
      for (size_t k = 0; k < sides.size(); ++k) {
        Side& side = *sides[(k + f) % sides.size()];
        if (play_fps > 0.0)
          side.settings.scene_time = static_cast<float>(side.start_time + f / play_fps);
        side.RenderFrame(camera, f >= warmup);
      }
    }
    nlohmann::json r = a.Result(w, h);
    if (!versus.empty()) {
      nlohmann::json v;
      v["flags"] = versus;
      v["result"] = b.Result(w, h);
      // Per frame pair, the other side's time over this side's (< 1: the other is faster).
      v["ratio_total"] = PairRatios(a.total, b.total);
      nlohmann::json passes = nlohmann::json::object();
      for (const std::string& name : a.order) {
        std::vector<double> pa, pb;
        for (size_t i = 0; i < std::min(a.frame_passes.size(), b.frame_passes.size()); ++i) {
          const auto ia = a.frame_passes[i].find(name), ib = b.frame_passes[i].find(name);
          if (ia == a.frame_passes[i].end() || ib == b.frame_passes[i].end()) continue;
          pa.push_back(ia->second);
          pb.push_back(ib->second);
        }
        if (!pa.empty()) passes[name] = PairRatios(pa, pb);
      }
      v["ratio_passes"] = passes;
      r["versus"] = v;
    }
    out["results"].push_back(r);
  }
  std::printf("%s\n", out.dump(2).c_str());
  // With TESSERA_VALIDATION=1 (as in the smoke test) any validation message is a failure.
  int rc = 0;
  for (Renderer* r : {renderer->get(), other_renderer.get()}) {
    if (r == nullptr || r->validation_message_count() == 0) continue;
    for (const std::string& m : r->validation_messages())
      std::fprintf(stderr, "validation: %s\n", m.c_str());
    rc = 1;
  }
  return rc;
}
