// tessera stream: a live session (Stream) for N frames, with a live per-pass timing table and
// an event-to-frame latency summary.
#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "clients/cli/cli_commands.h"
#include "clients/cli/cli_format.h"
#include "clients/cli/cli_progress.h"
#include "clients/cli/cli_render_flags.h"
#include "clients/cli/cli_session.h"
#include "clients/cli/cli_stream_parts.h"
#include "common/scene_id.h"
#include "common/status_macros.h"
#include "common/video.h"

namespace tessera::cli {
namespace {

// The session's options and where to save its frames.
struct StreamOptions : SessionOptions {
  std::string save_dir;
  std::string servers;  // --servers: replicas to place the session on (and fail over to)
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
    } else if (args.Is("--servers")) {
      o.servers = args.Value();
    } else if (args.Is("--interactive")) {
      o.interactive_scale = args.Float();
      if (!(o.interactive_scale >= 0.25f && o.interactive_scale <= 1.0f))
        args.Fail("--interactive wants a render scale in [0.25, 1]");
    } else if (args.Is("--rest-ms")) {
      o.rest_ms = static_cast<int>(args.Uint());
    } else if (ParseVideoFlag(args, &o.video)) {
    } else if (!o.flags.Parse(args)) {
      args.Unknown();
    }
  }
  o.flags.Finish(args);
  const bool video_file = absl::EndsWith(o.save_dir, ".mp4") || absl::EndsWith(o.save_dir, ".h264");
  if (video_file && o.video.codec() != v1::VIDEO_CODEC_H264)
    args.Fail(absl::StrCat("--save ", o.save_dir, ": a video file needs --codec h264"));
  if (!o.save_dir.empty() && !video_file && o.video.codec() == v1::VIDEO_CODEC_H264)
    args.Fail(absl::StrCat("--save ", o.save_dir,
                           ": with --codec h264, save to FILE.mp4 or FILE.h264 (the frames of a "
                           "video are not pictures one by one)"));
  if (o.orbit && o.flags.has_fixed_placement()) {
    args.Fail("--orbit moves the camera itself; it cannot be combined with --camera or --frame");
  }
  return o;
}

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
    absl::StrAppendFormat(&row, " %9.2f %9.2f %9s %8.1f%s %s", f.gpu_total_ms(),
                          f.cpu().total_ms(),
                          r.latency_ms ? absl::StrFormat("%.1f", *r.latency_ms) : "-",
                          r.bytes / 1024.0, f.keyframe() ? "K" : " ",
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
    absl::StrAppendFormat(&header, " %9s %9s %9s %8s  %s", "gpu ms", "cpu ms", "lat ms", "KiB",
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
    absl::PrintF("image    %ux%u %s, median %s per frame, %s in all", last.width(),
                 last.height(), s.codec, HumanBytes(static_cast<uint64_t>(s.bytes_median)),
                 HumanBytes(s.bytes_total));
    if (s.bitrate_kbps > 0) absl::PrintF(", %.2f Mbit/s", s.bitrate_kbps / 1000.0);
    if (last.encoding() == v1::VIDEO_H264)
      absl::PrintF(", %u keyframes (K), %s", s.keyframes, last.encoder());
    absl::PrintF("\n");
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
  j["latency_ms"] = LatencyJson(s);
  j["pass_median_ms"] = PassMediansJson(s);
  j["gpu_total_median_ms"] = s.gpu_total_median_ms;
  j["cpu_total_median_ms"] = s.cpu_total_median_ms;
  j["bytes_median"] = s.bytes_median;
  j["bytes_total"] = s.bytes_total;
  j["bitrate_kbps"] = s.bitrate_kbps;
  j["codec"] = s.codec;
  j["keyframes"] = s.keyframes;
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

// `tessera stream --codec h264 --save FILE.mp4|FILE.h264`: the packets into one file, each at
// its arrival time. A size change (none in a CLI session) would need a new file: refused.
class VideoSaver {
 public:
  explicit VideoSaver(std::string path) : path_(std::move(path)) {}
  bool Add(const FrameRecord& r, std::string* error) {
    const v1::Frame& f = r.frame;
    if (f.encoding() != v1::VIDEO_H264) {
      *error = absl::StrCat(path_, ": frame ", f.sequence(), " is not H.264");
      return false;
    }
    if (!writer_) {
      absl::StatusOr<std::unique_ptr<video::VideoFileWriter>> w =
          video::VideoFileWriter::Open(path_, f.width(), f.height());
      if (!w.ok()) {
        *error = std::string(w.status().message());
        return false;
      }
      writer_ = *std::move(w);
      width_ = f.width();
      height_ = f.height();
      t0_ = r.received_ms;
    }
    if (f.width() != width_ || f.height() != height_) {
      *error = absl::StrCat(path_, ": the frame size changed to ", f.width(), "x", f.height());
      return false;
    }
    absl::Status st = writer_->Write(reinterpret_cast<const uint8_t*>(f.data().data()),
                                     f.data().size(), f.keyframe(), r.received_ms - t0_);
    if (!st.ok()) *error = std::string(st.message());
    return st.ok();
  }
  bool Close(std::string* error) {
    if (!writer_) return true;
    absl::Status st = writer_->Close();
    if (!st.ok()) *error = std::string(st.message());
    return st.ok();
  }

 private:
  std::string path_;
  std::unique_ptr<video::VideoFileWriter> writer_;
  uint32_t width_ = 0, height_ = 0;
  double t0_ = 0;
};

// --servers: what one replica said when asked where to place the session.
struct ReplicaState {
  std::string address;
  grpc::Status status;  // of GetServerInfo
  v1::ServerInfo info;
  // Healthy, not shutting down, below max_sessions.
  bool ready() const { return status.ok() && info.accepting_sessions(); }
};

// The replicas of --servers: their addresses (resolved again before each placement: a
// dns:/// name's pods come and go) and the names they were found under (TLS).
struct Replicas {
  std::string servers;
  std::vector<std::string> addresses;
  std::map<std::string, std::string> host_of;
  absl::Status Resolve() {
    std::string lb_target;
    addresses.clear();
    host_of.clear();
    return ResolveServers(servers, &lb_target, &addresses, &host_of);
  }
  std::shared_ptr<grpc::Channel> Channel(const Invocation& inv, const std::string& address) const {
    const auto it = host_of.find(address);
    return MakeChannel(inv, address, false, it == host_of.end() ? "" : it->second);
  }
};

// Asks every replica (not in `exclude`) at once, within 3 s.
std::vector<ReplicaState> AskReplicas(const Invocation& inv, const Replicas& replicas,
                                      const std::set<std::string>& exclude) {
  std::vector<ReplicaState> states;
  for (const std::string& a : replicas.addresses)
    if (!exclude.count(a)) states.push_back({a, grpc::Status::OK, {}});
  std::vector<std::thread> threads;
  for (ReplicaState& r : states) {
    threads.emplace_back([&inv, &r, &replicas] {
      std::shared_ptr<grpc::Channel> channel = replicas.Channel(inv, r.address);
      if (!channel) {
        r.status = grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "TLS files");
        return;
      }
      grpc::ClientContext context;
      SetDeadline(&context, 3);
      context.set_wait_for_ready(true);  // a replica still connecting gets the 3 s
      r.status = v1::RenderService::NewStub(channel)->GetServerInfo(
          &context, v1::GetServerInfoRequest(), &r.info);
    });
  }
  for (std::thread& t : threads) t.join();
  return states;
}

// The ready replica with the fewest sessions (ties: a random one of them, so clients started
// together spread), or UNAVAILABLE saying what each replica answered.
absl::StatusOr<std::string> PlaceSession(const Invocation& inv, Replicas& replicas,
                                         const std::set<std::string>& exclude) {
  RETURN_IF_ERROR(replicas.Resolve());
  std::vector<ReplicaState> states = AskReplicas(inv, replicas, exclude);
  std::vector<const ReplicaState*> best;
  std::vector<std::string> why;
  for (const ReplicaState& r : states) {
    if (!r.ready()) {
      why.push_back(absl::StrCat(
          r.address, ": ",
          !r.status.ok() ? absl::StrCat(StatusCodeName(r.status.error_code()), " ",
                                        r.status.error_message())
          : !r.info.serving() ? absl::StrCat("NOT_SERVING (", r.info.unhealthy_reason(), ")")
          : r.info.active_sessions() >= r.info.limits().max_sessions()
              ? absl::StrCat("full (", r.info.active_sessions(), " of ",
                             r.info.limits().max_sessions(), " sessions)")
              : std::string("not taking sessions (shutting down)")));
      continue;
    }
    if (!best.empty() && r.info.active_sessions() > best[0]->info.active_sessions()) continue;
    if (!best.empty() && r.info.active_sessions() < best[0]->info.active_sessions()) best.clear();
    best.push_back(&r);
  }
  if (best.empty())
    return absl::UnavailableError(absl::StrCat(
        "--servers: no replica takes a session",
        exclude.empty() ? "" : absl::StrCat(" (", exclude.size(), " lost)"),
        why.empty() ? "" : ": ", absl::StrJoin(why, "; ")));
  std::random_device rd;
  return best[std::uniform_int_distribution<size_t>(0, best.size() - 1)(rd)]->address;
}

// A session moved to another replica after its own was lost.
struct Failover {
  std::string from, to;
  grpc::Status why;
  uint32_t frames_before = 0;
  double lost_ms = 0;                   // when the stream ended (the session's clock)
  std::optional<double> first_frame_ms;  // of the new stream, from lost_ms
};

int RunStream(const Invocation& inv) {
  const StreamOptions o = ParseStreamOptions(inv);
  const bool video_file =
      absl::EndsWith(o.save_dir, ".mp4") || absl::EndsWith(o.save_dir, ".h264");
  if (!o.save_dir.empty()) {
    // DIR for pictures, FILE's folder for a video.
    const std::filesystem::path dir =
        video_file ? std::filesystem::path(o.save_dir).parent_path()
                   : std::filesystem::path(o.save_dir);
    std::error_code ec;
    if (!dir.empty()) std::filesystem::create_directories(dir, ec);
    if (ec) {
      return ReportError(inv, absl::StrCat(o.save_dir, ": ", ec.message()),
                         ErrnoCodeName(ec.value()));
    }
  }
  // --servers: the session goes to the least loaded ready replica, and to another when its
  // replica is lost (the stream ends UNAVAILABLE) before the frames are in.
  Replicas replicas{o.servers, {}, {}};
  std::string placed;
  std::unique_ptr<v1::RenderService::Stub> stub;
  const auto connect = [&](const std::string& address) {
    std::shared_ptr<grpc::Channel> channel = replicas.Channel(inv, address);
    stub = channel ? v1::RenderService::NewStub(channel) : nullptr;
  };
  std::string scene_id = o.scene;
  if (!o.servers.empty()) {
    absl::StatusOr<std::string> address = PlaceSession(inv, replicas, {});
    if (!address.ok()) return ReportError(inv, address.status());
    placed = *address;
    // A scene id prefix names a scene some replica has loaded: the session (and any move)
    // opens with the full id, which every replica finds in the shared store.
    if (scene_id != "demo" && !IsSha256Hex(scene_id)) {
      for (const std::string& a : replicas.addresses) {
        std::shared_ptr<grpc::Channel> channel = replicas.Channel(inv, a);
        if (!channel) continue;
        std::string resolved;
        bool found = false;
        auto replica = v1::RenderService::NewStub(channel);
        if (ResolveSceneId(replica.get(), o.scene, &resolved, nullptr, &found).ok() && found) {
          scene_id = resolved;
          break;
        }
      }
    }
    connect(placed);
    absl::FPrintF(stderr, "tessera: stream: on %s\n", placed);  // stderr: --json too
  } else {
    stub = ConnectStub(inv);
  }
  if (!stub) return kExitError;

  std::optional<Orbit> orbit;
  if (o.orbit) {
    grpc::Status status = PlanOrbit(stub.get(), o, &scene_id, &orbit);
    if (!status.ok()) return ReportRpcError(inv, status);
  }

  InterruptHandler interrupt;
  // On a terminal the live table shows each frame as it comes; where it does not (--json, or
  // stdout redirected), a progress bar on stderr does.
  const bool table_on_terminal = !inv.global.json && StdoutIsTty();
  LiveTable table(StdoutIsTty());
  ProgressBar bar("stream", o.frames, ProgressBar::Unit::kCount, !table_on_terminal);
  std::string save_error;
  std::optional<VideoSaver> saver;
  if (video_file) saver.emplace(o.save_dir);
  Session session(o, [&](const FrameRecord& r, uint32_t index) {
    if (saver && save_error.empty()) {
      saver->Add(r, &save_error);
    } else if (!o.save_dir.empty() && save_error.empty()) {
      SaveFrame(o.save_dir, index, r.frame, &save_error);
    }
    if (!inv.global.json) table.Add(r, index);
    bar.Update(index);
  });
  grpc::Status status = session.Run(stub.get(), scene_id, orbit);
  std::vector<Failover> failovers;
  std::set<std::string> lost;
  std::string current = placed;
  while (!o.servers.empty() && status.error_code() == grpc::StatusCode::UNAVAILABLE &&
         session.records().size() < o.frames && !InterruptHandler::interrupted() &&
         failovers.size() < 3) {
    Failover f{current, "", status, static_cast<uint32_t>(session.records().size()),
               session.ElapsedMs(), std::nullopt};
    lost.insert(current);
    absl::StatusOr<std::string> next = PlaceSession(inv, replicas, lost);
    if (!next.ok()) {
      absl::FPrintF(stderr, "\ntessera: stream: %s lost (%s); %s\n", current,
                    status.error_message(), next.status().message());
      failovers.push_back(std::move(f));  // "to": null
      break;
    }
    current = f.to = *next;
    connect(current);
    if (!stub) break;
    absl::FPrintF(stderr, "\ntessera: stream: %s lost (%s); reopened on %s\n", f.from,
                  status.error_message(), f.to);
    status = session.Run(stub.get(), scene_id, orbit);
    if (session.records().size() > f.frames_before)
      f.first_frame_ms = session.records()[f.frames_before].received_ms - f.lost_ms;
    failovers.push_back(std::move(f));
  }
  if (saver && save_error.empty()) saver->Close(&save_error);
  bar.Clear();
  table.End();

  Summary summary = Summarize(session.records(), session.latencies());
  summary.extra_frames = session.extra_frames();
  const bool have_frames = !session.records().empty();
  if (have_frames && !inv.global.json) {
    PrintSummary(summary, session.records());
    for (const Failover& f : failovers)
      absl::PrintF("failover %s lost after %u frames; %s\n", f.from, f.frames_before,
                   f.to.empty() ? std::string("no replica to move to")
                                : absl::StrCat(f.to, ": first frame ",
                                               f.first_frame_ms
                                                   ? absl::StrFormat("%.0f ms", *f.first_frame_ms)
                                                   : std::string("none"),
                                               " after"));
    if (!o.save_dir.empty() && save_error.empty()) {
      absl::PrintF("saved    %u frames to %s%s\n", summary.frames, o.save_dir,
                   video_file ? "" : "/");
    }
  }
  // The summary covers the frames that came; the error says why no more did (and is part of
  // the --json document).
  int rc = 0;
  if (!save_error.empty()) {
    rc = ReportError(inv, save_error);
  } else if (InterruptHandler::interrupted()) {
    ReportError(inv, absl::StrCat("interrupted after ", summary.frames, " frames"), "CANCELLED");
    rc = kExitInterrupted;
  } else if (!status.ok()) {
    rc = ReportRpcError(inv, status);
  } else if (summary.frames < o.frames) {
    rc = ReportError(inv, absl::StrCat("the server ended the stream after ", summary.frames, " of ",
                                       o.frames, " frames"));
  }
  if (have_frames && inv.global.json) {
    Json j = SummaryJson(summary, session.records(), scene_id);
    if (!o.servers.empty()) {
      j["server"] = placed;
      Json list = Json::array();
      for (const Failover& f : failovers)
        list.push_back({{"from", f.from},
                        {"to", f.to.empty() ? Json(nullptr) : Json(f.to)},
                        {"error", ErrorJson(f.why)},
                        {"frames_before", f.frames_before},
                        {"first_frame_ms", f.first_frame_ms ? Json(*f.first_frame_ms) : nullptr}});
      j["failovers"] = std::move(list);
    }
    if (rc != 0) j["error"] = FirstError();
    PrintJson(j);
  }
  return rc;
}

}  // namespace

const Command kStreamCommand = {
    "stream", "a live session for N frames: per-pass timings and input-to-frame latency",
    R"(usage: tessera stream [--scene ID] [--frames N] [--orbit] [--fps F] [--save DIR|FILE]
                      [--interactive S [--rest-ms MS]] [--codec jpeg|h264 [video flags]]
                      [--servers LIST] [flags]
Opens a live session (Stream) and receives N frames, printing each frame's sequence number,
the event it reflects, the GPU time of every pass, totals, latency and size (redrawn in place
on a terminal), then a summary: fps, event-to-frame latency (median, p95: from sending an
event to the first frame reflecting it) and the median time of every pass. With --json, or
stdout not a terminal, a progress bar on stderr (when that is a terminal) shows the frames.
--json: the summary and every frame (without its image) as one JSON document; when the
stream ended early, the frames that came and "error": {"code", "message"}.
Exit status 130 after Ctrl-C (the summary of the frames so far is printed first).
  --scene ID          a scene id (or a unique prefix of 8+ characters) or "demo" (the default)
  --frames N          frames to receive (default 10)
  --orbit             circle the camera around the scene's bounds centre (or --target): one
                      camera move per received frame, one full turn in N moves
  --fps F             with --orbit: move the camera F times a second instead of once per frame;
                      without: the server renders continuously at up to F fps
                      (neither: one refresh event per received frame; with --play alone,
                      none: the server renders the playing animation at up to 30 fps)
  --save DIR          write the frames to DIR/frame_000001.jpg, ...
  --save FILE         with --codec h264: FILE.mp4 (MP4, each frame at its arrival time) or
                      FILE.h264 (the raw Annex B stream)
  --interactive S     idle refinement: while the camera moves, frames are rendered at scale S
                      (0.25..1), upscaled and sent at a lower JPEG quality (h264: at
                      --interactive-crf); once it rests, one
                      full-quality frame follows (the "profile" column says which)
  --rest-ms MS        with --interactive: how long the camera must rest (server default 250)
  --servers LIST      replicas, HOST:PORT,HOST:PORT or dns:///NAME:PORT (a headless Service):
                      the session opens on the ready one with the fewest sessions, and when
                      that replica is lost (the stream ends UNAVAILABLE) it reopens on another
                      with the same scene, camera and settings (up to 3 times; the scene must
                      be in a store the replicas share, --scene_store_dir)
)" TESSERA_VIDEO_FLAGS_USAGE,
    /*render_flags=*/true, RunStream};

}  // namespace tessera::cli
