// tessera stream: a live session (Stream) for N frames, with a live per-pass timing table and
// an event-to-frame latency summary.
#include <cstdio>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "clients/cli/cli_commands.h"
#include "clients/cli/cli_format.h"
#include "clients/cli/cli_render_flags.h"
#include "clients/cli/cli_stream_parts.h"

namespace tessera::cli {
namespace {

// How the CLI asks for frames.
enum class Pacing {
  kPerFrame,    // one event (camera move or refresh) per received frame
  kSteadyRate,  // --orbit --fps F: a camera move every 1/F s, whatever the frames do
  kServerRate,  // --fps F alone: the session renders continuously at F fps
};

struct StreamOptions {
  std::string scene = "demo";
  uint32_t frames = 10;
  bool orbit = false;
  float fps = 0;
  std::string save_dir;
  float interactive_scale = 0;  // > 0: enable the session's interactive profile at this scale
  int rest_ms = -1;             // the profile's rest time; -1: the server's default
  RenderFlags flags;

  Pacing pacing() const {
    if (fps <= 0) return Pacing::kPerFrame;
    return orbit ? Pacing::kSteadyRate : Pacing::kServerRate;
  }
};

StreamOptions ParseStreamOptions(const Invocation& inv) {
  StreamOptions o;
  ArgReader args(inv);
  while (args.Next()) {
    if (args.Is("--scene")) {
      o.scene = args.Value();
    } else if (args.Is("--frames")) {
      o.frames = args.Uint();
      if (o.frames == 0) args.Fail("--frames wants at least 1");
    } else if (args.Is("--orbit")) {
      o.orbit = true;
    } else if (args.Is("--fps")) {
      o.fps = args.Float();
      if (!(o.fps > 0 && o.fps <= 240)) args.Fail("--fps wants a rate in (0, 240]");
    } else if (args.Is("--save")) {
      o.save_dir = args.Value();
    } else if (args.Is("--interactive")) {
      o.interactive_scale = args.Float();
      if (!(o.interactive_scale >= 0.25f && o.interactive_scale <= 1.0f))
        args.Fail("--interactive wants a render scale in [0.25, 1]");
    } else if (args.Is("--rest-ms")) {
      o.rest_ms = static_cast<int>(args.Uint());
    } else if (!o.flags.Parse(args)) {
      args.Unknown();
    }
  }
  o.flags.Finish(args);
  if (o.orbit && o.flags.has_placement()) {
    args.Fail("--orbit moves the camera itself; it cannot be combined with --camera or --frame");
  }
  return o;
}

bool HasCameraFlags(const RenderFlags& f) {
  const v1::Camera& c = f.camera();
  return f.has_placement() || f.has_look_at() || c.has_yfov() || c.has_znear() || c.has_zfar();
}

// Makes the events of the session: the open event, then orbit moves or refreshes with
// increasing ids. Called from the writer thread and (OnFrame) the reader, hence the lock.
class StreamEvents {
 public:
  StreamEvents(const StreamOptions& o, std::string scene_id, std::optional<Orbit> orbit)
      : options_(o), scene_id_(std::move(scene_id)), orbit_(orbit) {}

  v1::ClientEvent Open() {
    std::lock_guard<std::mutex> lock(mu_);
    v1::ClientEvent event;
    event.set_event_id(next_id_++);
    v1::OpenSession* open = event.mutable_open();
    open->set_scene_id(scene_id_);
    *open->mutable_settings() = options_.flags.settings();
    if (options_.pacing() == Pacing::kServerRate) open->set_target_fps(options_.fps);
    if (options_.interactive_scale > 0) {
      open->mutable_interactive()->set_enabled(true);
      open->mutable_interactive()->set_render_scale(options_.interactive_scale);
      if (options_.rest_ms >= 0) open->mutable_interactive()->set_rest_ms(options_.rest_ms);
    }
    if (options_.orbit && orbit_) {
      *open->mutable_camera() = orbit_->CameraAt(step_++, options_.frames, options_.flags.camera());
    } else if (HasCameraFlags(options_.flags)) {
      *open->mutable_camera() = options_.flags.camera();
    }
    return event;
  }

  std::optional<v1::ClientEvent> Next() {
    std::lock_guard<std::mutex> lock(mu_);
    v1::ClientEvent event;
    if (options_.orbit) {
      if (!orbit_) return std::nullopt;  // waiting for the first frame's camera
      *event.mutable_camera() = orbit_->CameraAt(step_++, options_.frames, options_.flags.camera());
    } else {
      event.set_refresh(true);
    }
    event.set_event_id(next_id_++);
    return event;
  }

  // Without known bounds (a scene HasScene could not describe), orbit around what the server
  // framed for the first frame.
  void OnFrame(const v1::Frame& frame) {
    std::lock_guard<std::mutex> lock(mu_);
    if (options_.orbit && !orbit_ && frame.has_camera()) {
      orbit_ = Orbit::FromLookAt(frame.camera());
      step_ = 1;
    }
  }

 private:
  const StreamOptions& options_;
  const std::string scene_id_;
  std::mutex mu_;
  std::optional<Orbit> orbit_;
  uint64_t next_id_ = 1;
  uint64_t step_ = 0;
};

// One received frame, without its image.
struct FrameRecord {
  v1::Frame frame;
  uint64_t bytes = 0;                // of the encoded image (not kept)
  double received_ms = 0;            // since the open event was sent
  std::optional<double> latency_ms;  // of the newest event this frame answered first
};

// The per-frame table. On a terminal the current row is redrawn in place; otherwise every
// frame gets its own line (logs, pipes).
class LiveTable {
 public:
  explicit LiveTable(bool in_place) : in_place_(in_place) {}

  void Add(const FrameRecord& r, uint32_t index) {
    const v1::Frame& f = r.frame;
    if (!SamePasses(f)) PrintHeader(f);
    std::string row = absl::StrFormat("%5u %7u %7u", index, f.sequence(), f.event_id());
    for (int i = 0; i < f.passes_size(); ++i) {
      absl::StrAppendFormat(&row, " %*.2f", widths_[i], f.passes(i).gpu_ms());
    }
    absl::StrAppendFormat(&row, " %9.2f %9.2f %9s %8.1f %s", f.gpu_total_ms(),
                          f.cpu().total_ms(),
                          r.latency_ms ? absl::StrFormat("%.1f", *r.latency_ms) : "-",
                          r.bytes / 1024.0,
                          f.profile() == "interactive"
                              ? absl::StrFormat("interactive %ux%u", f.render_width(),
                                                f.render_height())
                              : f.profile());
    if (in_place_) {
      std::printf("\r\033[K%s", row.c_str());
      line_open_ = true;
    } else {
      std::printf("%s\n", row.c_str());
    }
    std::fflush(stdout);
  }

  void End() {
    if (line_open_) std::printf("\n");
    line_open_ = false;
  }

 private:
  bool SamePasses(const v1::Frame& f) const {
    if (!header_printed_ || static_cast<size_t>(f.passes_size()) != passes_.size()) return false;
    for (int i = 0; i < f.passes_size(); ++i) {
      if (f.passes(i).pass() != passes_[i]) return false;
    }
    return true;
  }

  void PrintHeader(const v1::Frame& f) {
    End();
    passes_.clear();
    widths_.clear();
    std::string header = absl::StrFormat("%5s %7s %7s", "#", "seq", "event");
    for (const v1::PassTiming& p : f.passes()) {
      passes_.push_back(p.pass());
      widths_.push_back(std::max<int>(7, p.pass().size()));
      absl::StrAppendFormat(&header, " %*s", widths_.back(), p.pass());
    }
    absl::StrAppendFormat(&header, " %9s %9s %9s %8s %s", "gpu ms", "cpu ms", "lat ms", "KiB",
                          "profile");
    std::printf("%s\n", header.c_str());
    header_printed_ = true;
  }

  bool in_place_;
  bool header_printed_ = false;
  bool line_open_ = false;
  std::vector<std::string> passes_;
  std::vector<int> widths_;
};

// What the summary reports, computed once from the records.
struct Summary {
  uint32_t frames = 0;
  uint32_t extra_frames = 0;  // arrived after the half-close, not counted
  double seconds = 0;         // open event sent -> last frame received
  double fps = 0;             // between the first and the last frame
  uint64_t dropped = 0;       // sequence numbers never received
  std::optional<double> first_frame_ms;
  std::vector<double> latencies_ms;                            // events after the open event
  std::vector<std::pair<std::string, double>> pass_median_ms;  // in pass order
  double gpu_total_median_ms = 0;
  double cpu_total_median_ms = 0;
  double bytes_median = 0;
};

Summary Summarize(const std::vector<FrameRecord>& records,
                  const std::vector<std::pair<uint64_t, double>>& latencies) {
  Summary s;
  s.frames = records.size();
  for (const auto& [id, ms] : latencies) {
    if (id == 1) {
      s.first_frame_ms = ms;  // includes opening the session: reported on its own
    } else {
      s.latencies_ms.push_back(ms);
    }
  }
  if (records.empty()) return s;
  s.seconds = records.back().received_ms / 1000.0;
  if (records.size() >= 2) {
    const double span_s = (records.back().received_ms - records.front().received_ms) / 1000.0;
    if (span_s > 0) s.fps = (records.size() - 1) / span_s;
  }
  const uint64_t span = records.back().frame.sequence() - records.front().frame.sequence() + 1;
  s.dropped = span > records.size() ? span - records.size() : 0;

  std::vector<std::string> order;
  std::map<std::string, std::vector<double>> per_pass;
  std::vector<double> gpu, cpu, bytes;
  for (const FrameRecord& r : records) {
    for (const v1::PassTiming& p : r.frame.passes()) {
      if (!per_pass.count(p.pass())) order.push_back(p.pass());
      per_pass[p.pass()].push_back(p.gpu_ms());
    }
    gpu.push_back(r.frame.gpu_total_ms());
    cpu.push_back(r.frame.cpu().total_ms());
    bytes.push_back(r.bytes);
  }
  for (const std::string& name : order) s.pass_median_ms.emplace_back(name, Median(per_pass[name]));
  s.gpu_total_median_ms = Median(gpu);
  s.cpu_total_median_ms = Median(cpu);
  s.bytes_median = Median(bytes);
  return s;
}

void PrintSummary(const Summary& s, const std::vector<FrameRecord>& records) {
  absl::PrintF("\nframes   %u in %.2f s", s.frames, s.seconds);
  if (s.fps > 0) absl::PrintF(", %.1f fps", s.fps);
  absl::PrintF(", %u dropped", s.dropped);
  if (s.extra_frames) absl::PrintF(", %u more after the half-close", s.extra_frames);
  absl::PrintF("\n");
  if (s.first_frame_ms)
    absl::PrintF("first    %.1f ms from opening to the first frame\n", *s.first_frame_ms);
  if (!s.latencies_ms.empty()) {
    absl::PrintF("latency  event -> frame: median %.1f ms, p95 %.1f ms (%u events)\n",
                 Median(s.latencies_ms), Percentile(s.latencies_ms, 95), s.latencies_ms.size());
  }
  if (!records.empty()) {
    const v1::Frame& last = records.back().frame;
    absl::PrintF("image    %ux%u, median %s per frame\n", last.width(), last.height(),
                 HumanBytes(static_cast<uint64_t>(s.bytes_median)));
    absl::PrintF("settings %s\n", WrapList(SettingsSummary(last.settings()), 9));
  }
  absl::PrintF("\n%-20s %10s\n", "pass", "median ms");
  for (const auto& [name, ms] : s.pass_median_ms) absl::PrintF("%-20s %10.3f\n", name, ms);
  absl::PrintF("%-20s %10.3f\n%-20s %10.3f\n", "gpu total", s.gpu_total_median_ms, "cpu total",
               s.cpu_total_median_ms);
  // Notes are the same for every frame of a session with fixed settings: show the last ones.
  if (!records.empty()) {
    for (const v1::SettingNote& n : records.back().frame.notes()) {
      absl::PrintF("note: %s: %s\n", n.field(), n.message());
    }
  }
}

Json SummaryJson(const Summary& s, const std::vector<FrameRecord>& records,
                 const std::string& scene_id) {
  Json j;
  j["scene_id"] = scene_id;
  j["frames"] = s.frames;
  j["extra_frames"] = s.extra_frames;
  j["seconds"] = s.seconds;
  j["fps"] = s.fps;
  j["dropped"] = s.dropped;
  j["first_frame_ms"] = s.first_frame_ms ? Json(*s.first_frame_ms) : nullptr;
  j["latency_ms"] = {{"median", Median(s.latencies_ms)},
                     {"p95", Percentile(s.latencies_ms, 95)},
                     {"events", s.latencies_ms.size()},
                     {"samples", s.latencies_ms}};
  Json passes = Json::array();
  for (const auto& [name, ms] : s.pass_median_ms)
    passes.push_back({{"pass", name}, {"median_ms", ms}});
  j["pass_median_ms"] = passes;
  j["gpu_total_median_ms"] = s.gpu_total_median_ms;
  j["cpu_total_median_ms"] = s.cpu_total_median_ms;
  j["bytes_median"] = s.bytes_median;
  Json frames = Json::array();
  for (const FrameRecord& r : records) {
    Json f = FrameJson(r.frame);
    f.erase("session_token");  // it resumes (takes over) the session: not for logs
    f["bytes"] = r.bytes;
    f["received_ms"] = r.received_ms;
    f["latency_ms"] = r.latency_ms ? Json(*r.latency_ms) : nullptr;
    frames.push_back(std::move(f));
  }
  j["frame_list"] = std::move(frames);
  return j;
}

bool SaveFrame(const std::string& dir, uint32_t index, const v1::Frame& frame, std::string* error) {
  const std::string path = absl::StrFormat("%s/frame_%06u.%s", dir, index,
                                           frame.encoding() == v1::IMAGE_PNG ? "png" : "jpg");
  FILE* f = std::fopen(path.c_str(), "wb");
  const bool ok =
      f && std::fwrite(frame.data().data(), 1, frame.data().size(), f) == frame.data().size();
  if ((f && std::fclose(f) != 0) || !ok) {
    *error = absl::StrCat(path, ": cannot write");
    return false;
  }
  return true;
}

// The orbit path when --orbit is given: around the scene bounds (HasScene), or through the
// explicit --eye/--target. nullopt when the scene could not be described (the first frame's
// camera is used then). Also resolves a scene id prefix.
grpc::Status PlanOrbit(v1::RenderService::Stub* stub, const StreamOptions& o, std::string* scene_id,
                       std::optional<Orbit>* orbit) {
  if (o.flags.has_look_at()) {
    *orbit = Orbit::FromLookAt(o.flags.camera().look_at());
    return grpc::Status::OK;
  }
  v1::SceneInfo info;
  bool found = false;
  grpc::Status status = ResolveSceneId(stub, o.scene, scene_id, &info, &found);
  if (!status.ok() || !found || !info.has_bounds()) return status;
  const v1::RenderSettings& s = o.flags.settings();
  const float width = s.has_width() ? s.width() : 1280.0f;  // the server's defaults
  const float height = s.has_height() ? s.height() : 720.0f;
  const v1::Camera& c = o.flags.camera();
  *orbit = Orbit::FromBounds(info.bounds(), c.has_yfov() ? c.yfov() : 0.8f,
                             height > 0 ? width / height : 1.0f);
  return grpc::Status::OK;
}

// The session from open to Finish. Fills `records` and `latencies`; returns the call's status.
class Session {
 public:
  Session(const Invocation& inv, const StreamOptions& o) : inv_(inv), o_(o) {}

  grpc::Status Run(v1::RenderService::Stub* stub, const std::string& scene_id,
                   std::optional<Orbit> orbit) {
    StreamEvents events(o_, scene_id, orbit);
    grpc::ClientContext context;
    std::unique_ptr<grpc::ClientReaderWriter<v1::ClientEvent, v1::Frame>> stream =
        stub->Stream(&context);
    std::optional<std::chrono::duration<double>> period;
    if (o_.pacing() == Pacing::kSteadyRate) period = std::chrono::duration<double>(1.0 / o_.fps);
    EventWriter writer(
        &context, stream.get(), &latency_, [&events] { return events.Next(); }, period);
    LiveTable table(StdoutIsTty());
    start_ = Clock::now();
    if (writer.WriteNow(events.Open())) {
      writer.Start();
      ReadFrames(stream.get(), &writer, &events, &table);
    }
    table.End();
    writer.Close();
    v1::Frame extra;
    while (stream->Read(&extra)) ++extra_frames_;
    writer.Join();
    return stream->Finish();
  }

  const std::vector<FrameRecord>& records() const { return records_; }
  const std::vector<std::pair<uint64_t, double>>& latencies() const { return latencies_; }
  uint32_t extra_frames() const { return extra_frames_; }
  const std::string& save_error() const { return save_error_; }

 private:
  void ReadFrames(grpc::ClientReaderWriter<v1::ClientEvent, v1::Frame>* stream, EventWriter* writer,
                  StreamEvents* events, LiveTable* table) {
    v1::Frame frame;
    while (records_.size() < o_.frames && stream->Read(&frame)) {
      const Clock::time_point now = Clock::now();
      events->OnFrame(frame);
      const uint32_t index = records_.size() + 1;
      // Ask for the next frame before anything slow (printing, saving) happens.
      if (o_.pacing() == Pacing::kPerFrame && index < o_.frames) writer->RequestEvent();

      FrameRecord r;
      r.received_ms = std::chrono::duration<double, std::milli>(now - start_).count();
      for (const auto& answered : latency_.Answered(frame.event_id(), now)) {
        latencies_.push_back(answered);
        r.latency_ms = answered.second;
      }
      if (!o_.save_dir.empty() && save_error_.empty()) {
        SaveFrame(o_.save_dir, index, frame, &save_error_);
      }
      r.bytes = frame.data().size();
      r.frame = std::move(frame);
      r.frame.clear_data();  // N frames of pixels would only cost memory
      if (!inv_.global.json) table->Add(r, index);
      records_.push_back(std::move(r));
    }
  }

  const Invocation& inv_;
  const StreamOptions& o_;
  LatencyTracker latency_;
  Clock::time_point start_;
  std::vector<FrameRecord> records_;
  std::vector<std::pair<uint64_t, double>> latencies_;
  uint32_t extra_frames_ = 0;
  std::string save_error_;
};

int RunStream(const Invocation& inv) {
  const StreamOptions o = ParseStreamOptions(inv);
  if (!o.save_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(o.save_dir, ec);
    if (ec) return ReportError(inv, absl::StrCat(o.save_dir, ": ", ec.message()));
  }
  auto stub = ConnectStub(inv);
  if (!stub) return kExitError;

  std::string scene_id = o.scene;
  std::optional<Orbit> orbit;
  if (o.orbit) {
    grpc::Status status = PlanOrbit(stub.get(), o, &scene_id, &orbit);
    if (!status.ok()) return ReportRpcError(inv, status);
  }

  InterruptHandler interrupt;
  Session session(inv, o);
  const grpc::Status status = session.Run(stub.get(), scene_id, orbit);

  Summary summary = Summarize(session.records(), session.latencies());
  summary.extra_frames = session.extra_frames();
  if (!session.records().empty()) {
    if (inv.global.json) {
      PrintJson(SummaryJson(summary, session.records(), scene_id));
    } else {
      PrintSummary(summary, session.records());
      if (!o.save_dir.empty() && session.save_error().empty()) {
        absl::PrintF("saved    %u frames to %s/\n", summary.frames, o.save_dir);
      }
    }
  }
  if (!session.save_error().empty()) return ReportError(inv, session.save_error());
  if (InterruptHandler::interrupted()) {
    ReportError(inv, absl::StrCat("interrupted after ", summary.frames, " frames"));
    return 130;
  }
  if (!status.ok()) return ReportRpcError(inv, status);
  if (summary.frames < o.frames) {
    return ReportError(inv, absl::StrCat("the server ended the stream after ", summary.frames,
                                         " of ", o.frames, " frames"));
  }
  return 0;
}

}  // namespace

const Command kStreamCommand = {
    "stream", "a live session for N frames: per-pass timings and input-to-frame latency",
    R"(usage: tessera stream [--scene ID] [--frames N] [--orbit] [--fps F] [--save DIR]
                      [--interactive S [--rest-ms MS]] [flags]
Opens a live session (Stream) and receives N frames, printing each frame's sequence number,
the event it reflects, the GPU time of every pass, totals, latency and size (redrawn in place
on a terminal), then a summary: fps, event-to-frame latency (median, p95: from sending an
event to the first frame reflecting it) and the median time of every pass.
--json: the summary and every frame (without its image) as one JSON document.
  --scene ID          a scene id (or a unique prefix of 8+ characters) or "demo" (the default)
  --frames N          frames to receive (default 10)
  --orbit             circle the camera around the scene's bounds centre (or --target): one
                      camera move per received frame, one full turn in N moves
  --fps F             with --orbit: move the camera F times a second instead of once per frame;
                      without: the server renders continuously at up to F fps
                      (neither: one refresh event per received frame)
  --save DIR          write the frames to DIR/frame_000001.jpg, ...
  --interactive S     idle refinement: while the camera moves, frames are rendered at scale S
                      (0.25..1), upscaled and sent at a lower JPEG quality; once it rests, one
                      full-quality frame follows (the "profile" column says which)
  --rest-ms MS        with --interactive: how long the camera must rest (server default 250)
)",
    /*render_flags=*/true, RunStream};

}  // namespace tessera::cli
