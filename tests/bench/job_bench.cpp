// tessera-job-bench: what a render-farm job costs the live viewers next to it, and what
// spreading a job's frames over several daemons costs per frame.
//
// 1. Live viewer while a job runs ("viewer"). One in-process tesserad on 127.0.0.1:0 per
//    background share (ServerOptions.background_share: the default, then 1.0 = no share limit,
//    to show what the limit buys). A live viewer is one Stream session in continuous mode
//    (OpenSession.target_fps = 30, still camera, --viewer-scene at 640x360) read as fast as
//    frames come, on a thread of its own, for the whole run. Each repeat (--repeats) has two
//    windows of --seconds:
//      - alone: nothing else on the server;
//      - with a job: SubmitJob (--scene at 1280x720, JPEG, 100000 frames so it outlasts the
//        window, the camera unset so every frame frames the bounds), the window opening once the
//        job's first frame is done (that frame builds the job's pipelines and views: warm-up),
//        then CancelJob and DeleteJob.
//    Per window: viewer fps (frames received / window), viewer latency p50/p95 (Frame.cpu
//    total_ms: from the continuous-mode tick until the frame was encoded, so a job frame the
//    render thread is busy with shows up here), the longest gap between two viewer frames, and
//    for the job the frames it finished in the window (Job.frames_done from WatchJob), its fps
//    and wall ms per frame, and its render + encode ms per frame (JobFrameEvent.cpu.total_ms).
//    drop_pct = 100 * (1 - fps with the job / fps alone), from the medians over the repeats;
//    the target is <= 20% with the default share.
//
// 2. Farm ("farm"). max(--daemons) tesserad processes (--tesserad) on 127.0.0.1:0, each telling
//    its port through --port_file. A warm-up run on each daemon puts the scene there and
//    renders two frames (pipelines built at the job's size); then, per repeat (--farm-repeats):
//      - the server-side baseline: `tessera --json --server D1 job submit --scene ID --frames
//        0..N-1 --out DIR` (SubmitJob on one daemon, no distribution): its seconds are the job's
//        own span (Job.finished_unix_s - created_unix_s), wall_seconds the whole command;
//      - for each daemon count k in --daemons: `tessera --json job submit --servers D1,..,Dk
//        --scene-file FILE --frames 0..N-1 --out DIR` (RenderJobFrame spread by the client):
//        its seconds (the CLI's, uploads excluded), seconds per frame and frames per daemon
//        (round_robin over the daemons connected so far: a late connection gets fewer).
//    distribution_overhead = 1-daemon farm seconds per frame / baseline seconds per frame: what
//    sending every frame through RenderJobFrame and writing it here costs over a server-side
//    job. Every run's frames are checked on disk (one non-empty file per frame).
//    The daemons share one machine's CPU cores (and on lavapipe the "GPU" is those cores too),
//    so more daemons cannot render faster here: the farm figures are per-frame cost and
//    overhead, not the speed-up of a farm of separate machines.
//
// Prints one JSON document on stdout (progress, the CLI's and the daemons' messages go to
// stderr); exit status 1 for a failed run (a job or a daemon failing, a missing output file,
// a viewer without frames, Vulkan validation messages), 2 for bad flags. Daemons and CLI runs
// are this process's children and get SIGTERM when it dies (PR_SET_PDEATHSIG): no orphans.
//
//   tessera-job-bench                       # Sponza jobs, demo viewer, 8 s windows, 1..3 daemons
//   tessera-job-bench --viewer-scene sponza --daemons 1,2 --frames 60
//   tessera-job-bench --smoke               # demo, 160x90, 6 frames, 1 and 2 daemons, 1 s (ctest)

#include <errno.h>  // program_invocation_short_name
#include <grpcpp/grpcpp.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "bench_stream.h"
#include "bench_util.h"
#include "process_util.h"
#include "renderer/scene/gltf_import.h"
#include "common/job_spec.h"
#include "server/server.h"
#include "tessera/v1/job.pb.h"
#include "tessera/v1/render_service.grpc.pb.h"

namespace {

using nlohmann::json;
using namespace tessera::bench;  // bench_util.h, bench_stream.h, process_util.h

namespace v1 = tessera::v1;
namespace fs = std::filesystem;

constexpr float kViewerFps = 30.0f;  // OpenSession.target_fps: a usual live viewer
// Far more than one window renders, even on a fast device with no share limit; the server's
// default max_job_frames.
constexpr uint32_t kViewerJobFrames = 100000;
constexpr uint32_t kViewerWarmupFrames = 10;  // before the first window
constexpr double kTargetDropPct = 20.0;       // the target, with the default share
constexpr double kUnlimitedShare = 1.0;       // ServerOptions.background_share: no limit
constexpr uint32_t kMaxDaemons = 8;

// Generous bounds, so a hung server or CLI ends the run with an error instead of a hang.
constexpr auto kCallDeadline = std::chrono::minutes(30);  // streams and watches

constexpr char kUsage[] =
    "usage: tessera-job-bench [--scene demo|sponza|PATH.gltf] [--viewer-scene demo|sponza|PATH]\n"
    "         [--seconds S] [--repeats N] [--frames N] [--daemons 1,2,3] [--farm-repeats N]\n"
    "         [--skip-viewer] [--skip-farm] [--tesserad PATH] [--tessera PATH] [--assets DIR]\n"
    "         [--device NAME] [--smoke]\n";

[[noreturn]] void UsageError(const std::string& msg) {
  std::fprintf(stderr, "%s: %s\n%s", program_invocation_short_name, msg.c_str(), kUsage);
  std::exit(2);
}

absl::Status FromGrpc(const std::string& what, const grpc::Status& status) {
  return absl::Status(static_cast<absl::StatusCode>(status.error_code()),
                      absl::StrCat(what, ": ", status.error_message()));
}

// An error with `context` in front of its message, same code.
absl::Status Prefixed(const std::string& context, const absl::Status& st) {
  return absl::Status(st.code(), absl::StrCat(context, ": ", st.message()));
}

Clock::duration FromSeconds(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

// A JSON number, or null where the figure does not exist (no frames to divide by).
json OrNull(std::optional<double> v) { return v ? json(*v) : json(nullptr); }

double Mean(const std::vector<double>& v) {
  if (v.empty()) return 0.0;
  double sum = 0.0;
  for (double x : v) sum += x;
  return sum / double(v.size());
}

struct Options {
  bool smoke = false;
  std::string scene = "sponza";       // the job's (and the farm's) scene
  std::string viewer_scene = "demo";  // the live viewer's
  std::string assets;
  std::string device;
  uint32_t viewer_width = 640;
  uint32_t viewer_height = 360;
  uint32_t job_width = 1280;
  uint32_t job_height = 720;
  double seconds = 8.0;   // each viewer window
  uint32_t repeats = 3;   // viewer window pairs per background share
  uint32_t frames = 120;  // the farm's job
  std::vector<uint32_t> daemons = {1, 2, 3};
  uint32_t farm_repeats = 1;
  bool skip_viewer = false;
  bool skip_farm = false;
  std::string tesserad;
  std::string tessera;
};

// --- scenes --------------------------------------------------------------------------------

// The glTF file a scene key names ("sponza" in the assets, or a path); empty for the demo.
std::string ScenePath(const std::string& key, const std::string& assets) {
  if (key == "demo") return "";
  if (key == "sponza") return assets + "/Sponza/glTF/Sponza.gltf";  // as ReadSceneFiles
  return key;
}

// A scene as the benchmark knows it: "demo" or a glTF file set read from disk (uploaded to the
// in-process servers; the farm's CLI reads the file itself).
struct BenchScene {
  std::string key;   // as given in the flags
  std::string path;  // the .gltf/.glb file; empty for the demo
  std::optional<tessera::GltfSource> source;
  std::string scene_id;  // "demo", or the content hash computed here
};

absl::StatusOr<BenchScene> ReadScene(const std::string& key, const std::string& assets) {
  BenchScene b;
  b.key = key;
  b.scene_id = "demo";
  if (key == "demo") return b;
  b.path = ScenePath(key, assets);
  absl::StatusOr<tessera::GltfSource> source = ReadSceneFiles(key, assets);
  if (!source.ok()) return source.status();
  b.scene_id = LocalSceneId(*source);
  b.source = *std::move(source);
  return b;
}

// Puts `b` on the server (UploadScene; the demo is looked up) and returns what the server
// knows about it.
absl::StatusOr<v1::SceneInfo> PutScene(v1::RenderService::Stub* stub, const BenchScene& b) {
  if (!b.source) {
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::minutes(1));
    v1::HasSceneRequest request;
    request.set_scene_id(b.scene_id);
    v1::HasSceneResponse response;
    if (grpc::Status st = stub->HasScene(&ctx, request, &response); !st.ok())
      return FromGrpc(b.key + ": HasScene", st);
    if (!response.present()) return absl::NotFoundError(b.key + ": not on the server");
    return response.info();
  }
  v1::SceneInfo info;
  if (grpc::Status st = UploadFileSet(stub, *b.source, &info); !st.ok())
    return FromGrpc(b.key + ": UploadScene", st);
  if (info.scene_id() != b.scene_id)
    return absl::InternalError(absl::StrCat(b.key, ": UploadScene answered scene id ",
                                            info.scene_id(), ", expected ", b.scene_id));
  return info;
}

absl::StatusOr<v1::ServerInfo> GetServerInfo(v1::RenderService::Stub* stub) {
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  v1::ServerInfo info;
  if (grpc::Status st = stub->GetServerInfo(&ctx, v1::GetServerInfoRequest{}, &info); !st.ok())
    return FromGrpc("GetServerInfo", st);
  return info;
}

json DeviceJson(const v1::ServerInfo& info) {
  const v1::DeviceDescription& d = info.device();
  return {{"name", d.name()},
          {"type", d.type()},
          {"driver_name", d.driver_name()},
          {"driver_info", d.driver_info()},
          {"api_version", d.api_version()},
          {"server_version", info.version()}};
}

std::shared_ptr<grpc::Channel> NewChannel(const std::string& address) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(256 << 20);  // large frames (the server allows 256 MiB)
  // A connection of its own, as a separate viewer has: channels would otherwise share one.
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
}

// --- part 1: a live viewer while a job runs --------------------------------------------------

// One frame the viewer received.
struct ViewerFrame {
  Clock::time_point received;
  uint64_t sequence = 0;
  double total_ms = 0.0;  // Frame.cpu.total_ms
};

// The live viewer: one Stream session in continuous mode on a thread of its own, reading every
// frame as it comes until Stop(). The main thread takes what arrived between two instants.
class LiveViewer {
 public:
  LiveViewer(std::shared_ptr<grpc::Channel> channel, v1::OpenSession open)
      : stub_(v1::RenderService::NewStub(std::move(channel))), open_(std::move(open)) {
    ctx_.set_deadline(std::chrono::system_clock::now() + kCallDeadline);
    thread_ = std::thread([this] { Run(); });
  }
  ~LiveViewer() { (void)Stop(); }
  LiveViewer(const LiveViewer&) = delete;
  LiveViewer& operator=(const LiveViewer&) = delete;

  // Waits until `n` frames have arrived; an error when the stream failed or `timeout` passed.
  absl::Status WaitFrames(size_t n, Clock::duration timeout) {
    std::unique_lock lock(mu_);
    cv_.wait_for(lock, timeout, [&] { return done_ || frames_.size() >= n; });
    if (frames_.size() >= n) return absl::OkStatus();
    if (!status_.ok()) return status_;
    return absl::DeadlineExceededError(absl::StrCat("viewer: ", frames_.size(), " of ", n,
                                                    " frames within ", Seconds(timeout), " s"));
  }

  // The stream's error, if it has failed by now.
  absl::Status Health() const {
    std::lock_guard lock(mu_);
    return status_;
  }

  std::vector<ViewerFrame> Between(Clock::time_point a, Clock::time_point b) const {
    std::lock_guard lock(mu_);
    std::vector<ViewerFrame> out;
    for (const ViewerFrame& f : frames_)
      if (f.received >= a && f.received < b) out.push_back(f);
    return out;
  }

  // Half-closes, drains and checks how the stream ended. Idempotent.
  absl::Status Stop() {
    stop_.store(true);
    {
      // A stream that stopped delivering (a stuck server) is cancelled rather than waited on.
      std::unique_lock lock(mu_);
      if (!cv_.wait_for(lock, std::chrono::seconds(30), [&] { return done_; })) ctx_.TryCancel();
    }
    if (thread_.joinable()) thread_.join();
    std::lock_guard lock(mu_);
    return status_;
  }

 private:
  void Run() {
    absl::Status result = Stream();
    std::lock_guard lock(mu_);
    status_ = result;
    done_ = true;
    cv_.notify_all();
  }

  absl::Status Stream() {
    std::unique_ptr<grpc::ClientReaderWriter<v1::ClientEvent, v1::Frame>> stream =
        stub_->Stream(&ctx_);
    v1::ClientEvent open;
    open.set_event_id(1);
    *open.mutable_open() = open_;
    if (!stream->Write(open)) return FromGrpc("viewer: Stream write failed", stream->Finish());
    v1::Frame frame;
    while (!stop_.load()) {
      if (!stream->Read(&frame)) {
        const grpc::Status st = stream->Finish();
        if (st.ok()) return absl::InternalError("viewer: the stream ended early with OK");
        return FromGrpc("viewer: Stream read failed", st);
      }
      if (absl::Status st = Record(frame); !st.ok()) {
        ctx_.TryCancel();
        stream->Finish();
        return st;
      }
    }
    // Half-close; the server sends what it still has, then ends the stream with OK. Those
    // frames come after every window and are not recorded.
    stream->WritesDone();
    while (stream->Read(&frame)) {
    }
    if (grpc::Status st = stream->Finish(); !st.ok()) return FromGrpc("viewer: Stream ended", st);
    return absl::OkStatus();
  }

  absl::Status Record(const v1::Frame& frame) {
    const v1::RenderSettings& s = open_.settings();
    if (frame.width() != s.width() || frame.height() != s.height() || frame.data().empty())
      return absl::InternalError(absl::StrCat("viewer: frame ", frame.sequence(), " is ",
                                              frame.width(), "x", frame.height(), " with ",
                                              frame.data().size(), " bytes"));
    ViewerFrame f;
    f.received = Clock::now();
    f.sequence = frame.sequence();
    f.total_ms = frame.cpu().total_ms();
    std::lock_guard lock(mu_);
    frames_.push_back(f);
    cv_.notify_all();
    return absl::OkStatus();
  }

  std::unique_ptr<v1::RenderService::Stub> stub_;
  const v1::OpenSession open_;
  grpc::ClientContext ctx_;
  std::atomic<bool> stop_{false};
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::vector<ViewerFrame> frames_;
  absl::Status status_;
  bool done_ = false;
  std::thread thread_;  // started in the constructor, once every member above exists
};

// What WatchJob told, as it arrived.
struct JobRecord {
  Clock::time_point received;
  uint32_t frames_done = 0;
  v1::JobState state = v1::JOB_STATE_UNSPECIFIED;
  double mean_frame_ms = 0.0;   // Job.mean_frame_ms
  bool has_frame = false;       // a finished-frame event
  double frame_total_ms = 0.0;  // JobFrameEvent.cpu.total_ms: render + encode
  double frame_gpu_ms = 0.0;
};

// WatchJob on a thread of its own, from SubmitJob until the job's final state.
class JobWatch {
 public:
  JobWatch(std::shared_ptr<grpc::Channel> channel, std::string job_id)
      : stub_(v1::RenderService::NewStub(std::move(channel))), job_id_(std::move(job_id)) {
    ctx_.set_deadline(std::chrono::system_clock::now() + kCallDeadline);
    thread_ = std::thread([this] { Run(); });
  }
  ~JobWatch() {
    ctx_.TryCancel();  // a no-op once the watch has ended
    if (thread_.joinable()) thread_.join();
  }
  JobWatch(const JobWatch&) = delete;
  JobWatch& operator=(const JobWatch&) = delete;

  // Waits until the job has `n` frames done; an error when it ended first or `timeout` passed.
  absl::Status WaitFramesDone(uint32_t n, Clock::duration timeout) {
    std::unique_lock lock(mu_);
    cv_.wait_for(lock, timeout, [&] { return done_ || frames_done_ >= n; });
    if (frames_done_ >= n) return absl::OkStatus();
    if (done_)
      return absl::InternalError(
          absl::StrCat("job ", job_id_, " ended ", v1::JobState_Name(state_), " with ",
                       frames_done_, " frames done", error_.empty() ? "" : ": ", error_,
                       status_.ok() ? "" : absl::StrCat(" (", status_.message(), ")")));
    return absl::DeadlineExceededError(
        absl::StrCat("job ", job_id_, ": no frame done within ", Seconds(timeout), " s"));
  }

  // Waits for the watch to end (after the job's final state) and returns that state; the watch
  // is cancelled past `timeout`.
  absl::StatusOr<v1::JobState> Finish(Clock::duration timeout) {
    {
      std::unique_lock lock(mu_);
      if (!cv_.wait_for(lock, timeout, [&] { return done_; })) ctx_.TryCancel();
    }
    if (thread_.joinable()) thread_.join();
    std::lock_guard lock(mu_);
    if (!status_.ok()) return status_;
    return state_;
  }

  std::vector<JobRecord> records() const {
    std::lock_guard lock(mu_);
    return records_;
  }

  std::string error() const {
    std::lock_guard lock(mu_);
    return error_;
  }

 private:
  void Run() {
    v1::WatchJobRequest request;
    request.set_job_id(job_id_);
    std::unique_ptr<grpc::ClientReader<v1::JobProgress>> reader = stub_->WatchJob(&ctx_, request);
    v1::JobProgress p;
    while (reader->Read(&p)) {
      JobRecord r;
      r.received = Clock::now();
      r.frames_done = p.job().frames_done();
      r.state = p.job().state();
      r.mean_frame_ms = p.job().mean_frame_ms();
      const std::string error = p.job().error();
      if (p.has_frame()) {
        r.has_frame = true;
        r.frame_total_ms = p.frame().cpu().total_ms();
        r.frame_gpu_ms = p.frame().gpu_total_ms();
      }
      std::lock_guard lock(mu_);
      records_.push_back(r);
      frames_done_ = r.frames_done;
      state_ = r.state;
      if (!error.empty()) error_ = error;
      cv_.notify_all();
    }
    const grpc::Status st = reader->Finish();
    std::lock_guard lock(mu_);
    if (!st.ok()) status_ = FromGrpc(absl::StrCat("WatchJob ", job_id_), st);
    done_ = true;
    cv_.notify_all();
  }

  std::unique_ptr<v1::RenderService::Stub> stub_;
  const std::string job_id_;
  grpc::ClientContext ctx_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::vector<JobRecord> records_;
  uint32_t frames_done_ = 0;
  v1::JobState state_ = v1::JOB_STATE_UNSPECIFIED;
  std::string error_;  // Job.error, once the job has one
  absl::Status status_;
  bool done_ = false;
  std::thread thread_;  // started in the constructor, once every member above exists
};

absl::StatusOr<v1::Job> SubmitJob(v1::RenderService::Stub* stub, const v1::JobSpec& spec) {
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::minutes(2));
  v1::SubmitJobRequest request;
  *request.mutable_spec() = spec;
  v1::Job job;
  if (grpc::Status st = stub->SubmitJob(&ctx, request, &job); !st.ok())
    return FromGrpc("SubmitJob", st);
  return job;
}

absl::Status CancelAndDelete(v1::RenderService::Stub* stub, const std::string& job_id,
                             JobWatch* watch, v1::JobState* final_state) {
  {
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::minutes(1));
    v1::CancelJobRequest request;
    request.set_job_id(job_id);
    v1::Job job;
    if (grpc::Status st = stub->CancelJob(&ctx, request, &job); !st.ok())
      return FromGrpc("CancelJob " + job_id, st);
  }
  absl::StatusOr<v1::JobState> state = watch->Finish(std::chrono::minutes(1));
  if (!state.ok()) return state.status();
  *final_state = *state;
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::minutes(1));
  v1::DeleteJobRequest request;
  request.set_job_id(job_id);
  v1::DeleteJobResponse response;
  if (grpc::Status st = stub->DeleteJob(&ctx, request, &response); !st.ok())
    return FromGrpc("DeleteJob " + job_id, st);
  return absl::OkStatus();
}

// The viewer's figures over one window.
json ViewerWindowJson(const std::vector<ViewerFrame>& frames, double seconds) {
  std::vector<double> total_ms;
  double max_gap_ms = 0.0;
  uint64_t gaps = 0;
  for (size_t i = 0; i < frames.size(); ++i) {
    total_ms.push_back(frames[i].total_ms);
    if (i == 0) continue;
    max_gap_ms = std::max(max_gap_ms, MsBetween(frames[i - 1].received, frames[i].received));
    gaps += frames[i].sequence - frames[i - 1].sequence - 1;
  }
  return {{"frames", frames.size()},
          {"fps", double(frames.size()) / seconds},
          {"latency_ms_p50", Median(total_ms)},
          {"latency_ms_p95", Percentile(total_ms, 95.0)},
          {"max_gap_ms", max_gap_ms},
          // Frames encoded but replaced by a newer one before they were sent.
          {"sequence_gaps", gaps}};
}

// Job.frames_done as last told at `t` (0 before the first message).
uint32_t FramesDoneAt(const std::vector<JobRecord>& records, Clock::time_point t) {
  uint32_t done = 0;
  for (const JobRecord& r : records) {
    if (r.received > t) break;
    done = r.frames_done;
  }
  return done;
}

// The job's figures over one window [a, b).
json JobWindowJson(const std::vector<JobRecord>& records, Clock::time_point a, Clock::time_point b,
                   double seconds) {
  const uint32_t frames = FramesDoneAt(records, b) - FramesDoneAt(records, a);
  std::vector<double> total_ms, gpu_ms;
  double server_mean_ms = 0.0;
  for (const JobRecord& r : records) {
    if (r.received >= b) break;
    server_mean_ms = r.mean_frame_ms;
    if (r.received < a || !r.has_frame) continue;
    total_ms.push_back(r.frame_total_ms);
    gpu_ms.push_back(r.frame_gpu_ms);
  }
  const bool any = !total_ms.empty();
  return {{"frames_done", frames},
          {"fps", double(frames) / seconds},
          // Window / frames: how often the job gets a frame while the viewer runs.
          {"wall_ms_per_frame",
           OrNull(frames ? std::optional(1000.0 * seconds / frames) : std::nullopt)},
          // What one job frame costs the render thread and the encoder.
          {"frame_ms_mean", OrNull(any ? std::optional(Mean(total_ms)) : std::nullopt)},
          {"frame_ms_median", OrNull(any ? std::optional(Median(total_ms)) : std::nullopt)},
          {"gpu_ms_median", OrNull(any ? std::optional(Median(gpu_ms)) : std::nullopt)},
          // Job.mean_frame_ms as the server last told it (its run so far, not this window).
          {"server_mean_frame_ms", server_mean_ms}};
}

// Medians over the repeats of `window`.`key` (nulls skipped); nullopt when there is none.
std::optional<double> MedianOf(const json& repeats, const std::string& window,
                               const std::string& key, const std::string& sub = "") {
  std::vector<double> v;
  for (const json& r : repeats) {
    const json& w = sub.empty() ? r.at(window) : r.at(window).at(sub);
    if (w.at(key).is_number()) v.push_back(w.at(key).get<double>());
  }
  if (v.empty()) return std::nullopt;
  return Median(v);
}

// One server at one background share: the viewer, then --repeats pairs of windows.
absl::StatusOr<json> RunShare(const Options& o, const BenchScene& viewer_scene,
                              const BenchScene& job_scene, double share, json* device) {
  const std::string tag = absl::StrFormat("[viewer, background_share %.2f]", share);
  std::fprintf(stderr, "%s starting the server\n", tag.c_str());
  tessera::server::ServerOptions so;
  so.listen = "127.0.0.1:0";
  so.device = o.device;
  so.validation = std::getenv("TESSERA_VALIDATION") != nullptr;
  so.load_demo_scene = true;
  so.background_share = share;
  so.max_job_frames = std::max(so.max_job_frames, kViewerJobFrames);
  absl::StatusOr<std::unique_ptr<tessera::server::Server>> started =
      tessera::server::Server::Start(so);
  if (!started.ok()) return Prefixed(tag + " server", started.status());
  // Declared first, destroyed last: the viewer and watch threads end before the server.
  std::unique_ptr<tessera::server::Server> server = *std::move(started);
  std::shared_ptr<grpc::Channel> control = NewChannel(server->address());
  std::unique_ptr<v1::RenderService::Stub> stub = v1::RenderService::NewStub(control);
  absl::StatusOr<v1::ServerInfo> info = GetServerInfo(stub.get());
  if (!info.ok()) return info.status();
  if (device->is_null()) *device = DeviceJson(*info);

  absl::StatusOr<v1::SceneInfo> vscene = PutScene(stub.get(), viewer_scene);
  if (!vscene.ok()) return vscene.status();
  absl::StatusOr<v1::SceneInfo> jscene = PutScene(stub.get(), job_scene);
  if (!jscene.ok()) return jscene.status();

  v1::OpenSession open;
  open.set_scene_id(vscene->scene_id());
  open.set_target_fps(kViewerFps);
  open.mutable_settings()->set_width(o.viewer_width);
  open.mutable_settings()->set_height(o.viewer_height);
  *open.mutable_camera() =
      MakeOrbit(vscene->bounds(), float(o.viewer_width) / float(o.viewer_height)).At(0);

  v1::JobSpec spec;
  spec.set_name("tessera-job-bench: beside a live viewer");
  spec.set_scene_id(jscene->scene_id());
  spec.mutable_settings()->set_width(o.job_width);
  spec.mutable_settings()->set_height(o.job_height);
  spec.mutable_frames()->set_first(0);
  spec.mutable_frames()->set_last(kViewerJobFrames - 1);
  spec.set_encoding(v1::IMAGE_JPEG);
  spec.set_output(v1::JOB_OUTPUT_RETURN);

  // The viewer's own connection, as a user's would be; it streams until the last window ends.
  LiveViewer viewer(NewChannel(server->address()), open);
  if (absl::Status st = viewer.WaitFrames(kViewerWarmupFrames, std::chrono::seconds(60)); !st.ok())
    return Prefixed(tag, st);

  const Clock::duration window = FromSeconds(o.seconds);
  const Clock::duration first_frame_timeout =
      o.smoke ? std::chrono::seconds(60) : std::chrono::seconds(600);
  json repeats = json::array();
  for (uint32_t rep = 0; rep < o.repeats; ++rep) {
    const Clock::time_point a0 = Clock::now();
    std::this_thread::sleep_until(a0 + window);
    const Clock::time_point a1 = Clock::now();
    if (absl::Status st = viewer.Health(); !st.ok()) return Prefixed(tag, st);

    absl::StatusOr<v1::Job> job = SubmitJob(stub.get(), spec);
    if (!job.ok()) return Prefixed(tag, job.status());
    JobWatch watch(control, job->job_id());
    // Without a share, background work runs only when no viewer frame waits: beside a
    // render-bound viewer the job may never get a frame. That is a result, not an error.
    bool starved = false;
    if (absl::Status st = watch.WaitFramesDone(
            1, share < 1.0 ? first_frame_timeout
                           : std::max<Clock::duration>(2 * window, std::chrono::seconds(10)));
        !st.ok()) {
      if (share < 1.0 || !absl::IsDeadlineExceeded(st)) return Prefixed(tag, st);
      starved = true;
      std::fprintf(stderr, "%s the job got no frame beside the viewer (starved)\n", tag.c_str());
    }
    const Clock::time_point b0 = Clock::now();
    std::this_thread::sleep_until(b0 + window);
    const Clock::time_point b1 = Clock::now();
    if (absl::Status st = viewer.Health(); !st.ok()) return Prefixed(tag, st);

    v1::JobState final_state = v1::JOB_STATE_UNSPECIFIED;
    if (absl::Status st = CancelAndDelete(stub.get(), job->job_id(), &watch, &final_state);
        !st.ok())
      return Prefixed(tag, st);
    // A job that ended by itself did not last the window (or failed): its figures are not
    // those of a running job.
    if (final_state != v1::JOB_CANCELLED)
      return absl::InternalError(
          absl::StrCat(tag, " job ", job->job_id(), " ended ", v1::JobState_Name(final_state),
                       " before it was cancelled", watch.error().empty() ? "" : ": ", watch.error(),
                       final_state == v1::JOB_SUCCEEDED
                           ? " (all its frames within the window: shorten --seconds)"
                           : ""));

    const std::vector<ViewerFrame> alone = viewer.Between(a0, a1);
    const std::vector<ViewerFrame> with_job = viewer.Between(b0, b1);
    if (alone.empty() || with_job.empty())
      return absl::InternalError(absl::StrCat(tag, " no viewer frames in a window (", alone.size(),
                                              " alone, ", with_job.size(), " with the job)"));
    const std::vector<JobRecord> records = watch.records();
    const double sa = Seconds(a1 - a0), sb = Seconds(b1 - b0);
    json r = {{"alone", ViewerWindowJson(alone, sa)}, {"with_job", ViewerWindowJson(with_job, sb)}};
    r["with_job"]["job"] = JobWindowJson(records, b0, b1, sb);
    r["with_job"]["job"]["starved"] = starved;
    const double fa = r["alone"]["fps"].get<double>(), fb = r["with_job"]["fps"].get<double>();
    r["drop_pct"] = 100.0 * (1.0 - fb / fa);
    const json& jw = r["with_job"]["job"];
    std::fprintf(stderr,
                 "%s repeat %u/%u: viewer %.1f fps alone, %.1f fps with the job (%+.1f%%), "
                 "latency p95 %.0f -> %.0f ms; job %u frames in %.1f s (%s ms/frame to render)\n",
                 tag.c_str(), rep + 1, o.repeats, fa, fb, -r["drop_pct"].get<double>(),
                 r["alone"]["latency_ms_p95"].get<double>(),
                 r["with_job"]["latency_ms_p95"].get<double>(), jw["frames_done"].get<uint32_t>(),
                 sb, jw["frame_ms_mean"].dump().c_str());
    repeats.push_back(std::move(r));

    // The render thread may still be inside a job frame it took before the cancel; the next
    // "alone" window must not see it.
    double longest_ms = 0.0;
    for (const JobRecord& rec : records) longest_ms = std::max(longest_ms, rec.frame_total_ms);
    std::this_thread::sleep_for(FromSeconds(std::max(0.5, 2.0 * longest_ms / 1000.0)));
  }
  if (absl::Status st = viewer.Stop(); !st.ok()) return Prefixed(tag, st);

  const tessera::server::ServerStats stats = server->stats();
  server->Shutdown();
  if (stats.validation_messages > 0)
    return absl::InternalError(absl::StrCat(tag, " ", stats.validation_messages,
                                            " Vulkan validation messages (see the log)"));

  const double fps_alone = MedianOf(repeats, "alone", "fps").value_or(0.0);
  const double fps_job = MedianOf(repeats, "with_job", "fps").value_or(0.0);
  const double drop = fps_alone > 0.0 ? 100.0 * (1.0 - fps_job / fps_alone) : 100.0;
  return json{
      {"background_share", share},
      {"share_limited", share < 1.0},
      {"viewer_fps_alone", fps_alone},
      {"viewer_fps_with_job", fps_job},
      {"drop_pct", drop},
      {"latency_ms_p50_alone", OrNull(MedianOf(repeats, "alone", "latency_ms_p50"))},
      {"latency_ms_p95_alone", OrNull(MedianOf(repeats, "alone", "latency_ms_p95"))},
      {"latency_ms_p50_with_job", OrNull(MedianOf(repeats, "with_job", "latency_ms_p50"))},
      {"latency_ms_p95_with_job", OrNull(MedianOf(repeats, "with_job", "latency_ms_p95"))},
      {"max_gap_ms_with_job", OrNull(MedianOf(repeats, "with_job", "max_gap_ms"))},
      {"job_frames_in_window", OrNull(MedianOf(repeats, "with_job", "frames_done", "job"))},
      {"job_fps", OrNull(MedianOf(repeats, "with_job", "fps", "job"))},
      {"job_wall_ms_per_frame", OrNull(MedianOf(repeats, "with_job", "wall_ms_per_frame", "job"))},
      {"job_frame_ms_mean", OrNull(MedianOf(repeats, "with_job", "frame_ms_mean", "job"))},
      // The target is about the limited share; without a limit there is none to meet.
      {"meets_target", share < 1.0 ? json(drop <= kTargetDropPct) : json(nullptr)},
      {"server_frames_rendered", stats.frames_rendered},
      {"repeats", repeats}};
}

absl::StatusOr<json> RunViewerPart(const Options& o, const BenchScene& viewer_scene,
                                   const BenchScene& job_scene, json* device) {
  const double default_share = tessera::server::ServerOptions{}.background_share;
  json out = {{"viewer_scene", viewer_scene.key},
              {"viewer_width", o.viewer_width},
              {"viewer_height", o.viewer_height},
              {"viewer_target_fps", kViewerFps},
              {"job_scene", job_scene.key},
              {"job_width", o.job_width},
              {"job_height", o.job_height},
              {"job_frames", kViewerJobFrames},
              {"seconds", o.seconds},
              {"repeats", o.repeats},
              {"target_drop_pct_max", kTargetDropPct}};
  json shares = json::array();
  for (double share : {default_share, kUnlimitedShare}) {
    absl::StatusOr<json> r = RunShare(o, viewer_scene, job_scene, share, device);
    if (!r.ok()) return r.status();
    std::fprintf(stderr,
                 "[viewer, background_share %.2f] median: %.1f fps alone, %.1f fps with the job "
                 "(drop %.1f%%), job %.1f frames/s\n",
                 share, (*r)["viewer_fps_alone"].get<double>(),
                 (*r)["viewer_fps_with_job"].get<double>(), (*r)["drop_pct"].get<double>(),
                 (*r)["job_fps"].is_number() ? (*r)["job_fps"].get<double>() : 0.0);
    shares.push_back(*std::move(r));
  }
  const json& limited = shares[0];
  const json& unlimited = shares[1];
  out["shares"] = shares;
  // The target is about the default share; no limit shows what the limit buys the viewer and
  // what it costs the job.
  out["drop_pct"] = limited["drop_pct"];
  out["meets_target"] = limited["meets_target"];
  out["limit_buys"] = {{"drop_pct_limited", limited["drop_pct"]},
                       {"drop_pct_unlimited", unlimited["drop_pct"]},
                       {"latency_ms_p95_limited", limited["latency_ms_p95_with_job"]},
                       {"latency_ms_p95_unlimited", unlimited["latency_ms_p95_with_job"]},
                       {"job_fps_limited", limited["job_fps"]},
                       {"job_fps_unlimited", unlimited["job_fps"]}};
  return out;
}

// --- part 2: the farm ----------------------------------------------------------------------

// Every frame 0..frames-1 of a run is in `dir` under the job's name, not empty.
absl::Status CheckFrameFiles(const std::string& dir, uint32_t frames) {
  v1::JobSpec spec;  // the CLI's default names: frame_%05d.jpg
  spec.set_encoding(v1::IMAGE_JPEG);
  for (uint32_t f = 0; f < frames; ++f) {
    const fs::path path = fs::path(dir) / tessera::jobs::FrameFileName(spec, f);
    std::error_code ec;
    const uintmax_t size = fs::file_size(path, ec);
    if (ec || size == 0)
      return absl::DataLossError(
          absl::StrCat(path.string(), ": missing or empty (", ec ? ec.message() : "0 bytes", ")"));
  }
  return absl::OkStatus();
}

// How long a CLI run may take before it is taken for hung: far beyond any sane frame time.
Clock::duration CliTimeout(uint32_t frames) {
  return std::chrono::seconds(120) + std::chrono::seconds(10) * frames;
}

// What every job command ends with: the frames, the size and where the frames go.
void AppendJobArgs(const Options& o, uint32_t frames, const std::string& out,
                   std::vector<std::string>* argv) {
  argv->insert(argv->end(), {"--frames", absl::StrCat("0..", frames - 1)});
  argv->insert(argv->end(), {"--width", absl::StrCat(o.job_width)});
  argv->insert(argv->end(), {"--height", absl::StrCat(o.job_height)});
  argv->insert(argv->end(), {"--out", out});
}

// The CLI's --servers run: `tessera --json job submit --servers ...` over `daemons`.
std::vector<std::string> FarmCommand(const Options& o, const BenchScene& scene,
                                     const std::vector<Daemon>& daemons, uint32_t frames,
                                     const std::string& out) {
  std::vector<std::string> addresses;
  for (const Daemon& d : daemons) addresses.push_back(d.address());
  std::vector<std::string> argv = {o.tessera, "--json", "job", "submit"};
  argv.insert(argv.end(), {"--servers", absl::StrJoin(addresses, ",")});
  if (scene.path.empty()) {
    argv.insert(argv.end(), {"--scene", "demo"});
  } else {
    argv.insert(argv.end(), {"--scene-file", scene.path});  // uploaded where missing
  }
  AppendJobArgs(o, frames, out, &argv);
  return argv;
}

// One --servers run: the CLI's JSON checked, the frames on disk checked.
absl::StatusOr<json> RunFarm(const Options& o, const BenchScene& scene,
                             const std::vector<Daemon>& daemons, uint32_t frames,
                             const std::string& out) {
  absl::StatusOr<std::string> text =
      RunCaptured(FarmCommand(o, scene, daemons, frames, out), CliTimeout(frames));
  if (!text.ok()) return text.status();
  const json j = json::parse(*text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object())
    return absl::InternalError("tessera job submit --servers: not JSON: " + text->substr(0, 500));
  json run;
  try {
    if (j.at("frames").get<uint32_t>() != frames)
      return absl::InternalError(
          absl::StrCat("tessera job submit --servers: ", j.at("frames").dump(), " frames written, ",
                       frames, " asked"));
    // Peers are "ipv4:127.0.0.1:PORT": the port tells the daemon.
    std::vector<uint32_t> per_daemon(daemons.size(), 0);
    for (const auto& [peer, n] : j.at("servers").items()) {
      int port = 0;
      const size_t colon = peer.rfind(':');
      if (colon == std::string::npos || !absl::SimpleAtoi(peer.substr(colon + 1), &port))
        return absl::InternalError("tessera job submit --servers: unknown peer " + peer);
      const auto it = std::find_if(daemons.begin(), daemons.end(),
                                   [&](const Daemon& d) { return d.port == port; });
      if (it == daemons.end())
        return absl::InternalError("tessera job submit --servers: a frame from " + peer +
                                   ", not one of the daemons");
      per_daemon[size_t(it - daemons.begin())] += n.get<uint32_t>();
    }
    const double seconds = j.at("seconds").get<double>();
    run = {{"seconds", seconds},
           {"seconds_per_frame", seconds / frames},
           {"frame_ms_median", j.at("frame_ms_median").get<double>()},
           {"retried", j.at("retried").get<uint32_t>()},
           {"frames_per_daemon", per_daemon}};
  } catch (const json::exception& e) {
    return absl::InternalError(absl::StrCat("tessera job submit --servers: unexpected JSON (",
                                            e.what(), "): ", text->substr(0, 500)));
  }
  if (absl::Status st = CheckFrameFiles(out, frames); !st.ok()) return st;
  return run;
}

// The baseline: the same job as a server-side job (SubmitJob) on one daemon.
absl::StatusOr<json> RunServerJob(const Options& o, const BenchScene& scene, const Daemon& d,
                                  uint32_t frames, const std::string& out) {
  std::vector<std::string> argv = {o.tessera, "--json", "--server", d.address(), "job", "submit"};
  argv.insert(argv.end(), {"--scene", scene.scene_id});
  AppendJobArgs(o, frames, out, &argv);
  double wall_s = 0.0;
  absl::StatusOr<std::string> text = RunCaptured(argv, CliTimeout(frames), &wall_s);
  if (!text.ok()) return text.status();
  const json j = json::parse(*text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object())
    return absl::InternalError("tessera job submit: not JSON: " + text->substr(0, 500));
  json run;
  try {
    const json& job = j.at("job");
    const std::string state = job.at("state").get<std::string>();
    if (state != "succeeded")
      return absl::InternalError(absl::StrCat("server-side job ", job.value("job_id", "?"),
                                              " ended ", state, ": ", job.value("error", "")));
    if (job.at("frames_done").get<uint32_t>() != frames || j.at("files").size() != frames)
      return absl::InternalError(absl::StrCat("server-side job: ", job.at("frames_done").dump(),
                                              " frames done, ", j.at("files").size(), " fetched, ",
                                              frames, " asked"));
    // The job's own span on the server, as the farm's seconds are its rendering span (neither
    // counts the upload; this one does not count the fetch either: wall_seconds does).
    const double seconds =
        job.at("finished_unix_s").get<double>() - job.at("created_unix_s").get<double>();
    run = {{"seconds", seconds},
           {"seconds_per_frame", seconds / frames},
           {"wall_seconds", wall_s},
           {"mean_frame_ms", job.at("mean_frame_ms").get<double>()}};
  } catch (const json::exception& e) {
    return absl::InternalError(absl::StrCat("tessera job submit: unexpected JSON (", e.what(),
                                            "): ", text->substr(0, 500)));
  }
  if (absl::Status st = CheckFrameFiles(out, frames); !st.ok()) return st;
  return run;
}

std::vector<double> Field(const json& runs, const char* key) {
  std::vector<double> v;
  for (const json& r : runs) v.push_back(r.at(key).get<double>());
  return v;
}

absl::StatusOr<json> RunFarmPart(const Options& o, const BenchScene& scene, json* device) {
  for (const std::string& bin : {o.tesserad, o.tessera})
    if (access(bin.c_str(), X_OK) != 0)
      return absl::NotFoundError(absl::StrCat(bin, ": not an executable (", std::strerror(errno),
                                              "); see --tesserad/--tessera"));
  // Declared before the daemons, so they are stopped before their directory goes.
  TempDir tmp("tessera-job-bench");
  if (tmp.path().empty())
    return absl::InternalError(absl::StrCat("mkdtemp: ", std::strerror(errno)));
  const uint32_t n = *std::max_element(o.daemons.begin(), o.daemons.end());
  std::fprintf(stderr, "[farm] starting %u tesserad processes\n", n);
  DaemonSet daemons;
  if (absl::Status st = daemons.Start(o.tesserad, o.device, n, tmp.path()); !st.ok())
    return Prefixed("[farm]", st);
  const std::vector<Daemon> all = daemons.daemons();
  if (device->is_null()) {
    auto stub = v1::RenderService::NewStub(NewChannel(all[0].address()));
    absl::StatusOr<v1::ServerInfo> info = GetServerInfo(stub.get());
    if (!info.ok()) return Prefixed("[farm]", info.status());
    *device = DeviceJson(*info);
  }

  // Warm-up on every daemon: the scene uploaded and its pipelines built at the job's size, so no
  // timed run pays for either. One daemon at a time: round_robin deals frames only to the
  // daemons already connected, so a run over all of them may leave one out.
  for (size_t i = 0; i < all.size(); ++i) {
    const std::string dir = absl::StrCat(tmp.path(), "/warmup", i);
    absl::StatusOr<json> warm = RunFarm(o, scene, {all[i]}, 2, dir);
    if (!warm.ok()) return Prefixed(absl::StrCat("[farm] warm-up of daemon ", i), warm.status());
    std::fprintf(stderr, "[farm] warm-up of daemon %zu (port %d): 2 frames in %.2f s\n", i,
                 all[i].port, (*warm)["seconds"].get<double>());
  }

  json server_runs = json::array();
  std::map<uint32_t, json> farm_runs;
  // Repeats interleave the configurations, so a drift of the machine touches all of them.
  for (uint32_t rep = 0; rep < o.farm_repeats; ++rep) {
    const std::string base = absl::StrCat(tmp.path(), "/rep", rep);
    absl::StatusOr<json> sj = RunServerJob(o, scene, all[0], o.frames, base + "-server");
    if (!sj.ok()) return Prefixed("[farm] server-side job", sj.status());
    std::fprintf(stderr,
                 "[farm] server-side job on 1 daemon: %u frames in %.2f s (%.0f ms/frame, %.2f s "
                 "with the fetch)\n",
                 o.frames, (*sj)["seconds"].get<double>(),
                 1000.0 * (*sj)["seconds_per_frame"].get<double>(),
                 (*sj)["wall_seconds"].get<double>());
    server_runs.push_back(*std::move(sj));
    for (uint32_t k : o.daemons) {
      const std::vector<Daemon> some(all.begin(), all.begin() + k);
      const std::string dir = absl::StrCat(base, "-farm", k);
      absl::StatusOr<json> r = RunFarm(o, scene, some, o.frames, dir);
      if (!r.ok()) return Prefixed(absl::StrCat("[farm] ", k, " daemons"), r.status());
      std::fprintf(stderr,
                   "[farm] %u daemon%s: %u frames in %.2f s (%.0f ms/frame), per daemon %s\n", k,
                   k == 1 ? "" : "s", o.frames, (*r)["seconds"].get<double>(),
                   1000.0 * (*r)["seconds_per_frame"].get<double>(),
                   (*r)["frames_per_daemon"].dump().c_str());
      farm_runs[k].push_back(*std::move(r));
      std::error_code ec;
      fs::remove_all(dir, ec);  // checked already; Sponza frames add up over the runs
    }
  }
  if (absl::Status st = daemons.Stop(); !st.ok()) return Prefixed("[farm]", st);

  const double server_spf = Median(Field(server_runs, "seconds_per_frame"));
  json out = {
      {"scene", scene.key},
      {"width", o.job_width},
      {"height", o.job_height},
      {"frames", o.frames},
      {"repeats", o.farm_repeats},
      {"cpu_cores", std::thread::hardware_concurrency()},
      {"note",
       absl::StrCat("all daemons run on this one machine and share its ",
                    std::thread::hardware_concurrency(), " CPU cores",
                    (*device)["type"] == "cpu" ? " (the Vulkan device is a CPU renderer on the "
                                                 "same cores)"
                                               : "",
                    ": these figures are the per-frame cost and the overhead of spreading a "
                    "job's frames, not the speed-up of a farm of separate machines")},
      {"server_job",
       {{"daemons", 1},
        {"seconds", Median(Field(server_runs, "seconds"))},
        {"seconds_per_frame", server_spf},
        {"wall_seconds", Median(Field(server_runs, "wall_seconds"))},
        {"mean_frame_ms", Median(Field(server_runs, "mean_frame_ms"))},
        {"runs", server_runs}}}};
  json per_count = json::array();
  std::optional<double> overhead;
  for (uint32_t k : o.daemons) {
    const json& runs = farm_runs[k];
    const double spf = Median(Field(runs, "seconds_per_frame"));
    if (k == 1 && server_spf > 0.0) overhead = spf / server_spf;
    per_count.push_back({{"daemons", k},
                         {"seconds", Median(Field(runs, "seconds"))},
                         {"seconds_per_frame", spf},
                         {"frame_ms_median", Median(Field(runs, "frame_ms_median"))},
                         {"frames_per_daemon", runs.back()["frames_per_daemon"]},
                         {"runs", runs}});
  }
  out["by_daemons"] = per_count;
  // 1-daemon farm seconds per frame / server-side job seconds per frame (null without a
  // 1-daemon run).
  out["distribution_overhead"] = OrNull(overhead);
  if (overhead)
    std::fprintf(stderr,
                 "[farm] distribution overhead (1 daemon, --servers vs server-side): %.2fx\n",
                 *overhead);
  return out;
}

// --- flags and main ------------------------------------------------------------------------

// "1,2,3" -> numbers in [min, max]; anything else is a usage error.
std::vector<uint32_t> ParseCounts(const std::string& flag, const std::string& s, uint32_t min,
                                  uint32_t max) {
  std::vector<uint32_t> out;
  for (absl::string_view part : absl::StrSplit(s, ',', absl::SkipEmpty())) {
    uint32_t v = 0;
    if (!absl::SimpleAtoi(part, &v) || v < min || v > max)
      UsageError(absl::StrCat(flag, " wants numbers in ", min, "..", max, ": ", s));
    if (std::find(out.begin(), out.end(), v) == out.end()) out.push_back(v);
  }
  if (out.empty()) UsageError(flag + " wants a list of numbers");
  return out;
}

// The default place of a sibling program in the build tree: <this binary's dir>/../`rel`.
std::string NextToThisBinary(const std::string& rel) {
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (ec) return rel;
  return (self.parent_path() / ".." / rel).lexically_normal().string();
}

bool KnownScene(const std::string& s) {
  return s == "demo" || s == "sponza" || absl::EndsWithIgnoreCase(s, ".gltf") ||
         absl::EndsWithIgnoreCase(s, ".glb");
}

Options ParseFlags(int argc, char** argv) {
  Options o;
  o.assets = AssetsDir();
  o.tesserad = NextToThisBinary("server/tesserad");
  o.tessera = NextToThisBinary("clients/cli/tessera");
  // --smoke sets small defaults first, so later flags can still change them.
  if (HasFlag(argc, argv, "--smoke")) {
    o.smoke = true;
    o.scene = "demo";
    o.viewer_width = o.job_width = 160;
    o.viewer_height = o.job_height = 90;
    o.seconds = 1.0;
    o.repeats = 1;
    o.frames = 6;
    o.daemons = {1, 2};
    o.farm_repeats = 1;
  }
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) UsageError(arg + " needs a value");
      return argv[++i];
    };
    auto number = [&](uint32_t* out, uint32_t min, uint32_t max) {
      if (!absl::SimpleAtoi(value(), out) || *out < min || *out > max)
        UsageError(absl::StrCat(arg, " wants a number in ", min, "..", max));
    };
    if (arg == "--smoke") {
      continue;
    } else if (arg == "--help" || arg == "-h") {
      std::fputs(kUsage, stdout);
      std::exit(0);
    } else if (arg == "--scene") {
      o.scene = value();
    } else if (arg == "--viewer-scene") {
      o.viewer_scene = value();
    } else if (arg == "--seconds") {
      if (!absl::SimpleAtod(value(), &o.seconds) || !(o.seconds > 0.0) || o.seconds > 3600.0)
        UsageError("--seconds wants a number in (0, 3600]");
    } else if (arg == "--repeats") {
      number(&o.repeats, 1, 100);
    } else if (arg == "--frames") {
      number(&o.frames, 1, 100000);
    } else if (arg == "--daemons") {
      o.daemons = ParseCounts(arg, value(), 1, kMaxDaemons);
    } else if (arg == "--farm-repeats") {
      number(&o.farm_repeats, 1, 100);
    } else if (arg == "--skip-viewer") {
      o.skip_viewer = true;
    } else if (arg == "--skip-farm") {
      o.skip_farm = true;
    } else if (arg == "--tesserad") {
      o.tesserad = value();
    } else if (arg == "--tessera") {
      o.tessera = value();
    } else if (arg == "--assets") {
      o.assets = value();
    } else if (arg == "--device") {
      o.device = value();
    } else {
      UsageError("unknown option " + arg);
    }
  }
  for (const std::string* s : {&o.scene, &o.viewer_scene})
    if (!KnownScene(*s))
      UsageError("unknown scene \"" + *s + "\" (demo, sponza, or a path to a .gltf/.glb)");
  if (o.skip_viewer && o.skip_farm) UsageError("--skip-viewer and --skip-farm leave nothing to do");
  return o;
}

// Everything after flag parsing; errors come back as a status (exit 1).
absl::StatusOr<json> RunBenchmark(const Options& o, const std::string& command) {
  absl::StatusOr<BenchScene> scene = ReadScene(o.scene, o.assets);
  if (!scene.ok()) return scene.status();
  json out;
  out["command"] = command;
  out["smoke"] = o.smoke;
  json device;  // from the first server that answers
  bool all_met = true;
  if (!o.skip_viewer) {
    absl::StatusOr<BenchScene> viewer_scene = o.viewer_scene == o.scene
                                                  ? absl::StatusOr<BenchScene>(*scene)
                                                  : ReadScene(o.viewer_scene, o.assets);
    if (!viewer_scene.ok()) return viewer_scene.status();
    absl::StatusOr<json> v = RunViewerPart(o, *viewer_scene, *scene, &device);
    if (!v.ok()) return v.status();
    all_met = all_met && (*v)["meets_target"].get<bool>();
    out["viewer"] = *std::move(v);
  }
  if (!o.skip_farm) {
    absl::StatusOr<json> f = RunFarmPart(o, *scene, &device);
    if (!f.ok()) return f.status();
    out["farm"] = *std::move(f);
  }
  out["device"] = device;
  out["all_targets_met"] = all_met;
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  const Options o = ParseFlags(argc, argv);
  std::vector<std::string> args(argv, argv + argc);
  absl::StatusOr<json> out = RunBenchmark(o, absl::StrJoin(args, " "));
  if (!out.ok()) {
    std::fprintf(stderr, "%s: %s\n", program_invocation_short_name,
                 std::string(out.status().message()).c_str());
    return 1;
  }
  std::printf("%s\n", out->dump(2).c_str());
  return 0;
}
