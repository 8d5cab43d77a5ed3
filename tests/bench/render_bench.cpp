// tessera-bench: renders a scene N times per frame size after a warm-up and prints JSON with
// the median GPU time of every pass and of the total, their spread over the timed frames (min
// and max), and the CPU stages. A program, not a timed test: compare figures as ratios within
// one run (the machines are noisy), and read the spread before reading a difference.
//
//   tessera-bench --scene ../shared/assets/Sponza/glTF/Sponza.gltf
//       --sizes 1280x720,1920x1080 --frames 20 --warmup 3 [--pipeline visibility --aa taa ...]
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
           "--play FPS --device NAME, and the settings flags of tessera-render)");
    }
  }

  absl::StatusOr<std::unique_ptr<Renderer>> renderer = Renderer::Create({device, false});
  if (!renderer.ok()) Fail(std::string(renderer.status().message()));
  const auto t0 = std::chrono::steady_clock::now();
  const SceneHandle scene = bench::LoadSceneOrDemo(**renderer, scene_path);
  const double load_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  const SceneInfo& info = scene->info();

  nlohmann::json out;
  const DeviceInfo& dev = (*renderer)->device_info();
  out["device"] = {{"name", dev.name}, {"type", dev.type}, {"driver", dev.driver_info}};
  out["scene"] = {{"name", info.name},
                  {"triangles", info.counts.triangles},
                  {"primitives", info.counts.primitives},
                  {"load_ms", load_ms},
                  {"device_mib", double(info.device_bytes) / (1 << 20)}};
  out["frames"] = frames;
  out["warmup"] = warmup;
  for (const auto& [w, h] : sizes) {
    Settings s = base;
    s.width = w;
    s.height = h;
    const float aspect = float(w) / float(h);
    Camera camera = !info.cameras.empty() ? FromSceneCamera(info.cameras[0])
                                          : FrameBounds(info.bounds, 0.8f, aspect);
    if (eye && target) {
      camera = Camera{};
      camera.eye = *eye;
      camera.target = *target;
      camera.znear = 0.05f;
    }
    std::map<std::string, std::vector<double>> pass_ms, pass_stamp_ms;
    std::vector<std::string> order;
    std::vector<double> total, record, submit_wait, readback, encode, encode_one, ratio;
    Frame last;
    std::vector<double> skinning_share;
    for (uint32_t f = 0; f < warmup + frames; ++f) {
      if (play_fps > 0.0) s.scene_time = static_cast<float>(base.scene_time + f / play_fps);
      absl::StatusOr<Frame> frame = (*renderer)->Render(*scene, camera, s);
      if (!frame.ok()) Fail(std::string(frame.status().message()));
      if (absl::StatusOr<std::vector<uint8_t>> jpg = EncodeFrame(*frame, ImageFormat::kJpeg);
          !jpg.ok()) {
        Fail(std::string(jpg.status().message()));
      }
      // The same encode in one strip, for the ratio (EncodeFrame uses AutoJpegStrips).
      const auto t_one = std::chrono::steady_clock::now();
      if (!EncodeJpeg(frame->image, int(s.jpeg_quality), ChromaSubsampling::k420, 1).ok())
        Fail("EncodeJpeg");
      const double one_ms = std::chrono::duration<double, std::milli>(
                                std::chrono::steady_clock::now() - t_one)
                                .count();
      if (f < warmup) continue;
      for (const PassTiming& p : frame->passes) {
        if (!pass_ms.count(p.pass)) order.push_back(p.pass);
        pass_ms[p.pass].push_back(p.gpu_ms);
        pass_stamp_ms[p.pass].push_back(p.timestamp_ms);
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
      (*renderer)->RecyclePixels(std::move(last.image.pixels));  // as the server gives them back
      last = std::move(*frame);
    }
    nlohmann::json r;
    r["width"] = w;
    r["height"] = h;
    nlohmann::json passes = nlohmann::json::array();
    for (const std::string& name : order)
      passes.push_back({{"pass", name},
                        {"gpu_ms_median", Median(pass_ms[name])},
                        {"gpu_ms_min", Min(pass_ms[name])},
                        {"gpu_ms_max", Max(pass_ms[name])},
                        {"timestamp_ms_median", Median(pass_stamp_ms[name])}});
    r["passes"] = passes;
    r["gpu_total_ms_median"] = Median(total);
    r["gpu_total_ms_min"] = Min(total);
    r["gpu_total_ms_max"] = Max(total);
    r["cpu_ms_median"] = {{"record", Median(record)},
                          {"submit_wait", Median(submit_wait)},
                          {"readback", Median(readback)},
                          {"encode_jpeg", Median(encode)},
                          {"encode_jpeg_one_strip", Median(encode_one)}};
    r["jpeg_strips"] = AutoJpegStrips(last.image);
    // Frame-total timestamps against the wall clock from submit to fence.
    r["timestamp_total_over_wall"] = Median(ratio);
    r["timing"] =
        last.timing == TimingSource::kPassWallClock ? "pass_wall_clock" : "gpu_timestamps";
    const double pixels = double(w) * h;
    r["pipeline"] = ToString(last.settings.effective.pipeline);
    r["aa"] = ToString(last.settings.effective.aa);
    r["stats"] = {{"draws", last.stats.draws},
                  {"triangles_submitted", last.stats.triangles_submitted},
                  {"drawables_culled", last.stats.drawables_culled},
                  {"fragment_invocations_per_pixel", double(last.stats.fragment_invocations) / pixels},
                  {"shaded_pixels", last.stats.shaded_pixels},
                  {"shading_invocations_per_pixel", double(last.stats.shading_invocations) / pixels},
                  {"edge_pixels", last.stats.edge_pixels},
                  {"runner_up_pixels", last.stats.runner_up_pixels},
                  {"animated_drawables", last.stats.animated_drawables},
                  {"deformed_vertices", last.stats.deformed_vertices}};
    if (!skinning_share.empty()) {
      r["skinning_share_median"] = Median(skinning_share);
      r["skinning_share_min"] = Min(skinning_share);
      r["skinning_share_max"] = Max(skinning_share);
    }
    out["results"].push_back(r);
  }
  std::printf("%s\n", out.dump(2).c_str());
  // With TESSERA_VALIDATION=1 (as in the smoke test) any validation message is a failure.
  if ((*renderer)->validation_message_count() > 0) {
    for (const std::string& m : (*renderer)->validation_messages())
      std::fprintf(stderr, "validation: %s\n", m.c_str());
    return 1;
  }
  return 0;
}
