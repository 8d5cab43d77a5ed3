// tessera bench: a benchmark suite against a running tesserad. Each configuration (an AA mode,
// a culling mode, a synthetic light count) is one live session: warm-up frames, then measured
// frames with the camera orbiting one step per received frame. The table reports medians, not
// means: a shared machine's stalls would drag a mean anywhere.
#include <algorithm>
#include <cstdio>
#include <set>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "clients/cli/cli_commands.h"
#include "clients/cli/cli_format.h"
#include "clients/cli/cli_progress.h"
#include "clients/cli/cli_render_flags.h"
#include "clients/cli/cli_session.h"
#include "clients/cli/cli_stream_parts.h"
#include "google/protobuf/descriptor.h"

namespace tessera::cli {
namespace {

constexpr const char* kSuites[] = {"aa", "culling", "lights", "all"};
constexpr uint32_t kLightCounts[] = {0, 64, 256, 1024};

struct BenchOptions {
  std::string suite = "aa";
  std::string scene = "demo";
  uint32_t warmup = 3;
  uint32_t frames = 30;
  v1::VideoSettings video;
  RenderFlags flags;
};

BenchOptions ParseBenchOptions(const Invocation& inv) {
  BenchOptions o;
  ArgReader args(inv);
  while (args.Next()) {
    if (args.Is("--suite")) {
      o.suite = args.Value();
      if (std::find_if(std::begin(kSuites), std::end(kSuites),
                       [&](const char* s) { return o.suite == s; }) == std::end(kSuites)) {
        args.Fail(absl::StrCat("--suite '", o.suite, "': use aa, culling, lights or all"));
      }
    } else if (args.Is("--scene")) {
      o.scene = args.Value();
    } else if (args.Is("--warmup")) {
      o.warmup = args.Uint();
    } else if (args.Is("--frames")) {
      o.frames = args.Uint();
      if (o.frames == 0) args.Fail("--frames wants at least 1");
    } else if (ParseVideoFlag(args, &o.video)) {
    } else if (!o.flags.Parse(args)) {
      args.Unknown();
    }
  }
  o.flags.Finish(args);
  if (o.flags.has_fixed_placement()) {
    args.Fail("bench orbits the camera itself; it cannot be combined with --camera or --frame");
  }
  return o;
}

// One configuration of the suite: the setting it puts over the command line's settings.
struct Config {
  std::string suite;        // "aa", "culling" or "lights"
  std::string name;         // "aa msaa", "lights 256"
  Json setting;             // {"aa": "msaa"}, for --json
  v1::RenderSettings over;  // merged over the command line's settings
  std::string error;        // set when the configuration cannot be asked for at all
};

// An enum setting's configurations, one per name the server offers.
void AddEnumConfigs(const std::string& suite, const char* field,
                    const google::protobuf::RepeatedPtrField<std::string>& names,
                    const google::protobuf::EnumDescriptor* type,
                    void (*set)(v1::RenderSettings*, int), std::vector<Config>* out) {
  for (const std::string& name : names) {
    Config c{suite, absl::StrCat(suite, " ", name), {{field, name}}, {}, {}};
    const int value = ParseEnumShortName(type, name);
    if (value > 0) {
      set(&c.over, value);
    } else {
      c.error = absl::StrCat("this client does not know the ", field, " mode '", name, "'");
    }
    out->push_back(std::move(c));
  }
}

std::vector<Config> MakeConfigs(const std::string& suite, const v1::SettingChoices& choices) {
  std::vector<Config> out;
  const bool all = suite == "all";
  if (all || suite == "aa") {
    AddEnumConfigs(
        "aa", "aa", choices.aa(), v1::AaMode_descriptor(),
        [](v1::RenderSettings* s, int v) { s->set_aa(static_cast<v1::AaMode>(v)); }, &out);
  }
  if (all || suite == "culling") {
    AddEnumConfigs(
        "culling", "culling", choices.culling(), v1::CullingMode_descriptor(),
        [](v1::RenderSettings* s, int v) { s->set_culling(static_cast<v1::CullingMode>(v)); },
        &out);
  }
  if (all || suite == "lights") {
    for (uint32_t n : kLightCounts) {
      Config c{"lights", absl::StrCat("lights ", n), {{"synthetic_lights", n}}, {}, {}};
      c.over.set_synthetic_lights(n);
      out.push_back(std::move(c));
    }
  }
  return out;
}

// What one configuration measured.
struct Result {
  const Config* config = nullptr;
  grpc::Status status;  // not OK: the figures below are empty
  Summary summary;      // of the measured frames (warm-up left out)
  double fps = 0;       // measured frames over the wall time they took
  v1::Frame last;       // the last frame (no image): effective settings, size, timing source
};

// The session of one configuration: o.warmup + o.frames frames, one turn around the scene.
Result RunConfig(v1::RenderService::Stub* stub, const BenchOptions& o, const std::string& scene_id,
                 const std::optional<Orbit>& orbit, const Config& config, ProgressBar* bar,
                 uint64_t done_before) {
  Result r;
  r.config = &config;
  if (!config.error.empty()) {
    r.status = grpc::Status(grpc::StatusCode::UNIMPLEMENTED, config.error);
    return r;
  }
  SessionOptions so;
  so.scene = scene_id;
  so.frames = o.warmup + o.frames;
  so.orbit = true;
  so.flags = o.flags;
  so.video = o.video;
  so.flags.mutable_settings()->MergeFrom(config.over);
  Session session(so,
                  [&](const FrameRecord&, uint32_t index) { bar->Update(done_before + index); });
  r.status = session.Run(stub, scene_id, orbit);
  const std::vector<FrameRecord>& records = session.records();
  if (InterruptHandler::interrupted()) {
    r.status = grpc::Status(grpc::StatusCode::CANCELLED, "interrupted");
  } else if (r.status.ok() && records.size() < so.frames) {
    r.status = grpc::Status(grpc::StatusCode::UNKNOWN,
                            absl::StrCat("the server ended the stream after ", records.size(),
                                         " of ", so.frames, " frames"));
  }
  if (!r.status.ok()) return r;

  const std::vector<FrameRecord> measured(records.begin() + o.warmup, records.end());
  // Latency samples: the events the measured frames answered (the warm-up's are left out).
  const uint64_t last_warmup_event = o.warmup > 0 ? records[o.warmup - 1].frame.event_id() : 0;
  std::vector<std::pair<uint64_t, double>> latencies;
  for (const auto& l : session.latencies()) {
    if (l.first > last_warmup_event) latencies.push_back(l);
  }
  r.summary = Summarize(measured, latencies);
  r.fps = r.summary.fps;
  if (o.warmup > 0) {
    // From the last warm-up frame: o.frames intervals, not o.frames - 1.
    const double span_ms = records.back().received_ms - records[o.warmup - 1].received_ms;
    if (span_ms > 0) r.fps = o.frames * 1000.0 / span_ms;
  }
  r.last = records.back().frame;
  return r;
}

std::string TimingSourceName(v1::TimingSource source) {
  return EnumShortName(v1::TimingSource_descriptor()->FindValueByNumber(source));
}

// The timing source(s) of the results that ran, in words.
std::string TimingSourceText(const std::vector<Result>& results) {
  std::set<int> sources;
  for (const Result& r : results) {
    if (r.status.ok()) sources.insert(r.last.timing_source());
  }
  std::vector<std::string> words;
  for (int s : sources) {
    switch (s) {
      case v1::TIMING_GPU_TIMESTAMPS:
        words.push_back("device timestamps around each pass");
        break;
      case v1::TIMING_PASS_WALL_CLOCK:
        words.push_back("each pass submitted alone and timed by the wall clock (CPU device)");
        break;
      case v1::TIMING_FRAME_WALL_CLOCK:
        words.push_back(
            "one submission per frame, timed by the wall clock; passes as the device's "
            "timestamps say (CPU device)");
        break;
      default:
        words.push_back(TimingSourceName(static_cast<v1::TimingSource>(s)));
    }
  }
  return words.empty() ? "none (nothing ran)" : absl::StrJoin(words, "; ");
}

// "forward 14.10, depth_prepass 2.31, tonemap 1.02": the three passes with the largest median.
std::string TopPasses(const Summary& s) {
  std::vector<std::pair<std::string, double>> passes = s.pass_median_ms;
  std::stable_sort(passes.begin(), passes.end(),
                   [](const auto& a, const auto& b) { return a.second > b.second; });
  if (passes.size() > 3) passes.resize(3);
  std::vector<std::string> items;
  for (const auto& [name, ms] : passes) items.push_back(absl::StrFormat("%s %.2f", name, ms));
  return absl::StrJoin(items, ", ");
}

void PrintTable(const Invocation& inv, const BenchOptions& o, const v1::ServerInfo& info,
                const std::vector<Result>& results) {
  const v1::DeviceDescription& d = info.device();
  absl::PrintF("tesserad %s at %s, device %s (%s)\n", info.version(), inv.global.server, d.name(),
               d.type());
  absl::PrintF("timing   %s\n", TimingSourceText(results));
  const v1::RenderSettings& asked = o.flags.settings();
  std::string size = asked.has_width() && asked.has_height()
                         ? absl::StrCat(asked.width(), "x", asked.height())
                         : "the server's default size";
  for (const Result& r : results) {
    if (r.status.ok()) {
      size = absl::StrCat(r.last.width(), "x", r.last.height());
      break;
    }
  }
  absl::PrintF(
      "run      scene %s at %s, %u warm-up + %u measured frames per configuration, "
      "medians and p10-p90\n",
      o.scene, size, o.warmup, o.frames);
  // A fast configuration measures the cap, not the renderer; the gpu ms column still tells.
  absl::PrintF(
      "camera   orbiting, one step per received frame; the server caps a session at %g "
      "fps\n",
      info.limits().max_session_fps());
  absl::PrintF("settings %s (each row changes one)\n\n",
               WrapList(SettingsSummary(o.flags.settings()), 9));

  int width = 6;
  for (const Result& r : results) width = std::max<int>(width, r.config->name.size());
  absl::PrintF("%-*s %7s %8s %13s %8s %8s %8s %9s %8s  %s\n", width, "config", "fps", "gpu ms",
               "gpu p10-p90", "cpu ms", "lat p50", "lat p95", "KB/frame", "Mbit/s",
               "most expensive passes (gpu ms)");
  for (const Result& r : results) {
    if (!r.status.ok()) {
      absl::PrintF("%-*s FAILED  %s: %s\n", width, r.config->name,
                   StatusCodeName(r.status.error_code()), r.status.error_message());
      continue;
    }
    const Summary& s = r.summary;
    absl::PrintF("%-*s %7.1f %8.2f %13s %8.2f %8.1f %8.1f %9.1f %8.2f  %s\n", width,
                 r.config->name, r.fps, s.gpu_total_median_ms,
                 absl::StrFormat("%.2f-%.2f", s.gpu_total_p10_ms, s.gpu_total_p90_ms),
                 s.cpu_total_median_ms, Median(s.latencies_ms), Percentile(s.latencies_ms, 95),
                 s.bytes_median / 1000.0, s.bitrate_kbps / 1000.0, TopPasses(s));
  }
  for (const Result& r : results) {
    for (const v1::SettingNote& n : r.last.notes()) {
      absl::PrintF("note (%s): %s: %s\n", r.config->name, n.field(), n.message());
    }
  }
}

Json ResultJson(const Result& r) {
  Json j;
  j["config"] = r.config->name;
  j["suite"] = r.config->suite;
  j["setting"] = r.config->setting;
  j["ok"] = r.status.ok();
  if (!r.status.ok()) {
    j["error"] = ErrorJson(r.status);
    return j;
  }
  const Summary& s = r.summary;
  j["frames"] = s.frames;
  j["fps"] = r.fps;
  j["dropped"] = s.dropped;
  j["gpu_total_median_ms"] = s.gpu_total_median_ms;
  j["gpu_total_p10_ms"] = s.gpu_total_p10_ms;
  j["gpu_total_p90_ms"] = s.gpu_total_p90_ms;
  j["cpu_total_median_ms"] = s.cpu_total_median_ms;
  j["pass_median_ms"] = PassMediansJson(s);
  j["latency_ms"] = LatencyJson(s);
  j["bytes_median"] = s.bytes_median;
  j["bitrate_kbps"] = s.bitrate_kbps;
  j["codec"] = s.codec;
  j["keyframes"] = s.keyframes;
  j["timing_source"] = TimingSourceName(r.last.timing_source());
  j["width"] = r.last.width();
  j["height"] = r.last.height();
  j["settings"] = ToJson(r.last.settings());
  Json notes = Json::array();
  for (const v1::SettingNote& n : r.last.notes()) notes.push_back(ToJson(n));
  j["notes"] = std::move(notes);
  return j;
}

Json BenchJson(const Invocation& inv, const BenchOptions& o, const v1::ServerInfo& info,
               const std::string& scene_id, const std::vector<Result>& results) {
  Json j;
  j["server"] = inv.global.server;
  j["version"] = info.version();
  j["device"] = ToJson(info.device());
  j["scene"] = o.scene;
  j["scene_id"] = scene_id;
  j["suite"] = o.suite;
  j["warmup"] = o.warmup;
  j["frames"] = o.frames;
  j["settings"] = ToJson(o.flags.settings());
  j["max_session_fps"] = info.limits().max_session_fps();
  Json rows = Json::array();
  size_t failed = 0;
  for (const Result& r : results) {
    rows.push_back(ResultJson(r));
    if (!r.status.ok()) ++failed;
  }
  j["results"] = std::move(rows);
  j["failed"] = failed;
  return j;
}

int RunBench(const Invocation& inv) {
  const BenchOptions o = ParseBenchOptions(inv);
  auto stub = ConnectStub(inv);
  if (!stub) return kExitError;

  v1::ServerInfo info;
  {
    grpc::ClientContext context;
    SetDeadline(&context, kShortCallSeconds);
    grpc::Status status = stub->GetServerInfo(&context, v1::GetServerInfoRequest(), &info);
    if (!status.ok()) return ReportRpcError(inv, status);
  }
  // The scene once, before any session: a missing scene fails the run, not every row.
  std::string scene_id;
  bool found = false;
  if (grpc::Status st = ResolveSceneId(stub.get(), o.scene, &scene_id, nullptr, &found); !st.ok())
    return ReportRpcError(inv, st);
  if (!found) {
    return ReportRpcError(inv, grpc::Status(grpc::StatusCode::NOT_FOUND,
                                            absl::StrCat("scene_id: no scene \"", o.scene, "\"")));
  }
  SessionOptions plan;
  plan.scene = scene_id;
  plan.orbit = true;
  plan.flags = o.flags;
  std::optional<Orbit> orbit;
  if (grpc::Status st = PlanOrbit(stub.get(), plan, &scene_id, &orbit); !st.ok())
    return ReportRpcError(inv, st);

  const std::vector<Config> configs = MakeConfigs(o.suite, info.choices());
  const uint64_t per_config = o.warmup + o.frames;
  InterruptHandler interrupt;
  ProgressBar bar("bench", configs.size() * per_config);
  std::vector<Result> results;
  int rc = 0;
  for (const Config& config : configs) {
    bar.set_note(config.name);
    results.push_back(
        RunConfig(stub.get(), o, scene_id, orbit, config, &bar, results.size() * per_config));
    const Result& r = results.back();
    if (!r.status.ok()) {
      // One configuration failing (a mode the device cannot do) does not stop the others.
      bar.Clear();
      rc = ReportRpcError(inv,
                          grpc::Status(r.status.error_code(),
                                       absl::StrCat(config.name, ": ", r.status.error_message())));
    }
    if (InterruptHandler::interrupted()) {
      rc = kExitInterrupted;
      break;
    }
  }
  bar.Clear();
  if (inv.global.json) {
    PrintJson(BenchJson(inv, o, info, scene_id, results));
  } else {
    PrintTable(inv, o, info, results);
  }
  return rc;
}

}  // namespace

const Command kBenchCommand = {
    "bench", "run a benchmark suite on the server and print a table of medians",
    R"(usage: tessera bench [--suite aa|culling|lights|all] [--scene ID] [--warmup W]
                     [--frames N] [--codec jpeg|h264 [video flags]] [flags]
Runs one live session per configuration of the suite on the server's scene: W warm-up
frames, then N measured frames, the camera orbiting the scene one step per received frame
(one event in flight at a time). For each configuration it prints a row of medians over the
measured frames: frames/s (wall clock), GPU and CPU time per frame, input-to-frame latency
p50/p95 (a camera event sent -> the frame that reflects it), KB per frame, the bitrate (bytes
of the measured frames over their span), and the three most expensive passes; above the table, the device and where its timings come from (device
timestamps, each pass timed by the wall clock on a CPU device, or, with --no-pass-timing, the
frame in one submission timed by the wall clock). A progress bar over all
configurations shows on stderr when it is a terminal.
  --suite S           aa: every AA mode the server offers (the default); culling: every
                      culling mode; lights: 0, 64, 256 and 1024 synthetic lights; all: the three
  --scene ID          a scene id (or a unique prefix of 8+ characters) or "demo" (the default)
  --warmup W          frames rendered before measuring (default 3)
  --frames N          frames measured per configuration (default 30)
The settings flags apply to every configuration; each row then changes the one setting it
measures. --eye/--target set the orbit's centre and radius (--camera/--frame do not apply).
A configuration that fails (a mode the device cannot do) is reported in its row and on
stderr, and the others still run; the exit status is then 1 (130 after Ctrl-C, with the rows
measured so far).
fps cannot exceed the server's max_session_fps (tessera info), whatever the GPU time.
--json: {"server", "version", "device", "scene", "scene_id", "suite", "warmup", "frames",
"settings", "max_session_fps", "results": [{"config", "suite", "setting", "ok", "frames", "fps", "dropped",
"gpu_total_median_ms", "gpu_total_p10_ms", "gpu_total_p90_ms", "cpu_total_median_ms",
"pass_median_ms": [{"pass", "median_ms", "p10_ms", "p90_ms"}],
"latency_ms": {"median", "p95", "events", "samples"}, "bytes_median", "bitrate_kbps", "codec",
"keyframes", "timing_source",
"width", "height", "settings" (effective), "notes"} or {"config", "suite", "setting", "ok":
false, "error": {"code", "message"}}], "failed"}.
)" TESSERA_VIDEO_FLAGS_USAGE,
    /*render_flags=*/true, RunBench};

}  // namespace tessera::cli
