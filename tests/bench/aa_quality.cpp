// tessera-aa-quality: image quality and cost of every anti-aliasing mode, as JSON on stdout.
//
// Each scene is rendered once without AA at 4x width and 4x height and box-filtered down
// (DownsampleBox: 16 samples per pixel, linear light): the reference. Then every mode renders
// the same scene, camera and settings in its own fresh view (so TAA starts without history and
// converges over the frames) and is scored against it (renderer/image_metrics.h):
//   psnr_all, ssim_all        the whole frame against the reference;
//   psnr_edges, ssim_edges    over the edge mask: pixels where the reference and the no-AA frame
//                             differ by more than 2/255 in some channel (what needs AA);
//   psnr_nonedge_vs_none      against the no-AA frame over the other pixels (how much a mode
//                             blurs what needed no AA; the none mode itself scores "identical");
//   coverage (edges scene)    per-pixel coverage MAE against the analytic coverage (edge pixels
//                             and all pixels), with the reference's own as a sanity line.
// Cost: median Frame::gpu_total_ms and median wall time of the Render call over the timed
// frames, and the median of every pass. Quality is taken from the last frame of each mode.
// Compare figures as ratios within one run (the machines are noisy).
//
// Scenes (--scenes):
//   sponza  <assets>/Sponza/glTF/Sponza.gltf at --width x --height. The file's first camera if it
//           has one; the Khronos file has none, so a fixed view from the east end of the atrium
//           at eye height looking west down its length and slightly up (kSponzaEye/Target): both
//           arcades' columns and arches, the upper gallery's balustrades and the roof line, at
//           every angle and distance.
//   helmet  <assets>/DamagedHelmet/glTF-Binary/DamagedHelmet.glb, framed with FrameBounds.
//   edges   BuildEdgeScene(): half-planes at 0..90 degrees and thin wires, white on black, with
//           the debug view base_color at the scene's own size (--width/--height do not apply).
// Assets come from $TESSERA_ASSETS_DIR, else the build's default; --sponza/--helmet override.
//
// Targets, reported per scene under "targets" and not enforced: vis_mlaa's edge PSNR within
// 1 dB of msaa's at the same sample count while costing less GPU time than msaa, and >= 3 dB
// better than fxaa's on edges.
//
// Numbers in the JSON: a PSNR of identical pixels (+infinity) is written as 999 (kInfDb); a
// metric over an empty selection (e.g. no edge pixels) is null. Everything else is finite.
//
//   tessera-aa-quality [--scenes sponza,helmet,edges] [--modes none,msaa,fxaa,taa,vis_mlaa]
//       [--samples 4] [--vis-mlaa-coverage auto] [--no-pass-timing] [--width 1280] [--height 720]
//       [--frames 5]
//       [--warmup 1] [--taa-frames 16] [--edge-cell 24] [--sponza FILE] [--helmet FILE] [--out DIR]
//       [--device NAME] [--smoke]
//
// With --out DIR: per scene <scene>_reference.png, <scene>_edge_mask.png, <scene>_<mode>.png
// and <scene>_contact.png (4x zoomed crops of the busiest edge windows, one column per image).
// Exit status: 0; 2 on bad flags (with the usage); 1 on a missing asset, a failed render, a
// validation message (TESSERA_VALIDATION=1) or a non-finite number where one was measured.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <glm/glm.hpp>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"
#include "bench_util.h"
#include "renderer/camera.h"
#include "renderer/image_io.h"
#include "renderer/image_metrics.h"
#include "renderer/renderer.h"
#include "renderer/scene/edge_scene.h"
#include "renderer/scene/gltf_import.h"
#include "renderer/settings_table.h"

#ifndef TESSERA_DEFAULT_ASSETS_DIR
#define TESSERA_DEFAULT_ASSETS_DIR "../shared/assets"
#endif

namespace tessera {
namespace {

using bench::Median;
using Json = nlohmann::ordered_json;  // keeps keys in the order written

constexpr double kInfDb = 999.0;      // JSON has no infinity: the PSNR of identical pixels
constexpr uint32_t kRefFactor = 4;    // the reference renders at 4x width and 4x height
constexpr int kEdgeThreshold = 2;     // 8-bit steps: the edge mask's DifferenceMask threshold
constexpr uint32_t kMaxSide = 16384;  // Settings' range, which the reference must stay within
constexpr uint32_t kCropSize = 48, kCrops = 4, kZoom = 4;  // the contact sheet
// The fixed Sponza view (the file has no camera): east end of the atrium, eye height, looking
// west down its length, a little towards +z and up, so the colonnades on both sides recede at
// many angles. Sponza spans about x -15..14, y -1..11, z -9.5..9 (metres after its 0.008 scale).
constexpr glm::vec3 kSponzaEye(9.0f, 1.6f, -1.0f), kSponzaTarget(-5.0f, 3.5f, 1.5f);
constexpr float kSponzaYfov = 1.0f, kSponzaZnear = 0.1f;

constexpr char kUsage[] =
    "usage: tessera-aa-quality [--scenes sponza,helmet,edges] [--modes "
    "none,msaa,fxaa,taa,vis_mlaa]\n"
    "    [--samples 1|2|4|8] [--vis-mlaa-coverage auto|raster|analytic] [--no-pass-timing]\n"
    "    [--width N] [--height N] [--frames N] [--warmup N] [--taa-frames N]\n"
    "    [--edge-cell N] [--sponza FILE] [--helmet FILE] [--out DIR] [--device NAME] [--smoke]\n"
    "  defaults: all scenes and modes, samples 4, 1280x720 (sponza, helmet; edges renders at its\n"
    "  own size), 1 warm-up + 5 timed frames per mode (taa: at least --taa-frames, 16), edge cell\n"
    "  24 px. --smoke: edges (cell 8, gap 2) and helmet at 64x48, 1 frame (taa 2), no warm-up.\n";

// Bad arguments: the message and the usage, exit status 2.
[[noreturn]] void BadFlag(const std::string& msg) {
  std::fprintf(stderr, "%s: %s\n%s", program_invocation_short_name, msg.c_str(), kUsage);
  std::exit(2);
}

// A failed run (missing asset, render error...): one line, exit status 1.
[[noreturn]] void Die(const std::string& msg) {
  std::fprintf(stderr, "%s: %s\n", program_invocation_short_name, msg.c_str());
  std::exit(1);
}

struct Options {
  std::vector<std::string> scenes = {"sponza", "helmet", "edges"};
  std::vector<AaMode> modes = {AaMode::kNone, AaMode::kMsaa, AaMode::kFxaa, AaMode::kTaa,
                               AaMode::kVisMlaa};
  uint32_t samples = 4, width = 1280, height = 720, frames = 5, warmup = 1, taa_frames = 16;
  EdgeSceneParams edge;
  std::string sponza_path, helmet_path, out_dir, device;
  bool smoke = false;
  VisMlaaCoverage coverage = VisMlaaCoverage::kAuto;
  bool pass_timing = true;  // --no-pass-timing: frames in one submission (Settings::pass_timing)
};

uint32_t ParseUint(const std::string& flag, const std::string& s) {
  uint32_t v = 0;
  if (!absl::SimpleAtoi(s, &v)) BadFlag(flag + ": not a number: " + s);
  return v;
}

Options ParseOptions(int argc, char** argv) {
  Options o;
  // --smoke sets small defaults first, so later flags can still change them.
  for (int i = 1; i < argc; ++i) {
    if (std::string(argv[i]) != "--smoke") continue;
    o.smoke = true;
    o.scenes = {"edges", "helmet"};
    o.modes = {AaMode::kNone, AaMode::kMsaa, AaMode::kFxaa, AaMode::kVisMlaa, AaMode::kTaa};
    o.width = 64;
    o.height = 48;
    o.frames = 1;
    o.warmup = 0;
    o.taa_frames = 2;
    o.edge = EdgeSceneParams{8, 2};
  }
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) BadFlag(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--smoke") {
      continue;
    } else if (arg == "--help" || arg == "-h") {
      std::fputs(kUsage, stdout);
      std::exit(0);
    } else if (arg == "--scenes") {
      o.scenes.clear();
      for (const std::string& s : std::vector<std::string>(absl::StrSplit(value(), ','))) {
        if (s != "sponza" && s != "helmet" && s != "edges")
          BadFlag("--scenes: want sponza, helmet and/or edges, got '" + s + "'");
        if (std::find(o.scenes.begin(), o.scenes.end(), s) == o.scenes.end()) o.scenes.push_back(s);
      }
    } else if (arg == "--modes") {
      o.modes.clear();
      for (const std::string& m : std::vector<std::string>(absl::StrSplit(value(), ','))) {
        absl::StatusOr<AaMode> aa = ParseAaMode(m);
        if (!aa.ok()) BadFlag("--modes: " + std::string(aa.status().message()));
        if (std::find(o.modes.begin(), o.modes.end(), *aa) == o.modes.end()) o.modes.push_back(*aa);
      }
    } else if (arg == "--samples") {
      o.samples = ParseUint(arg, value());
      if (o.samples != 1 && o.samples != 2 && o.samples != 4 && o.samples != 8)
        BadFlag("--samples: want 1, 2, 4 or 8");
    } else if (arg == "--vis-mlaa-coverage") {
      // The settings table's parser (renderer/settings_table.h), as tessera-bench's flags.
      Settings parsed;
      SettingMask set;
      const absl::StatusOr<bool> ok = ParseSettingFlag(arg, value, &parsed, &set);
      if (!ok.ok()) BadFlag(std::string(ok.status().message()));
      o.coverage = parsed.vis_mlaa_coverage;
    } else if (arg == "--no-pass-timing") {
      o.pass_timing = false;
    } else if (arg == "--width") {
      o.width = ParseUint(arg, value());
    } else if (arg == "--height") {
      o.height = ParseUint(arg, value());
    } else if (arg == "--frames") {
      o.frames = ParseUint(arg, value());
      if (o.frames == 0) BadFlag("--frames: want at least 1");
    } else if (arg == "--warmup") {
      o.warmup = ParseUint(arg, value());
    } else if (arg == "--taa-frames") {
      o.taa_frames = ParseUint(arg, value());
    } else if (arg == "--edge-cell") {
      o.edge.cell = ParseUint(arg, value());
      if (o.edge.cell < 8 || o.edge.cell > 256) BadFlag("--edge-cell: want 8..256 pixels");
    } else if (arg == "--sponza") {
      o.sponza_path = value();
    } else if (arg == "--helmet") {
      o.helmet_path = value();
    } else if (arg == "--out") {
      o.out_dir = value();
    } else if (arg == "--device") {
      o.device = value();
    } else {
      BadFlag("unknown option " + arg);
    }
  }
  if (o.scenes.empty()) BadFlag("--scenes: no scene");
  if (o.modes.empty()) BadFlag("--modes: no mode");
  // The reference renders at 4x: keep it inside Settings' 1..16384.
  for (const auto& [flag, v] : {std::pair{"--width", o.width}, std::pair{"--height", o.height}})
    if (v == 0 || v * kRefFactor > kMaxSide)
      BadFlag(std::string(flag) + ": want 1.." + std::to_string(kMaxSide / kRefFactor) +
              " (the reference renders at 4x)");
  return o;
}

std::string AssetPath(const std::string& override_path, const std::string& relative) {
  if (!override_path.empty()) return override_path;
  const char* env = std::getenv("TESSERA_ASSETS_DIR");
  return std::string(env && *env ? env : TESSERA_DEFAULT_ASSETS_DIR) + "/" + relative;
}

// One scene on the device with the camera, size and debug view every mode renders it with.
struct QualityScene {
  std::string name, file;
  SceneHandle handle;
  Camera camera;
  std::string camera_source;  // "scene camera 0", "fixed", "frame_bounds", "edge_scene"
  uint32_t width = 0, height = 0;
  DebugView debug_view = DebugView::kNone;
  std::vector<float> coverage;  // edges only: the analytic coverage, width x height
};

// Collects what should have been a finite number but is not; the run fails on any.
struct Problems {
  std::vector<std::string> list;

  // A PSNR: +inf (identical) -> kInfDb, nothing selected -> null.
  Json Db(double v, uint64_t selected, const std::string& what) {
    if (selected == 0) return Json();
    if (std::isinf(v) && v > 0) return kInfDb;
    return Finite(v, what);
  }
  // SSIM, MAE, ms: finite, or null when nothing was selected.
  Json Value(double v, uint64_t selected, const std::string& what) {
    return selected == 0 ? Json() : Finite(v, what);
  }
  Json Finite(double v, const std::string& what) {
    if (std::isfinite(v)) return v;
    list.push_back(what + " is " + std::to_string(v));
    return Json();
  }
};

// "inf", "-" (not measured) or the value, for the table.
std::string Fmt(double v, int precision) {
  if (std::isnan(v)) return "-";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.*f", precision, v);
  return buf;
}

// Timings of the frames of one render series.
struct Timings {
  std::vector<double> gpu_ms, wall_ms;
  std::vector<std::string> pass_order;
  std::map<std::string, std::vector<double>> pass_ms;
  TimingSource source = TimingSource::kGpuTimestamps;

  void Add(const Frame& f, double wall) {
    gpu_ms.push_back(f.gpu_total_ms);
    wall_ms.push_back(wall);
    source = f.timing;
    for (const PassTiming& p : f.passes) {
      if (!pass_ms.count(p.pass)) pass_order.push_back(p.pass);
      pass_ms[p.pass].push_back(p.gpu_ms);
    }
  }
  void ToJson(Json& out, Problems& problems, const std::string& what) const {
    out["gpu_ms_median"] = problems.Finite(Median(gpu_ms), what + " gpu_ms_median");
    out["wall_ms_median"] = problems.Finite(Median(wall_ms), what + " wall_ms_median");
    Json passes = Json::object();
    for (const std::string& p : pass_order)
      passes[p] = problems.Finite(Median(pass_ms.at(p)), what + " pass " + p);
    out["pass_ms_median"] = passes;
  }
};

// Renders one frame and checks it came out at the size asked for.
Frame RenderOne(Renderer& r, const QualityScene& sc, const Settings& s, uint64_t view,
                const std::string& what, double* wall_ms) {
  const auto t0 = std::chrono::steady_clock::now();
  absl::StatusOr<Frame> frame = r.Render(*sc.handle, sc.camera, s, view);
  *wall_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (!frame.ok()) Die(sc.name + " " + what + ": " + std::string(frame.status().message()));
  if (frame->image.width != s.width || frame->image.height != s.height) {
    std::string notes;
    for (const SettingNote& n : frame->settings.notes) notes += "; " + n.field + ": " + n.message;
    Die(sc.name + " " + what + ": rendered " + std::to_string(frame->image.width) + "x" +
        std::to_string(frame->image.height) + ", asked for " + std::to_string(s.width) + "x" +
        std::to_string(s.height) + notes);
  }
  return std::move(*frame);
}

// One AA mode over its frames.
struct ModeRun {
  AaMode aa = AaMode::kNone;
  uint32_t frames = 0;  // timed
  Frame last;           // the measured image and its effective settings
  Timings timings;
};

ModeRun RunMode(Renderer& r, const QualityScene& sc, const Settings& base, AaMode aa, uint64_t view,
                const Options& o) {
  ModeRun run;
  run.aa = aa;
  Settings s = base;
  s.aa = aa;
  // TAA converges over its 16-frame jitter sequence: measure it only once it has history.
  run.frames = aa == AaMode::kTaa ? std::max(o.frames, o.taa_frames) : o.frames;
  const std::string what(ToString(aa));
  for (uint32_t i = 0; i < o.warmup + run.frames; ++i) {
    double wall = 0.0;
    Frame f = RenderOne(r, sc, s, view, what, &wall);
    if (i >= o.warmup) run.timings.Add(f, wall);
    run.last = std::move(f);
  }
  return run;
}

// The scores of one image (see the header).
struct Quality {
  double psnr_all = 0, ssim_all = 0, psnr_edges = 0, ssim_edges = 0, psnr_nonedge_vs_none = 0;
  std::optional<CoverageError> coverage;  // edges scene only
};

double Must(absl::StatusOr<double> v, const std::string& what) {
  if (!v.ok()) Die(what + ": " + std::string(v.status().message()));
  return *v;
}

std::optional<CoverageError> Coverage(const RgbaImage& img, const QualityScene& sc,
                                      const std::string& what) {
  if (sc.coverage.empty()) return std::nullopt;
  absl::StatusOr<CoverageError> c = MeasureCoverage(img, sc.coverage);
  if (!c.ok()) Die(what + ": " + std::string(c.status().message()));
  return *c;
}

Quality Measure(const RgbaImage& img, const RgbaImage& ref, const RgbaImage& none,
                const std::vector<uint8_t>& edges, const std::vector<uint8_t>& nonedges,
                const QualityScene& sc, const std::string& what) {
  Quality q;
  q.psnr_all = Must(PsnrMasked(img, ref), what + " psnr_all");
  q.ssim_all = Must(SsimMasked(img, ref), what + " ssim_all");
  q.psnr_edges = Must(PsnrMasked(img, ref, edges), what + " psnr_edges");
  q.ssim_edges = Must(SsimMasked(img, ref, edges), what + " ssim_edges");
  q.psnr_nonedge_vs_none = Must(PsnrMasked(img, none, nonedges), what + " psnr_nonedge_vs_none");
  q.coverage = Coverage(img, sc, what);
  return q;
}

Json CoverageJson(const CoverageError& c, Problems& problems, const std::string& what) {
  return {{"edge_mae", problems.Value(c.edge_mae, c.edge_pixels, what + " edge_mae")},
          {"all_mae", problems.Finite(c.all_mae, what + " all_mae")},
          {"edge_pixels", c.edge_pixels}};
}

Json NotesJson(const std::vector<SettingNote>& notes) {
  Json out = Json::array();
  for (const SettingNote& n : notes) out.push_back({{"field", n.field}, {"message", n.message}});
  return out;
}

// Writes a PNG under --out, prints the path on stderr and returns it.
std::string WritePng(const Options& o, const std::string& name, const RgbaImage& img) {
  const std::string path = (std::filesystem::path(o.out_dir) / (name + ".png")).string();
  absl::StatusOr<std::vector<uint8_t>> png = EncodePng(img);
  if (!png.ok()) Die(path + ": " + std::string(png.status().message()));
  if (absl::Status st = WriteFileBytes(path, *png); !st.ok()) Die(std::string(st.message()));
  std::fprintf(stderr, "wrote %s\n", path.c_str());
  return path;
}

RgbaImage MaskImage(const std::vector<uint8_t>& mask, uint32_t width, uint32_t height) {
  RgbaImage img{width, height, std::vector<uint8_t>(size_t{width} * height * 4, 255)};
  for (size_t i = 0; i < mask.size(); ++i)
    img.pixels[i * 4] = img.pixels[i * 4 + 1] = img.pixels[i * 4 + 2] = mask[i] ? 255 : 0;
  return img;
}

// A target: its value (null when not measured or not comparable) and whether it is met.
Json Target(double value, bool comparable, const char* text, bool met) {
  const bool ok = comparable && std::isfinite(value);
  return {{"value", ok ? Json(value) : Json()}, {"target", text}, {"met", ok ? Json(met) : Json()}};
}

// The targets for vis_mlaa against msaa (same sample count) and fxaa.
Json Targets(const std::vector<ModeRun>& runs, const std::vector<Quality>& q) {
  auto find = [&](AaMode m) -> int {
    for (size_t i = 0; i < runs.size(); ++i)
      if (runs[i].aa == m) return int(i);
    return -1;
  };
  const int vis = find(AaMode::kVisMlaa), msaa = find(AaMode::kMsaa), fxaa = find(AaMode::kFxaa);
  Json out = Json::object();
  if (vis < 0) return out;
  const Settings& ve = runs[vis].last.settings.effective;
  const bool vis_ran = ve.aa == AaMode::kVisMlaa;  // not fallen back to msaa or none
  if (msaa >= 0) {
    const Settings& me = runs[msaa].last.settings.effective;
    // Comparable only when both ran as themselves with the same number of samples.
    const bool same = vis_ran && me.aa == AaMode::kMsaa && me.samples == ve.samples;
    const double d = q[vis].psnr_edges - q[msaa].psnr_edges;
    const double ratio = Median(runs[vis].timings.gpu_ms) / Median(runs[msaa].timings.gpu_ms);
    out["samples"] = {{"vis_mlaa", ve.samples}, {"msaa", me.samples}};
    out["comparable_with_msaa"] = same;
    out["vis_mlaa_edge_psnr_minus_msaa_db"] =
        Target(d, same, ">= -1 (within 1 dB of msaa)", d >= -1.0);
    out["vis_mlaa_gpu_ms_over_msaa"] = Target(ratio, same, "< 1 (cheaper than msaa)", ratio < 1.0);
  }
  if (fxaa >= 0) {
    const bool ran = vis_ran && runs[fxaa].last.settings.effective.aa == AaMode::kFxaa;
    const double d = q[vis].psnr_edges - q[fxaa].psnr_edges;
    out["vis_mlaa_edge_psnr_minus_fxaa_db"] = Target(d, ran, ">= 3", d >= 3.0);
  }
  return out;
}

std::string Label(const ModeRun& run) {
  const Settings& e = run.last.settings.effective;
  std::string label(ToString(run.aa));
  if (e.aa == AaMode::kMsaa || e.aa == AaMode::kVisMlaa)
    label += " " + std::to_string(e.samples) + "x";
  return label;
}

Json RunScene(Renderer& r, const QualityScene& sc, const Options& o, uint64_t& next_view,
              Problems& problems) {
  Settings base;
  base.width = sc.width;
  base.height = sc.height;
  base.samples = o.samples;
  base.vis_mlaa_coverage = o.coverage;
  base.pass_timing = o.pass_timing;
  base.debug_view = sc.debug_view;

  Json out;
  out["name"] = sc.name;
  if (!sc.file.empty()) out["file"] = sc.file;
  out["width"] = sc.width;
  out["height"] = sc.height;
  out["debug_view"] = std::string(ToString(sc.debug_view));
  out["triangles"] = sc.handle->info().counts.triangles;
  const glm::vec3 eye = CameraPosition(sc.camera);
  Json cam = {{"source", sc.camera_source},
              {"eye", {eye.x, eye.y, eye.z}},
              {"yfov", sc.camera.yfov},
              {"znear", sc.camera.znear}};
  if (!sc.camera.view) cam["target"] = {sc.camera.target.x, sc.camera.target.y, sc.camera.target.z};
  out["camera"] = cam;

  // The reference: one frame without AA at 4x, box-filtered down.
  Settings ref_settings = base;
  ref_settings.aa = AaMode::kNone;
  ref_settings.width = sc.width * kRefFactor;
  ref_settings.height = sc.height * kRefFactor;
  double ref_wall = 0.0;
  const Frame ref_frame = RenderOne(r, sc, ref_settings, next_view++, "reference", &ref_wall);
  absl::StatusOr<RgbaImage> ref = DownsampleBox(ref_frame.image, kRefFactor);
  if (!ref.ok()) Die(sc.name + " reference: " + std::string(ref.status().message()));

  std::vector<ModeRun> runs;
  for (AaMode m : o.modes) runs.push_back(RunMode(r, sc, base, m, next_view++, o));
  out["timing"] = ToString(runs.front().timings.source);

  // The no-AA frame: the none mode's, else one of its own.
  const RgbaImage* none = nullptr;
  Frame none_frame;
  for (const ModeRun& run : runs)
    if (run.aa == AaMode::kNone) none = &run.last.image;
  if (!none) {
    Settings s = base;
    s.aa = AaMode::kNone;
    double wall = 0.0;
    none_frame = RenderOne(r, sc, s, next_view++, "none (for the edge mask)", &wall);
    none = &none_frame.image;
  }
  absl::StatusOr<std::vector<uint8_t>> edges = DifferenceMask(*ref, *none, kEdgeThreshold);
  if (!edges.ok()) Die(sc.name + " edge mask: " + std::string(edges.status().message()));
  const std::vector<uint8_t> nonedges = InvertMask(*edges);
  const uint64_t edge_count = MaskCount(*edges), nonedge_count = MaskCount(nonedges);

  Json ref_json = {{"width", ref_settings.width},
                   {"height", ref_settings.height},
                   {"factor", kRefFactor},
                   {"gpu_ms", problems.Finite(ref_frame.gpu_total_ms, sc.name + " reference ms")},
                   {"wall_ms", problems.Finite(ref_wall, sc.name + " reference wall ms")},
                   {"notes", NotesJson(ref_frame.settings.notes)}};
  const std::optional<CoverageError> ref_cov = Coverage(*ref, sc, sc.name + " reference");
  if (ref_cov) ref_json["coverage"] = CoverageJson(*ref_cov, problems, sc.name + " reference");
  out["reference"] = ref_json;
  out["edge_pixels"] = edge_count;
  out["nonedge_pixels"] = nonedge_count;
  out["edge_fraction"] = double(edge_count) / double(uint64_t{sc.width} * sc.height);

  std::vector<Quality> quality;
  Json modes = Json::object();
  for (const ModeRun& run : runs) {
    const std::string name(ToString(run.aa)), what = sc.name + " " + name;
    const Quality q = Measure(run.last.image, *ref, *none, *edges, nonedges, sc, what);
    quality.push_back(q);
    const Settings& e = run.last.settings.effective;
    Json m;
    m["aa"] = name;
    m["effective_aa"] = std::string(ToString(e.aa));
    m["samples"] = o.samples;
    m["effective_samples"] = e.samples;
    if (e.aa == AaMode::kVisMlaa) m["vis_mlaa_coverage"] = std::string(ToString(e.vis_mlaa_coverage));
    m["notes"] = NotesJson(run.last.settings.notes);
    m["frames"] = run.frames;
    m["warmup"] = o.warmup;
    run.timings.ToJson(m, problems, what);
    const uint64_t all = uint64_t{sc.width} * sc.height;
    m["psnr_all"] = problems.Db(q.psnr_all, all, what + " psnr_all");
    m["ssim_all"] = problems.Value(q.ssim_all, all, what + " ssim_all");
    m["psnr_edges"] = problems.Db(q.psnr_edges, edge_count, what + " psnr_edges");
    m["ssim_edges"] = problems.Value(q.ssim_edges, edge_count, what + " ssim_edges");
    m["psnr_nonedge_vs_none"] =
        problems.Db(q.psnr_nonedge_vs_none, nonedge_count, what + " psnr_nonedge_vs_none");
    if (q.coverage) m["coverage"] = CoverageJson(*q.coverage, problems, what);
    modes[name] = m;
  }
  out["modes"] = modes;
  out["targets"] = Targets(runs, quality);

  // The table.
  std::fprintf(
      stderr, "%s %ux%u (reference %ux%u: %.1f ms), %s, edge pixels %llu (%.2f%%), timing %s\n",
      sc.name.c_str(), sc.width, sc.height, ref_settings.width, ref_settings.height,
      ref_frame.gpu_total_ms, std::string(ToString(sc.debug_view)).c_str(),
      static_cast<unsigned long long>(edge_count), 100.0 * out["edge_fraction"].get<double>(),
      std::string(ToString(ref_frame.timing)).c_str());
  std::fprintf(stderr, "  %-16s %9s %9s %10s %10s %13s %10s\n", "mode", "gpu ms", "wall ms",
               "edge PSNR", "edge SSIM", "nonedge/none", "cov MAE");
  if (ref_cov)
    std::fprintf(stderr, "  %-16s %9s %9s %10s %10s %13s %10s\n", "reference (16x)", "-", "-", "-",
                 "-", "-", Fmt(ref_cov->edge_mae, 4).c_str());
  for (size_t i = 0; i < runs.size(); ++i) {
    const Quality& q = quality[i];
    std::string label = Label(runs[i]);
    if (runs[i].last.settings.effective.aa != runs[i].aa)
      label += " ->" + std::string(ToString(runs[i].last.settings.effective.aa));
    std::fprintf(stderr, "  %-16s %9.3f %9.3f %10s %10s %13s %10s\n", label.c_str(),
                 Median(runs[i].timings.gpu_ms), Median(runs[i].timings.wall_ms),
                 Fmt(q.psnr_edges, 2).c_str(), Fmt(q.ssim_edges, 4).c_str(),
                 Fmt(q.psnr_nonedge_vs_none, 2).c_str(),
                 q.coverage ? Fmt(q.coverage->edge_mae, 4).c_str() : "-");
  }

  if (!o.out_dir.empty()) {
    Json files;
    files["reference"] = WritePng(o, sc.name + "_reference", *ref);
    files["edge_mask"] =
        WritePng(o, sc.name + "_edge_mask", MaskImage(*edges, sc.width, sc.height));
    for (const ModeRun& run : runs) {
      const std::string name(ToString(run.aa));
      files[name] = WritePng(o, sc.name + "_" + name, run.last.image);
    }
    // Columns: reference, none, then the other modes in --modes order.
    std::vector<LabelledImage> columns = {{"reference", &*ref}, {"none", none}};
    for (const ModeRun& run : runs)
      if (run.aa != AaMode::kNone) columns.push_back({Label(run), &run.last.image});
    const std::vector<Crop> crops = BusiestCrops(*edges, sc.width, sc.height, kCropSize, kCrops);
    if (crops.empty()) {
      std::fprintf(stderr, "%s: no edge pixels, no contact sheet\n", sc.name.c_str());
    } else {
      absl::StatusOr<RgbaImage> sheet = ContactSheet(columns, crops, kZoom);
      if (!sheet.ok()) Die(sc.name + " contact sheet: " + std::string(sheet.status().message()));
      files["contact_sheet"] = WritePng(o, sc.name + "_contact", *sheet);
    }
    out["files"] = files;
  }
  return out;
}

// Loads a glTF file; a missing file is a clear error (exit 1), or a skip in smoke runs.
std::optional<QualityScene> LoadAsset(Renderer& r, const std::string& name, const std::string& path,
                                      const Options& o) {
  if (!std::filesystem::exists(path)) {
    if (o.smoke) {
      std::fprintf(stderr, "%s skipped: no %s\n", name.c_str(), path.c_str());
      return std::nullopt;
    }
    Die(name + ": no such file " + path + " (set TESSERA_ASSETS_DIR or pass --" + name + " FILE)");
  }
  absl::StatusOr<GltfSource> source = LoadGltfSourceFromDisk(path);
  if (!source.ok()) Die(name + ": " + std::string(source.status().message()));
  absl::StatusOr<SceneHandle> handle = r.LoadScene(*source);
  if (!handle.ok()) Die(name + ": " + std::string(handle.status().message()));
  QualityScene sc;
  sc.name = name;
  sc.file = path;
  sc.handle = *handle;
  sc.width = o.width;
  sc.height = o.height;
  return sc;
}

std::optional<QualityScene> MakeScene(Renderer& r, const std::string& name, const Options& o) {
  if (name == "edges") {
    EdgeScene edge = BuildEdgeScene(o.edge);
    absl::StatusOr<SceneHandle> handle = r.LoadScene(edge.scene);
    if (!handle.ok()) Die("edges: " + std::string(handle.status().message()));
    QualityScene sc;
    sc.name = name;
    sc.handle = *handle;
    sc.camera.eye = edge.eye;
    sc.camera.target = edge.target;
    sc.camera.yfov = edge.yfov;
    sc.camera.znear = edge.znear;
    sc.camera_source = "edge_scene";
    sc.width = edge.width;
    sc.height = edge.height;
    // Unlit base colour, no tonemap: a pixel's linear value is its coverage.
    sc.debug_view = DebugView::kBaseColor;
    sc.coverage = std::move(edge.coverage);
    return sc;
  }
  const float aspect = float(o.width) / float(o.height);
  if (name == "sponza") {
    std::optional<QualityScene> sc =
        LoadAsset(r, name, AssetPath(o.sponza_path, "Sponza/glTF/Sponza.gltf"), o);
    if (!sc) return sc;
    if (!sc->handle->info().cameras.empty()) {
      sc->camera = FromSceneCamera(sc->handle->info().cameras[0]);
      sc->camera_source = "scene camera 0";
    } else {
      sc->camera.eye = kSponzaEye;
      sc->camera.target = kSponzaTarget;
      sc->camera.yfov = kSponzaYfov;
      sc->camera.znear = kSponzaZnear;
      sc->camera_source = "fixed";
    }
    return sc;
  }
  std::optional<QualityScene> sc = LoadAsset(
      r, name, AssetPath(o.helmet_path, "DamagedHelmet/glTF-Binary/DamagedHelmet.glb"), o);
  if (!sc) return sc;
  sc->camera = FrameBounds(sc->handle->info().bounds, 0.8f, aspect);
  sc->camera_source = "frame_bounds";
  return sc;
}

// Every number in `j` is finite (nlohmann keeps NaN and inf as numbers; dump() hides them).
void CheckFinite(const Json& j, const std::string& at, Problems& problems) {
  if (j.is_number_float() && !std::isfinite(j.get<double>()))
    problems.list.push_back(at + " is not finite");
  if (j.is_object())
    for (const auto& [k, v] : j.items()) CheckFinite(v, at + "/" + k, problems);
  if (j.is_array())
    for (size_t i = 0; i < j.size(); ++i) CheckFinite(j[i], at + "/" + std::to_string(i), problems);
}

}  // namespace
}  // namespace tessera

int main(int argc, char** argv) {
  using namespace tessera;
  const Options o = ParseOptions(argc, argv);
  if (!o.out_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(o.out_dir, ec);
    if (ec) Die("--out " + o.out_dir + ": " + ec.message());
  }
  absl::StatusOr<std::unique_ptr<Renderer>> renderer = Renderer::Create({o.device, false});
  if (!renderer.ok()) Die(std::string(renderer.status().message()));

  Json out;
  const DeviceInfo& dev = (*renderer)->device_info();
  out["device"] = {{"name", dev.name},
                   {"type", dev.type},
                   {"driver", dev.driver_info},
                   {"max_samples", dev.max_samples},
                   {"sample_counts", dev.sample_counts},
                   {"visibility_buffer", dev.visibility_buffer}};
  Json modes = Json::array();
  for (AaMode m : o.modes) modes.push_back(std::string(ToString(m)));
  out["run"] = {{"width", o.width},         {"height", o.height},     {"samples", o.samples},
                {"frames", o.frames},       {"warmup", o.warmup},     {"taa_frames", o.taa_frames},
                {"edge_cell", o.edge.cell}, {"edge_gap", o.edge.gap}, {"modes", modes},
                {"smoke", o.smoke}};
  out["conventions"] = {{"psnr_identical_db", kInfDb},
                        {"empty_selection", nullptr},
                        {"edge_threshold", kEdgeThreshold},
                        {"reference_factor", kRefFactor}};
  out["scenes"] = Json::object();
  out["skipped"] = Json::array();
  Problems problems;
  uint64_t next_view = 1;  // a fresh view per render series: TAA starts without history
  for (const std::string& name : o.scenes) {
    std::optional<QualityScene> sc = MakeScene(**renderer, name, o);
    if (!sc) {
      out["skipped"].push_back(name);
      continue;
    }
    out["scenes"][name] = RunScene(**renderer, *sc, o, next_view, problems);
  }
  CheckFinite(out, "", problems);
  std::printf("%s\n", out.dump(2).c_str());
  std::fflush(stdout);

  int status = 0;
  for (const std::string& p : problems.list) {
    std::fprintf(stderr, "%s: %s\n", program_invocation_short_name, p.c_str());
    status = 1;
  }
  if (o.smoke && out["scenes"].empty()) {
    std::fprintf(stderr, "%s: smoke run measured no scene\n", program_invocation_short_name);
    status = 1;
  }
  // With TESSERA_VALIDATION=1 (as in the smoke test) any validation message is a failure.
  if ((*renderer)->validation_message_count() > 0) {
    for (const std::string& m : (*renderer)->validation_messages())
      std::fprintf(stderr, "validation: %s\n", m.c_str());
    status = 1;
  }
  return status;
}
