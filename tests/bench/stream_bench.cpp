// tessera-stream-bench: how much of the renderer's speed survives the service. For each scene it
// measures, in one process and one after the other (never overlapping):
//   render-only  a Renderer renders and JPEG-encodes an orbit of frames: median ms of each, and
//                render_only_fps = 1000 / median render ms (the ceiling for a pipelined server,
//                which encodes frame N while it renders frame N+1);
//   streaming    an in-process tesserad on 127.0.0.1:0 (scenes other than "demo" are uploaded
//                through UploadScene in 1 MiB chunks) serves a Stream whose client moves the
//                camera one orbit step per received frame, keeping one event waiting so the
//                render thread never idles: stream_fps; then one event at a time, waiting for
//                the frame that reflects it: event-to-frame latency p50/p95.
// Prints JSON on stdout (logs go to stderr). A program, not a timed test: compare the ratios
// (stream_fps_ratio >= 0.9, latency_ratio <= 1) within one run, as the machines are noisy.
//
//   tessera-stream-bench --scenes demo,sponza --width 1280 --height 720 --seconds 10
//   tessera-stream-bench --smoke     # demo only, 64x64, about a second (ctest)
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"
#include "bench_stream.h"
#include "bench_util.h"
#include "renderer/renderer.h"
#include "renderer/scene/demo_scene.h"
#include "renderer/scene/gltf_import.h"
#include "server/convert.h"
#include "server/server.h"
#include "tessera/v1/render_service.grpc.pb.h"

namespace {

using namespace tessera::bench;  // bench_util.h, bench_stream.h

namespace v1 = tessera::v1;

constexpr double kLatencySlackMs = 10.0;  // latency budget = render + encode + this
constexpr double kTargetStreamFpsRatio = 0.9;
constexpr double kTargetLatencyRatio = 1.0;

struct Options {
  std::vector<std::string> scenes = {"demo", "sponza"};
  std::string assets;
  std::string device;
  uint32_t width = 1280;
  uint32_t height = 720;
  double seconds = 10.0;  // streaming throughput window, after the warm-up
  uint32_t latency_samples = 20;
  uint32_t warmup = 3;   // frames, in every measurement
  uint32_t frames = 20;  // render-only frames
};

v1::RenderSettings WireSettings(const Options& o) {
  v1::RenderSettings s;
  s.set_width(o.width);
  s.set_height(o.height);
  return s;
}

// A scene as the benchmark knows it: "demo" or a glTF file set read from disk.
struct BenchScene {
  std::string key;                            // as given in --scenes
  std::optional<tessera::GltfSource> source;  // unset for the built-in demo
  std::string local_scene_id;                 // what the server must answer for the upload
  Orbit orbit;
  nlohmann::json result;
  double render_ms = 0.0;
  double encode_ms = 0.0;
};

// (a) Render-only: the renderer alone, in this process.
nlohmann::json MeasureRenderOnly(tessera::Renderer& renderer, const Options& o, BenchScene* b) {
  const auto t0 = Clock::now();
  absl::StatusOr<tessera::SceneHandle> scene =
      b->source ? renderer.LoadScene(*b->source) : renderer.LoadScene(tessera::BuildDemoScene());
  if (!scene.ok()) Fail(b->key + ": " + std::string(scene.status().message()));
  const double load_ms = MsBetween(t0, Clock::now());
  const tessera::SceneInfo& info = (*scene)->info();
  const float aspect = float(o.width) / float(o.height);
  b->orbit = MakeOrbit(info.bounds, aspect);
  // The server's defaults with this size: what the Stream session will render with.
  absl::StatusOr<tessera::Settings> settings =
      tessera::server::MergeSettings(tessera::Settings{}, WireSettings(o));
  if (!settings.ok()) Fail(std::string(settings.status().message()));

  std::vector<double> render_ms, encode_ms, gpu_ms;
  for (uint32_t i = 0; i < o.warmup + o.frames; ++i) {
    absl::StatusOr<tessera::Camera> camera =
        tessera::server::ResolveCamera(b->orbit.At(i), info, aspect);
    if (!camera.ok()) Fail(b->key + ": " + std::string(camera.status().message()));
    const auto r0 = Clock::now();
    absl::StatusOr<tessera::Frame> frame = renderer.Render(**scene, *camera, *settings);
    const auto r1 = Clock::now();
    if (!frame.ok()) Fail(b->key + ": " + std::string(frame.status().message()));
    absl::StatusOr<std::vector<uint8_t>> jpeg =
        tessera::EncodeFrame(*frame, tessera::ImageFormat::kJpeg);
    const auto r2 = Clock::now();
    if (!jpeg.ok()) Fail(b->key + ": " + std::string(jpeg.status().message()));
    if (i < o.warmup) continue;
    render_ms.push_back(MsBetween(r0, r1));
    encode_ms.push_back(MsBetween(r1, r2));
    gpu_ms.push_back(frame->gpu_total_ms);
  }
  b->render_ms = Median(render_ms);
  b->encode_ms = Median(encode_ms);
  std::fprintf(stderr, "%s: render-only %.2f ms render, %.2f ms encode\n", b->key.c_str(),
               b->render_ms, b->encode_ms);
  return {{"name", info.name},
          {"triangles", info.counts.triangles},
          {"primitives", info.counts.primitives},
          {"load_ms", load_ms},
          {"gpu_total_ms_median", Median(gpu_ms)}};
}

// Uploads a file set through UploadScene; returns the scene id the server answered.
std::string Upload(v1::RenderService::Stub* stub, const BenchScene& b, double* upload_ms) {
  const auto t0 = Clock::now();
  v1::SceneInfo info;
  const grpc::Status status = UploadFileSet(stub, *b.source, &info);
  if (!status.ok()) Fail(b.key + ": UploadScene: " + status.error_message());
  if (info.scene_id() != b.local_scene_id)
    Fail(b.key + ": UploadScene answered scene id " + info.scene_id() + ", expected " +
         b.local_scene_id);
  *upload_ms = MsBetween(t0, Clock::now());
  return info.scene_id();
}

// One Stream call driven from this thread.
class Session {
 public:
  Session(v1::RenderService::Stub* stub, std::chrono::seconds timeout, const std::string& key)
      : key_(key) {
    ctx_.set_deadline(std::chrono::system_clock::now() + timeout);
    stream_ = stub->Stream(&ctx_);
  }

  // Opens the session (event 1) with the orbit's first camera.
  void Open(const std::string& scene_id, const Options& o, const Orbit& orbit) {
    v1::ClientEvent e;
    e.set_event_id(++last_sent_);
    e.mutable_open()->set_scene_id(scene_id);
    *e.mutable_open()->mutable_camera() = orbit.At(last_sent_);
    *e.mutable_open()->mutable_settings() = WireSettings(o);
    if (!stream_->Write(e)) FailWithStatus("open");
  }

  // Sends the next orbit step; returns its event id.
  uint64_t SendCamera(const Orbit& orbit) {
    v1::ClientEvent e;
    e.set_event_id(++last_sent_);
    *e.mutable_camera() = orbit.At(last_sent_);
    if (!stream_->Write(e)) FailWithStatus("write");
    return last_sent_;
  }

  // The next frame, checked: never older than the previous one, the requested size, not empty.
  void Read(const Options& o, v1::Frame* frame) {
    if (!stream_->Read(frame)) FailWithStatus("read");
    if (frame->event_id() < last_event_ || frame->event_id() > last_sent_)
      Fail(key_ + ": frame " + std::to_string(frame->sequence()) + " reflects event " +
           std::to_string(frame->event_id()) + " after event " + std::to_string(last_event_));
    if (frame->width() != o.width || frame->height() != o.height || frame->data().empty())
      Fail(key_ + ": frame " + std::to_string(frame->sequence()) + " is " +
           std::to_string(frame->width()) + "x" + std::to_string(frame->height()) + " with " +
           std::to_string(frame->data().size()) + " bytes");
    if (last_sequence_ > 0) gaps_ += frame->sequence() - last_sequence_ - 1;
    last_sequence_ = frame->sequence();
    last_event_ = frame->event_id();
  }

  // Half-closes, reads what the server still sends, and expects OK.
  void Close() {
    stream_->WritesDone();
    v1::Frame frame;
    while (stream_->Read(&frame)) {
      if (frame.event_id() < last_event_) Fail(key_ + ": stale frame after half-close");
    }
    const grpc::Status status = stream_->Finish();
    if (!status.ok()) Fail(key_ + ": Stream ended with " + status.error_message());
  }

  uint64_t last_sent() const { return last_sent_; }
  uint64_t gaps() const { return gaps_; }

 private:
  [[noreturn]] void FailWithStatus(const char* what) {
    const grpc::Status status = stream_->Finish();
    Fail(key_ + ": Stream " + what + " failed: " + std::to_string(status.error_code()) + " " +
         status.error_message());
  }

  std::string key_;
  grpc::ClientContext ctx_;
  std::unique_ptr<grpc::ClientReaderWriter<v1::ClientEvent, v1::Frame>> stream_;
  uint64_t last_sent_ = 0;
  uint64_t last_event_ = 0;
  uint64_t last_sequence_ = 0;
  uint64_t gaps_ = 0;
};

struct CpuMedians {
  std::vector<double> queue_wait, encode, total;
  void Add(const v1::Frame& f) {
    queue_wait.push_back(f.cpu().queue_wait_ms());
    encode.push_back(f.cpu().encode_ms());
    total.push_back(f.cpu().total_ms());
  }
  nlohmann::json Json() const {
    return {
        {"queue_wait", Median(queue_wait)}, {"encode", Median(encode)}, {"total", Median(total)}};
  }
};

// (b1) Throughput: one camera event per received frame, one event always waiting.
nlohmann::json MeasureStreamFps(v1::RenderService::Stub* stub, tessera::server::Server& server,
                                const std::string& scene_id, const Options& o, BenchScene* b) {
  Session s(stub, std::chrono::seconds(static_cast<int64_t>(o.seconds) + 600), b->key);
  s.Open(scene_id, o, b->orbit);
  std::this_thread::sleep_for(kRestartGap);
  s.SendCamera(b->orbit);
  v1::Frame frame;
  uint64_t received = 0, counted = 0, restarts = 0, rendered_at_start = 0;
  Clock::time_point start, last;
  bool measuring = false;
  CpuMedians cpu;
  for (;;) {
    s.Read(o, &frame);
    const Clock::time_point now = Clock::now();
    ++received;
    if (!measuring) {
      if (received >= std::max(1u, o.warmup)) {
        measuring = true;
        start = last = now;
        rendered_at_start = server.stats().frames_rendered;
      }
    } else {
      ++counted;
      last = now;
      cpu.Add(frame);
      if (MsBetween(start, now) >= o.seconds * 1000.0) break;
    }
    // Events the server has and this frame does not reflect. One: it renders that one now, so
    // queue the next. None: it is idle; restart the pipeline with two.
    const uint64_t waiting = s.last_sent() - frame.event_id();
    if (waiting == 0) {
      ++restarts;
      s.SendCamera(b->orbit);
      std::this_thread::sleep_for(kRestartGap);
      s.SendCamera(b->orbit);
    } else if (waiting == 1) {
      s.SendCamera(b->orbit);
    }
  }
  const uint64_t rendered = server.stats().frames_rendered - rendered_at_start;
  const double elapsed_s = MsBetween(start, last) / 1000.0;
  s.Close();
  const double fps = elapsed_s > 0.0 ? double(counted) / elapsed_s : 0.0;
  std::fprintf(stderr, "%s: streaming %.1f fps over %.1f s (%llu frames)\n", b->key.c_str(), fps,
               elapsed_s, static_cast<unsigned long long>(counted));
  return {{"fps", fps},
          {"frames", counted},
          {"seconds", elapsed_s},
          // Frames the render thread finished in the window, whether sent or replaced.
          {"server_render_fps", elapsed_s > 0.0 ? double(rendered) / elapsed_s : 0.0},
          {"frames_dropped", s.gaps()},
          {"pipeline_restarts", restarts},
          {"server_cpu_ms_median", cpu.Json()}};
}

// (b2) Latency: one event at a time, timed until the frame that reflects it arrives.
nlohmann::json MeasureLatency(v1::RenderService::Stub* stub, const std::string& scene_id,
                              const Options& o, BenchScene* b, std::vector<double>* latency_ms) {
  Session s(stub, std::chrono::seconds(600 + 30 * int64_t{o.latency_samples}), b->key);
  s.Open(scene_id, o, b->orbit);
  v1::Frame frame;
  s.Read(o, &frame);  // the open's frame; the session is idle after it
  CpuMedians cpu;
  for (uint32_t i = 0; i < o.warmup + o.latency_samples; ++i) {
    const auto t0 = Clock::now();
    const uint64_t id = s.SendCamera(b->orbit);
    do {
      s.Read(o, &frame);
    } while (frame.event_id() < id);
    const double ms = MsBetween(t0, Clock::now());
    if (i < o.warmup) continue;
    latency_ms->push_back(ms);
    cpu.Add(frame);
  }
  s.Close();
  return {{"frames", latency_ms->size()}, {"server_cpu_ms_median", cpu.Json()}};
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  o.assets = AssetsDir();
  // --smoke sets small defaults first, so later flags can still change them.
  if (HasFlag(argc, argv, "--smoke")) {
    o.scenes = {"demo"};
    o.width = o.height = 64;
    o.seconds = 1.0;
    o.latency_samples = 3;
    o.warmup = 1;
    o.frames = 3;
  }
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) Fail(arg + " needs a value");
      return argv[++i];
    };
    auto number = [&](uint32_t* out, uint32_t min) {
      if (!absl::SimpleAtoi(value(), out) || *out < min)
        Fail(arg + " wants a number >= " + std::to_string(min));
    };
    if (arg == "--smoke") {
      continue;
    } else if (arg == "--scenes") {
      o.scenes = absl::StrSplit(value(), ',', absl::SkipEmpty());
      if (o.scenes.empty()) Fail("--scenes wants demo,sponza or .gltf paths");
    } else if (arg == "--assets") {
      o.assets = value();
    } else if (arg == "--device") {
      o.device = value();
    } else if (arg == "--width") {
      number(&o.width, 1);
    } else if (arg == "--height") {
      number(&o.height, 1);
    } else if (arg == "--latency-samples") {
      number(&o.latency_samples, 1);
    } else if (arg == "--warmup") {
      number(&o.warmup, 0);
    } else if (arg == "--frames") {
      number(&o.frames, 1);
    } else if (arg == "--seconds") {
      if (!absl::SimpleAtod(value(), &o.seconds) || !(o.seconds > 0.0)) Fail("--seconds");
    } else {
      Fail("unknown option " + arg +
           " (--scenes demo,sponza --width N --height N --seconds S --latency-samples N "
           "--warmup N --frames N --assets DIR --device NAME --smoke)");
    }
  }

  std::vector<BenchScene> scenes;
  for (const std::string& key : o.scenes) {
    BenchScene b;
    b.key = key;
    if (key != "demo") {
      absl::StatusOr<tessera::GltfSource> source = ReadSceneFiles(key, o.assets);
      if (!source.ok()) Fail(std::string(source.status().message()));
      b.local_scene_id = LocalSceneId(*source);
      b.source = *std::move(source);
    }
    scenes.push_back(std::move(b));
  }

  nlohmann::json out;
  out["width"] = o.width;
  out["height"] = o.height;
  out["warmup"] = o.warmup;
  out["render_frames"] = o.frames;
  out["stream_seconds"] = o.seconds;
  out["latency_samples"] = o.latency_samples;
  out["targets"] = {{"stream_fps_ratio_min", kTargetStreamFpsRatio},
                    {"latency_ratio_max", kTargetLatencyRatio},
                    {"latency_slack_ms", kLatencySlackMs}};

  // (a) Render-only, on a renderer that is gone before the server opens its own device.
  uint64_t validation_messages = 0;
  {
    absl::StatusOr<std::unique_ptr<tessera::Renderer>> renderer =
        tessera::Renderer::Create({o.device, false});
    if (!renderer.ok()) Fail(std::string(renderer.status().message()));
    const tessera::DeviceInfo& dev = (*renderer)->device_info();
    out["device"] = {{"name", dev.name}, {"type", dev.type}, {"driver", dev.driver_info}};
    for (BenchScene& b : scenes) b.result["scene"] = MeasureRenderOnly(**renderer, o, &b);
    validation_messages = (*renderer)->validation_message_count();
    for (const std::string& m : (*renderer)->validation_messages())
      std::fprintf(stderr, "validation: %s\n", m.c_str());
  }

  // (b) Streaming through an in-process server.
  tessera::server::ServerOptions server_options;
  server_options.listen = "127.0.0.1:0";
  server_options.device = o.device;
  absl::StatusOr<std::unique_ptr<tessera::server::Server>> server =
      tessera::server::Server::Start(server_options);
  if (!server.ok()) Fail("server: " + std::string(server.status().message()));
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(256 << 20);  // large frames (the server allows 256 MiB)
  std::unique_ptr<v1::RenderService::Stub> stub = v1::RenderService::NewStub(
      grpc::CreateCustomChannel((*server)->address(), grpc::InsecureChannelCredentials(), args));

  for (BenchScene& b : scenes) {
    std::string scene_id = "demo";
    if (b.source) {
      double upload_ms = 0.0;
      scene_id = Upload(stub.get(), b, &upload_ms);
      b.result["upload_ms"] = upload_ms;
      b.source.reset();  // the server has it now
    }
    nlohmann::json stream = MeasureStreamFps(stub.get(), **server, scene_id, o, &b);
    std::vector<double> latency_ms;
    nlohmann::json latency = MeasureLatency(stub.get(), scene_id, o, &b, &latency_ms);

    const double render_only_fps = b.render_ms > 0.0 ? 1000.0 / b.render_ms : 0.0;
    const double stream_fps = stream["fps"];
    const double budget_ms = b.render_ms + b.encode_ms + kLatencySlackMs;
    const double p50 = Median(latency_ms);
    nlohmann::json& r = b.result;
    r["scene_key"] = b.key;
    r["scene_id"] = scene_id;
    r["render_ms_median"] = b.render_ms;
    r["encode_ms_median"] = b.encode_ms;
    r["render_only_fps"] = render_only_fps;
    r["stream_fps"] = stream_fps;
    r["stream_fps_ratio"] = render_only_fps > 0.0 ? stream_fps / render_only_fps : 0.0;
    r["latency_ms_p50"] = p50;
    r["latency_ms_p95"] = Percentile(latency_ms, 95.0);
    r["latency_budget_ms"] = budget_ms;
    r["latency_ratio"] = p50 / budget_ms;
    r["meets_targets"] = double(r["stream_fps_ratio"]) >= kTargetStreamFpsRatio &&
                         double(r["latency_ratio"]) <= kTargetLatencyRatio;
    r["frames"] = {{"render_only", o.frames},
                   {"stream", stream["frames"]},
                   {"stream_dropped", stream["frames_dropped"]},
                   {"latency", latency["frames"]}};
    r["stream"] = stream;
    r["latency"] = latency;
    out["results"].push_back(r);
  }
  const tessera::server::ServerStats stats = (*server)->stats();
  out["server"] = {{"frames_rendered", stats.frames_rendered},
                   {"frames_dropped", stats.frames_dropped}};
  (*server)->Shutdown();

  std::printf("%s\n", out.dump(2).c_str());
  // With TESSERA_VALIDATION=1 any validation message of the render-only renderer is a failure.
  return validation_messages > 0 ? 1 : 0;
}
