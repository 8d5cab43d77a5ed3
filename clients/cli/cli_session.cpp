#include "clients/cli/cli_session.h"

#include <map>
#include <mutex>

#include "absl/strings/str_cat.h"

namespace tessera::cli {

namespace {

bool HasCameraFlags(const RenderFlags& f) {
  const v1::Camera& c = f.camera();
  return f.has_placement() || f.has_look_at() || c.has_yfov() || c.has_znear() || c.has_zfar();
}

}  // namespace

// Makes the events of the session: the open event, then orbit moves or refreshes with
// increasing ids. Called from the writer thread and (OnFrame) the reader, hence the lock.
class Session::Events {
 public:
  // A session continued on another server (failover) goes on from `next_id` and `step`.
  Events(const SessionOptions& o, std::string scene_id, std::optional<Orbit> orbit,
         uint64_t next_id, uint64_t step)
      : options_(o), scene_id_(std::move(scene_id)), orbit_(orbit), next_id_(next_id),
        step_(step) {}

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
    if (options_.video.ByteSizeLong() > 0) *open->mutable_video() = options_.video;
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

  // Where a continuation starts.
  uint64_t next_id() {
    std::lock_guard<std::mutex> lock(mu_);
    return next_id_;
  }
  uint64_t step() {
    std::lock_guard<std::mutex> lock(mu_);
    return step_;
  }
  std::optional<Orbit> orbit() {
    std::lock_guard<std::mutex> lock(mu_);
    return orbit_;
  }

 private:
  const SessionOptions& options_;
  const std::string scene_id_;
  std::mutex mu_;
  std::optional<Orbit> orbit_;
  uint64_t next_id_ = 1;
  uint64_t step_ = 0;
};

grpc::Status Session::Run(v1::RenderService::Stub* stub, const std::string& scene_id,
                          std::optional<Orbit> orbit) {
  // Run again after a server was lost: the same session goes on (event ids, orbit, frame
  // count and clock), opened anew.
  const bool continued = runs_++ > 0;
  Events events(o_, scene_id, continued ? orbit_ : orbit, next_event_id_, step_);
  grpc::ClientContext context;
  std::unique_ptr<grpc::ClientReaderWriter<v1::ClientEvent, v1::Frame>> stream =
      stub->Stream(&context);
  std::optional<std::chrono::duration<double>> period;
  if (o_.pacing() == Pacing::kSteadyRate) period = std::chrono::duration<double>(1.0 / o_.fps);
  EventWriter writer(
      &context, stream.get(), &latency_, [&events] { return events.Next(); }, period);
  if (!continued) start_ = Clock::now();
  if (writer.WriteNow(events.Open())) {
    writer.Start();
    ReadFrames(stream.get(), &writer, &events);
  }
  writer.Close();
  v1::Frame extra;
  while (stream->Read(&extra)) ++extra_frames_;
  writer.Join();
  next_event_id_ = events.next_id();
  step_ = events.step();
  orbit_ = events.orbit();
  return stream->Finish();
}

double Session::ElapsedMs() const {
  return std::chrono::duration<double, std::milli>(Clock::now() - start_).count();
}

void Session::ReadFrames(grpc::ClientReaderWriter<v1::ClientEvent, v1::Frame>* stream,
                         EventWriter* writer, Events* events) {
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
    r.bytes = frame.data().size();
    r.frame = std::move(frame);
    if (on_frame_) on_frame_(r, index);
    r.frame.clear_data();  // N frames of pixels would only cost memory
    records_.push_back(std::move(r));
  }
}

bool ParseVideoFlag(ArgReader& args, v1::VideoSettings* video) {
  if (args.Is("--codec")) {
    const std::string c = args.Value();
    if (c == "jpeg") {
      video->set_codec(v1::VIDEO_CODEC_JPEG);
    } else if (c == "h264") {
      video->set_codec(v1::VIDEO_CODEC_H264);
    } else {
      args.Fail(absl::StrCat("--codec '", c, "': use jpeg or h264"));
    }
  } else if (args.Is("--crf")) {
    video->set_crf(args.Uint());
  } else if (args.Is("--interactive-crf")) {
    video->set_interactive_crf(args.Uint());
  } else if (args.Is("--preset")) {
    video->set_preset(args.Value());
  } else if (args.Is("--keyframe-interval")) {
    video->set_keyframe_interval(args.Uint());
  } else if (args.Is("--max-bitrate")) {
    video->set_max_bitrate_kbps(args.Uint());
  } else if (args.Is("--encoder")) {
    const std::string e = args.Value();
    if (e == "auto") {
      video->set_encoder(v1::VIDEO_ENCODER_AUTO);
    } else if (e == "software") {
      video->set_encoder(v1::VIDEO_ENCODER_SOFTWARE);
    } else if (e == "hardware") {
      video->set_encoder(v1::VIDEO_ENCODER_HARDWARE);
    } else {
      args.Fail(absl::StrCat("--encoder '", e, "': use auto, software or hardware"));
    }
  } else {
    return false;
  }
  return true;
}

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
  // Between the first and the last frame (the first one's bytes arrived at its start).
  const double span_s = (records.back().received_ms - records.front().received_ms) / 1000.0;
  const auto per_second = [&](double v) { return records.size() >= 2 && span_s > 0 ? v / span_s : 0.0; };
  s.fps = per_second(double(records.size() - 1));
  // Sequence numbers never received; a number that does not increase starts a new stream (a
  // session reopened on another server after its own was lost).
  for (size_t i = 1; i < records.size(); ++i) {
    const uint64_t prev = records[i - 1].frame.sequence(), seq = records[i].frame.sequence();
    if (seq > prev) s.dropped += seq - prev - 1;
  }

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
    s.bytes_total += r.bytes;
    if (r.frame.keyframe()) ++s.keyframes;
  }
  for (const std::string& name : order) {
    s.pass_median_ms.emplace_back(name, Median(per_pass[name]));
    s.pass_p10_p90_ms.emplace_back(Percentile(per_pass[name], 10), Percentile(per_pass[name], 90));
  }
  s.gpu_total_median_ms = Median(gpu);
  s.gpu_total_p10_ms = Percentile(gpu, 10);
  s.gpu_total_p90_ms = Percentile(gpu, 90);
  s.cpu_total_median_ms = Median(cpu);
  s.bytes_median = Median(bytes);
  s.bitrate_kbps = per_second((s.bytes_total - records.front().bytes) * 8.0 / 1000.0);
  const v1::Frame& last = records.back().frame;
  s.codec = last.encoding() == v1::VIDEO_H264 ? last.codec()
            : last.encoding() == v1::IMAGE_PNG ? "png"
                                                : "jpeg";
  return s;
}

Json LatencyJson(const Summary& s) {
  return {{"median", Median(s.latencies_ms)},
          {"p95", Percentile(s.latencies_ms, 95)},
          {"events", s.latencies_ms.size()},
          {"samples", s.latencies_ms}};
}

Json PassMediansJson(const Summary& s) {
  Json passes = Json::array();
  for (size_t i = 0; i < s.pass_median_ms.size(); ++i) {
    const auto& [name, ms] = s.pass_median_ms[i];
    const auto [p10, p90] =
        i < s.pass_p10_p90_ms.size() ? s.pass_p10_p90_ms[i] : std::pair<double, double>{ms, ms};
    passes.push_back({{"pass", name}, {"median_ms", ms}, {"p10_ms", p10}, {"p90_ms", p90}});
  }
  return passes;
}

grpc::Status PlanOrbit(v1::RenderService::Stub* stub, const SessionOptions& o,
                       std::string* scene_id, std::optional<Orbit>* orbit) {
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

}  // namespace tessera::cli
