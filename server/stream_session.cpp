#include "server/stream_session.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "absl/strings/str_cat.h"
#include "common/status_macros.h"
#include "renderer/image_io.h"
#include "renderer/log.h"
#include "server/convert.h"
#include "server/metrics.h"

namespace tessera::server {
namespace {

constexpr float kMaxTargetFps = 240.0f;

absl::Status CheckTargetFps(float fps, const char* field) {
  if (!std::isfinite(fps) || fps < 0.0f || fps > kMaxTargetFps)
    return absl::InvalidArgumentError(
        absl::StrCat(field, ": ", fps, " is out of range (0..", kMaxTargetFps, ")"));
  return absl::OkStatus();
}

Clock::duration MinInterval(float max_session_fps) {
  return std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(1.0 / std::max(0.001f, max_session_fps)));
}

}  // namespace

StreamSession::StreamSession(ServiceState* state, grpc::CallbackServerContext* ctx,
                             std::shared_ptr<const Principal> principal)
    : state_(state),
      ctx_(ctx),
      principal_(std::move(principal)),
      opened_at_(Clock::now()),
      schedule_(MinInterval(state->options.max_session_fps), state->options.resume_grace_s > 0) {
  st_.id = state->next_session_id++;
  st_.principal = principal_ ? principal_->name : "";
}

void StreamSession::Begin(const absl::Status& admission) {
  self_ = shared_from_this();
  if (!admission.ok()) {
    Log().info("Stream session={} refused: {} peer={}", st_.id, admission.ToString(), ctx_->peer());
    schedule_.Refuse();  // nothing else runs before the reactor is returned
    FinishCounted(ToGrpc(admission));
    return;
  }
  StartRead(&event_);
}

void StreamSession::OnReadDone(bool ok) {
  bool opened;
  {
    std::lock_guard lock(mu_);
    opened = schedule_.opened();
  }
  // A new session whose scene is not in memory but in the shared scene store (or the job
  // journal): loaded on the loader thread first, then the open goes on from there.
  if (ok && !opened && event_.has_open() && event_.open().resume_token().empty()) {
    state_->EnsureSceneLoaded(event_.open().scene_id(),
                              [self = shared_from_this()](absl::Status loaded) {
                                self->scene_load_ = std::move(loaded);
                                self->HandleRead(true, false);
                              });
    return;
  }
  HandleRead(ok, opened);
}

void StreamSession::HandleRead(bool ok, bool opened) {
  // A resume takes the session from another stream (whose lock it needs) or the parked set:
  // done before taking this session's lock. Only this thread opens the session, so it is not
  // opened behind its back.
  std::optional<absl::StatusOr<SessionState>> resumed;
  if (ok && !opened && event_.has_open() && !event_.open().resume_token().empty())
    resumed = state_->Resume(event_.open().resume_token(), st_.principal);
  StreamDecision decision;
  bool read_more = false;
  {
    std::lock_guard lock(mu_);
    const Clock::time_point now = Clock::now();
    if (!ok) {
      // A half-close, or the call is cancelled (the client or its connection went away),
      // which can show up here before OnCancel does.
      if (ctx_->IsCancelled())
        schedule_.ClientGone();
      else
        schedule_.ReadsDone();
    } else {
      ApplyEventLocked(now, std::move(resumed));
    }
    decision = DecideLocked(now);
    read_more = ok && !schedule_.failed() && !schedule_.finished();
  }
  Perform(decision);
  if (read_more) StartRead(&event_);
}

void StreamSession::ApplyEventLocked(Clock::time_point now,
                                     std::optional<absl::StatusOr<SessionState>> resumed) {
  if (!schedule_.TakesEvents()) {
    if (resumed && resumed->ok())
      state_->Park(*std::move(*resumed));  // died meanwhile: put it back
    return;
  }
  absl::Status st = resumed              ? ResumeLocked(now, *std::move(resumed))
                    : schedule_.opened() ? ApplyUpdateLocked(now)
                                         : OpenLocked(now);
  if (!st.ok() && schedule_.Fail(st))
    Log().info("Stream session={} event={}: {}", st_.id, event_.event_id(), st.ToString());
}

void StreamSession::OnWriteDone(bool ok) {
  React([&] {
    state_->pending_frame_bytes -= writing_frame_.data().size();
    if (ok) ++frames_sent_;  // else the client is gone
    schedule_.WriteDone(ok);
  });
}

void StreamSession::OnCancel() {
  React([&] { schedule_.ClientGone(); });
}

void StreamSession::OnDone() {
  std::shared_ptr<StreamSession> keep = std::move(self_);
  std::shared_ptr<ViewLease> view;  // released after unlocking: ForgetView waits for the frame
  {                                  // being rendered, if any
    std::lock_guard lock(mu_);
    if (slot_) state_->pending_frame_bytes -= slot_->data().size();
    slot_.reset();
    if (slot_pixels_) state_->pending_frame_bytes -= slot_pixels_->view().pixels.size();
    slot_pixels_.reset();
    st_.lease.reset();  // a deleted scene is freed with its last session
    view = std::move(st_.view);
  }
  view.reset();  // before the session stops counting as open: its memory goes first
  {
    std::lock_guard lock(state_->sessions_mu);
    // principal_, not st_.principal: the state may have moved to a parked or resumed session.
    if (state_->sessions.erase(keep) != 0 && principal_)
      state_->principal_sessions.Release(principal_->name);
    if (auto it = state_->live_tokens.find(st_.token);
        it != state_->live_tokens.end() && it->second.lock() == keep)
      state_->live_tokens.erase(it);
  }
  Log().info("Stream session={} ended: {} frames sent, {} dropped, {:.1f} s, {}", st_.id,
             frames_sent_, frames_dropped_, MsSince(opened_at_) / 1000.0, end_status_);
}

std::optional<RenderWork> StreamSession::TakeWork() {
  StreamDecision decision;
  std::optional<RenderWork> work;
  {
    std::lock_guard lock(mu_);
    const Clock::time_point now = Clock::now();
    if (std::optional<FrameStart> start = schedule_.Take(now))
      work = MakeWorkLocked(*start);
    else
      decision = DecideLocked(now);
  }
  Perform(decision);
  return work;
}

void StreamSession::Deliver(const RenderWork& work, absl::StatusOr<EncodedFrame> frame) {
  std::optional<v1::Frame> wire;  // converted before taking the lock
  std::optional<Frame> pixels;
  if (frame.ok()) {
    ToProto(*frame, &wire.emplace());
    if (frame->format == ImageFormat::kRgba) pixels = std::move(frame->frame);
  }
  React([&] {
    const Arrival arrival = schedule_.FrameDone(work.sequence, frame.status());
    if (wire) KeepFrameLocked(arrival, *std::move(wire), &pixels);
  });
  if (pixels) state_->renderer->ReleasePixels(*pixels);  // not kept
}

void StreamSession::KeepFrameLocked(Arrival arrival, v1::Frame frame,
                                    std::optional<Frame>* pixels) {
  switch (arrival) {
    case Arrival::kIgnored:
      return;
    case Arrival::kStale:
      Drop();  // a newer frame overtook it in the encoder pool
      return;
    case Arrival::kReplacesSlot:
      state_->pending_frame_bytes -= slot_->data().size();
      Drop();  // the client has not taken the previous one yet: latest wins
      break;
    case Arrival::kToSlot:
      break;
  }
  state_->pending_frame_bytes += frame.data().size();
  frame.set_session_token(st_.token);
  if (!fps_note_.empty()) {
    v1::SettingNote* note = frame.add_notes();
    note->set_field("target_fps");
    note->set_message(fps_note_);
  }
  slot_ = std::move(frame);
  if (slot_pixels_) {  // replaced (latest wins) before it cost an encode
    state_->pending_frame_bytes -= slot_pixels_->view().pixels.size();
    state_->renderer->ReleasePixels(*slot_pixels_);
  }
  slot_pixels_ = std::exchange(*pixels, std::nullopt);
  // Unencoded pixels held for the client count as pending bytes too, until encoded.
  if (slot_pixels_) state_->pending_frame_bytes += slot_pixels_->view().pixels.size();
}

void StreamSession::Stop() {
  React([&] { schedule_.Stop(); });
}

std::optional<SessionState> StreamSession::Handover(const std::string& principal) {
  StreamDecision decision;
  std::optional<SessionState> out;
  {
    std::lock_guard lock(mu_);
    if (!schedule_.CanHandOver() || st_.principal != principal) return std::nullopt;
    schedule_.HandOver();
    out = std::move(st_);
    st_.id = out->id;  // for the log lines of this (ending) stream
    st_.token = out->token;
    if (slot_) state_->pending_frame_bytes -= slot_->data().size();
    slot_.reset();
    if (slot_pixels_) state_->pending_frame_bytes -= slot_pixels_->view().pixels.size();
    slot_pixels_.reset();
    decision = DecideLocked(Clock::now());
  }
  Perform(decision);
  return out;
}

void StreamSession::Drop() {
  ++frames_dropped_;
  ++state_->frames_dropped;
  if (state_->metrics) state_->metrics->FrameDropped();
}

void StreamSession::FinishCounted(const grpc::Status& status) {
  state_->CountRpc("Stream", status);
  Finish(status);
}

absl::Status StreamSession::CheckTargetFpsLocked(float fps, const char* field) {
  RETURN_IF_ERROR(CheckTargetFps(fps, field));
  const float cap = state_->options.max_session_fps;
  fps_note_.clear();
  if (fps > cap) {
    fps_note_ = absl::StrCat("lowered from ", fps, " to ", cap, " (the server's max_session_fps)");
    fps = cap;
  }
  st_.target_fps = fps;
  return absl::OkStatus();
}

// TAA on a resting camera: full frames after the newest change until this many reflect it
// (the history is then within a few tenths of a dB of converged; aa_test's convergence table).
constexpr uint32_t kTaaSettleFrames = 16;

// A playing animation with target_fps 0 (frames only on change) is shown at this rate, or the
// server's max_session_fps when lower.
constexpr float kPlayFps = 30.0f;

namespace {

// The time a playing session shows now, and whether a non-looping animation has reached its end.
struct PlayTime {
  double t = 0.0;
  bool ended = false;
};

// The duration of the session's animation (0 for none, or while its scene lease is elsewhere).
double AnimationDuration(const SessionState& st) {
  if (!st.lease) return 0.0;
  const SceneInfo& info = st.lease->get().scene->info();
  const absl::StatusOr<int> a = FindAnimation(info, st.settings.animation);
  return a.ok() && *a >= 0 ? info.animations[size_t(*a)].duration_s : 0.0;
}

PlayTime PlayingSceneTime(const SessionState& st, Clock::time_point now) {
  double t = st.play_base + std::chrono::duration<double>(now - st.play_origin).count();
  // Kept within the animation, as the renderer would wrap or clamp it anyway, so a long stream
  // neither loses precision nor leaves the setting's range.
  const double duration = AnimationDuration(st);
  bool ended = false;
  if (duration > 0.0) {
    ended = !st.settings.loop && t >= duration;
    t = WrapAnimationTime(t, duration, st.settings.loop);
  }
  return {std::clamp(t, -1e6, 1e6), ended};
}

}  // namespace

StreamPacing StreamSession::PacingLocked() const {
  const InteractiveProfile& p = st_.profile;
  StreamPacing pacing;
  pacing.target_fps = st_.target_fps;
  // Only a playing animation that moves: `play` without one renders nothing new.
  if (st_.settings.play && pacing.target_fps <= 0.0f && AnimationDuration(st_) > 0.0)
    pacing.target_fps = std::min(kPlayFps, state_->options.max_session_fps);
  pacing.interactive =
      p.enabled && (p.render_scale < 1.0f ||
                    (st_.video.h264 ? st_.video.interactive_crf > st_.video.crf
                                    : p.jpeg_quality < st_.settings.jpeg_quality));
  pacing.rest = std::chrono::milliseconds(p.rest_ms);
  pacing.settle_frames = st_.settings.aa == AaMode::kTaa ? kTaaSettleFrames : 0;
  return pacing;
}

absl::Status StreamSession::OpenLocked(Clock::time_point now) {
  if (!event_.has_open())
    return absl::InvalidArgumentError("open: the first ClientEvent must open the session");
  const v1::OpenSession& open = event_.open();
  if (!scene_load_.ok())
    return absl::Status(scene_load_.code(),
                        absl::StrCat("open.scene_id: ", scene_load_.message()));
  ASSIGN_OR_RETURN(std::shared_ptr<StoredScene> scene, state_->store->Find(open.scene_id()));
  ASSIGN_OR_RETURN(Settings settings, MergeSettings(state_->default_settings, open.settings()));
  RETURN_IF_ERROR(FindAnimation(scene->scene->info(), settings.animation).status());
  RETURN_IF_ERROR(ResolveCamera(open.camera(), scene->scene->info(), Aspect(settings)).status());
  ASSIGN_OR_RETURN(InteractiveProfile profile,
                   MergeProfile(InteractiveProfile{}, open.interactive(), "open.interactive"));
  ASSIGN_OR_RETURN(VideoSettings video, MergeVideo(VideoSettings{}, open.video(), "open.video"));
  RETURN_IF_ERROR(CheckVideo(video, settings, "open."));
  RETURN_IF_ERROR(CheckTargetFpsLocked(open.target_fps(), "open.target_fps"));
  st_.lease = std::make_shared<SceneLease>(scene);
  st_.view = std::make_shared<ViewLease>(state_->renderer, scene->scene, st_.id);
  st_.settings = settings;
  st_.play_base = settings.scene_time;
  st_.play_origin = now;
  st_.camera = open.camera();
  st_.profile = profile;
  st_.video = video;
  st_.token = RandomHex(16);  // 128 bits
  schedule_.Open(now, PacingLocked());
  Register();
  MarkDirtyLocked(now);
  if (state_->metrics) state_->metrics->SessionOpened(false);
  Log().info("Stream session={} opened scene={} {}x{} fps={} interactive={} codec={} peer={}",
             st_.id, scene->id, st_.settings.width, st_.settings.height, st_.target_fps,
             st_.profile.enabled ? absl::StrCat(st_.profile.render_scale) : "off",
             st_.video.h264 ? "h264" : "jpeg", ctx_->peer());
  return absl::OkStatus();
}

absl::Status StreamSession::ResumeLocked(Clock::time_point now,
                                         absl::StatusOr<SessionState> resumed) {
  const uint64_t fresh_id = st_.id;
  ASSIGN_OR_RETURN(st_, std::move(resumed));
  schedule_.Resume(now, PacingLocked(), st_.sequence);
  Register();
  if (state_->metrics) state_->metrics->SessionOpened(true);
  Log().info("Stream session={} resumed (stream {}) scene={} at frame {} peer={}", st_.id, fresh_id,
             st_.lease->get().id, st_.sequence, ctx_->peer());
  return absl::OkStatus();
}

void StreamSession::Register() {
  std::lock_guard lock(state_->sessions_mu);
  state_->live_tokens[st_.token] = weak_from_this();
}

absl::Status StreamSession::ApplyUpdateLocked(Clock::time_point now) {
  if (event_.has_open()) return absl::InvalidArgumentError("open: the session is already open");
  if (!st_.lease) return absl::OkStatus();  // the state has left (parked or handed over)
  Settings settings = st_.settings;
  if (event_.has_settings()) {
    ASSIGN_OR_RETURN(settings, MergeSettings(st_.settings, event_.settings()));
    RETURN_IF_ERROR(FindAnimation(st_.lease->get().scene->info(), settings.animation).status());
  }
  std::optional<InteractiveProfile> profile;
  if (event_.has_interactive()) {
    ASSIGN_OR_RETURN(profile, MergeProfile(st_.profile, event_.interactive(), "interactive"));
  }
  VideoSettings video = st_.video;
  if (event_.has_video()) {
    ASSIGN_OR_RETURN(video, MergeVideo(st_.video, event_.video(), "video"));
  }
  if (event_.has_video() || event_.has_settings())
    RETURN_IF_ERROR(CheckVideo(video, settings, ""));
  if (event_.has_camera()) {
    RETURN_IF_ERROR(
        ResolveCamera(event_.camera(), st_.lease->get().scene->info(), Aspect(settings)).status());
    st_.camera = event_.camera();
    schedule_.CameraMoved(now);
  }
  if (event_.has_target_fps()) {
    RETURN_IF_ERROR(CheckTargetFpsLocked(event_.target_fps(), "target_fps"));
    schedule_.RestartCadence(now);
  }
  // play: the clock (re)starts from scene_time when play turns on or an event sets the time;
  // turning it off keeps the time it had reached, unless the event sets one.
  // A playing session whose animation or loop changes without a time goes on from the time it
  // showed (in the old animation's terms), not from where the clock would put it now.
  const bool time_set = event_.has_settings() && event_.settings().has_scene_time();
  const bool timeline_changed =
      settings.animation != st_.settings.animation || settings.loop != st_.settings.loop;
  if (settings.play && (!st_.settings.play || time_set)) {
    st_.play_base = settings.scene_time;
    st_.play_origin = now;
  } else if (settings.play && timeline_changed) {
    st_.play_base = PlayingSceneTime(st_, now).t;
    st_.play_origin = now;
  } else if (!settings.play && st_.settings.play && !time_set) {
    settings.scene_time = static_cast<float>(PlayingSceneTime(st_, now).t);
  }
  st_.settings = settings;
  if (profile) st_.profile = *profile;
  if (!video.SameStream(st_.video)) ++st_.video_generation;
  const bool video_changed = video != st_.video;
  st_.video = video;
  if (event_.keyframe()) keyframe_requested_ = true;
  schedule_.SetPacing(PacingLocked());
  if (event_.has_settings() || event_.has_camera() || event_.refresh() || event_.keyframe() ||
      video_changed)
    MarkDirtyLocked(now);
  else if (event_.event_id() > st_.newest_event)
    st_.newest_event = event_.event_id();
  return absl::OkStatus();
}

void StreamSession::MarkDirtyLocked(Clock::time_point now) {
  schedule_.Changed(now);
  st_.newest_event = event_.event_id();
}

RenderWork StreamSession::MakeWorkLocked(const FrameStart& start) {
  RenderWork w;
  w.scene = st_.lease->get().scene;
  w.scene_id = st_.lease->get().id;
  w.view = st_.id;
  w.settings = st_.settings;
  if (st_.settings.play) {  // the frame's settings say the time it shows
    const PlayTime now = PlayingSceneTime(st_, Clock::now());
    w.settings.scene_time = static_cast<float>(now.t);
    if (now.ended) {
      // A non-looping animation that reached its end stops playing: this frame shows the end
      // with play off, and the session goes back to frames on change.
      st_.settings.play = false;
      st_.settings.scene_time = w.settings.scene_time;
      w.settings.play = false;
      schedule_.SetPacing(PacingLocked());
    }
  }
  // Validated when the event arrived; framing depends only on the scene and aspect ratio.
  absl::StatusOr<Camera> camera = ResolveCamera(st_.camera, w.scene->info(), Aspect(st_.settings));
  w.camera = camera.ok() ? *camera : Camera{};
  w.format = st_.video.h264 ? ImageFormat::kRgba : ImageFormat::kJpeg;
  w.kind = "stream";
  if (start.profile == FrameProfile::kInteractive) {
    auto scaled = [&](uint32_t v) {
      return std::max(1u, static_cast<uint32_t>(std::lround(v * st_.profile.render_scale)));
    };
    w.settings.width = scaled(st_.settings.width);
    w.settings.height = scaled(st_.settings.height);
    w.settings.jpeg_quality = std::min(st_.profile.jpeg_quality, st_.settings.jpeg_quality);
    w.output_width = st_.settings.width;
    w.output_height = st_.settings.height;
    w.profile = "interactive";
  } else {
    w.profile = "full";
  }
  w.sequence = ++st_.sequence;
  w.event_id = st_.newest_event;
  w.requested = start.requested;
  return w;
}

StreamDecision StreamSession::DecideLocked(Clock::time_point now) {
  StreamDecision d = schedule_.Next(now);
  if (d.write) {
    writing_frame_ = std::move(*slot_);
    slot_.reset();
    writing_video_.reset();
    if (slot_pixels_) {
      writing_pixels_ = std::move(*slot_pixels_);
      slot_pixels_.reset();
      VideoWrite& v = writing_video_.emplace();
      v.video = st_.video;
      v.generation = st_.video_generation;
      v.keyframe = std::exchange(keyframe_requested_, false);
      v.crf = writing_frame_.profile() == "interactive" ? st_.video.interactive_crf : st_.video.crf;
    } else if (st_.video.h264) {
      // A JPEG frame rendered before the switch to h264 goes out as it is; a client that
      // switches its decoder on it needs the next video frame to be a keyframe.
      keyframe_requested_ = true;
    }
  }
  if (d.park) {
    st_.sequence = std::max(st_.sequence, schedule_.newest_delivered());
    state_->Park(std::move(st_));
  }
  if (d.finish)
    end_status_ = d.finish->ok()
                      ? "OK"
                      : absl::StrCat(static_cast<int>(d.finish->code()), ": ", d.finish->message());
  return d;
}

void StreamSession::Perform(const StreamDecision& d) {
  if (d.write) {
    if (writing_video_)
      state_->loop->SubmitEncode([self = shared_from_this()] { self->EncodeAndWrite(); });
    else
      StartWrite(&writing_frame_);
  }
  if (d.enqueue) state_->loop->Enqueue(shared_from_this());
  if (d.enqueue_at) state_->loop->EnqueueAt(shared_from_this(), *d.enqueue_at);
  if (d.finish) FinishCounted(ToGrpc(*d.finish));
}

// On the encoder pool, for a write decided by DecideLocked: encodes the frame, then writes it.
// The schedule counts the write as outstanding from the decision, so nothing else writes, takes
// writing_frame_ or finishes the stream meanwhile.
void StreamSession::EncodeAndWrite() {
  const VideoWrite& job = *writing_video_;
  const RgbaView pixels = writing_pixels_.view();
  const auto t0 = Clock::now();
  absl::Status st;
  bool fresh = false;
  if (!job.video.h264) {
    // Rendered for h264, taken after the session switched to JPEG.
    absl::StatusOr<std::vector<uint8_t>> jpeg = EncodeJpeg(
        pixels, static_cast<int>(writing_frame_.settings().jpeg_quality()),
        writing_frame_.settings().jpeg_444() ? ChromaSubsampling::k444 : ChromaSubsampling::k420);
    if (jpeg.ok()) {
      writing_frame_.set_data(jpeg->data(), jpeg->size());
      writing_frame_.set_encoding(v1::IMAGE_JPEG);
    } else {
      st = jpeg.status();
    }
    encoder_.reset();
  } else if (!encoder_ || encoder_generation_ != job.generation ||
             encoder_->width() != pixels.width || encoder_->height() != pixels.height ||
             // NVENC keeps the quality it opened with: another one needs a new encoder.
             (!encoder_->per_frame_crf() && encoder_->crf() != job.crf)) {
    video::EncoderOptions o;
    o.width = pixels.width;
    o.height = pixels.height;
    o.kind = job.video.encoder == v1::VIDEO_ENCODER_HARDWARE   ? video::EncoderKind::kHardware
             : job.video.encoder == v1::VIDEO_ENCODER_SOFTWARE ? video::EncoderKind::kSoftware
                                                               : video::EncoderKind::kAuto;
    o.crf = job.crf;
    o.max_bitrate_kbps = job.video.max_bitrate_kbps;
    o.keyframe_interval = job.video.keyframe_interval;
    o.preset = job.video.preset;
    encoder_.reset();
    absl::StatusOr<std::unique_ptr<video::Encoder>> enc = video::Encoder::Create(o);
    if (enc.ok()) {
      encoder_ = *std::move(enc);
      encoder_generation_ = job.generation;
      fresh = true;
    } else {
      st = absl::Status(enc.status().code(), absl::StrCat("video: ", enc.status().message()));
    }
  }
  if (st.ok() && job.video.h264) {
    absl::StatusOr<video::Packet> packet = encoder_->Encode(
        pixels.pixels.data(), size_t{pixels.width} * 4, fresh || job.keyframe, job.crf);
    if (packet.ok()) {
      const double ms = MsSince(t0);
      writing_frame_.set_data(packet->data.data(), packet->data.size());
      writing_frame_.set_encoding(v1::VIDEO_H264);
      writing_frame_.set_keyframe(packet->keyframe);
      writing_frame_.set_codec(encoder_->codec_string());
      writing_frame_.set_encoder(encoder_->name());
      v1::CpuTimings* cpu = writing_frame_.mutable_cpu();
      cpu->set_encode_ms(cpu->encode_ms() + ms);
      cpu->set_total_ms(cpu->total_ms() + ms);
      if (state_->metrics) state_->metrics->VideoFrameEncoded(ms, packet->data.size(), packet->keyframe);
    } else {
      encoder_.reset();  // the next frame starts a new video
      st = packet.status();
    }
  }
  state_->pending_frame_bytes -= pixels.pixels.size();
  state_->renderer->ReleasePixels(writing_pixels_);
  writing_pixels_ = {};
  if (!st.ok()) {
    // As if the write were done: the stream then ends with the error.
    React([&] {
      Log().warn("Stream session={}: {}", st_.id, st.ToString());
      schedule_.Fail(st);
      schedule_.WriteDone(true);
    });
    return;
  }
  {
    std::lock_guard lock(mu_);
    state_->pending_frame_bytes += writing_frame_.data().size();
  }
  StartWrite(&writing_frame_);
}

// ---------------------------------------------------------------------------------------------
// The Stream handler and the sessions apart from their streams (open, parked, resumed).

grpc::ServerBidiReactor<v1::ClientEvent, v1::Frame>* RenderServiceImpl::Stream(
    grpc::CallbackServerContext* ctx) {
  absl::StatusOr<std::shared_ptr<const Principal>> principal = state_->Authorize(ctx);
  auto session = std::make_shared<StreamSession>(
      state_, ctx, principal.ok() ? *principal : std::shared_ptr<const Principal>());
  absl::Status admission = principal.status();
  if (admission.ok()) {
    const Principal& p = **principal;
    // Under the lock ShutdownSessions takes, so no session slips in after its snapshot.
    std::lock_guard lock(state_->sessions_mu);
    if (state_->shutting_down)
      admission = Unavailable();
    else if (state_->sessions.size() >= state_->options.max_sessions)
      admission = absl::ResourceExhaustedError(absl::StrCat(
          "sessions: ", state_->sessions.size(), " open streams reach the max_sessions limit (",
          state_->options.max_sessions, ")"));
    else if (!state_->principal_sessions.TryAcquire(p.name, p.max_sessions))
      admission = absl::ResourceExhaustedError(
          absl::StrCat("sessions: token \"", p.name, "\" has its max_sessions (",
                       p.max_sessions.value_or(0), ") streams open"));
    else
      state_->sessions.insert(session);
  }
  session->Begin(admission);
  return session.get();
}

uint32_t ServiceState::session_count() const {
  std::lock_guard lock(sessions_mu);
  return static_cast<uint32_t>(sessions.size());
}

uint32_t ServiceState::parked_count() const {
  std::lock_guard lock(sessions_mu);
  return static_cast<uint32_t>(parked.size());
}

void ServiceState::ShutdownSessions() {
  std::vector<std::shared_ptr<StreamSession>> open;
  std::map<std::string, Parked> dropped;  // scene leases released after unlocking
  {
    std::lock_guard lock(sessions_mu);
    shutting_down = true;
    open.assign(sessions.begin(), sessions.end());
    dropped.swap(parked);
  }
  for (auto& s : open) s->Stop();
}

void ServiceState::Park(SessionState state) {
  std::optional<SessionState> dropped;  // released after unlocking (it holds a scene lease)
  std::lock_guard lock(sessions_mu);
  if (shutting_down) return;
  if (parked.size() >= options.max_sessions) {
    auto oldest = std::min_element(parked.begin(), parked.end(), [](const auto& a, const auto& b) {
      return a.second.expires < b.second.expires;
    });
    dropped = std::move(oldest->second.state);
    parked.erase(oldest);
  }
  Log().info("Stream session={} parked for {} s (resume_token)", state.id, options.resume_grace_s);
  const std::string token = state.token;
  live_tokens.erase(token);
  parked[token] =
      Parked{std::move(state), Clock::now() + std::chrono::seconds(options.resume_grace_s)};
}

absl::StatusOr<SessionState> ServiceState::Resume(const std::string& token,
                                                  const std::string& principal) {
  const absl::Status unknown = absl::NotFoundError(
      "open.resume_token: no session to resume (unknown token, or its grace period is over)");
  // Expired sessions are left to the sweeper (which frees them outside the lock).
  auto take_parked = [&]() -> std::optional<SessionState> {
    std::lock_guard lock(sessions_mu);
    auto it = parked.find(token);
    if (it == parked.end() || it->second.state.principal != principal ||
        Clock::now() >= it->second.expires)
      return std::nullopt;
    SessionState out = std::move(it->second.state);
    parked.erase(it);
    return out;
  };
  if (std::optional<SessionState> s = take_parked()) return *std::move(s);
  std::shared_ptr<StreamSession> live;
  {
    std::lock_guard lock(sessions_mu);
    if (auto it = live_tokens.find(token); it != live_tokens.end()) live = it->second.lock();
  }
  if (live) {
    if (std::optional<SessionState> s = live->Handover(principal)) return *std::move(s);
    // It was being parked meanwhile.
    if (std::optional<SessionState> s = take_parked()) return *std::move(s);
  }
  return unknown;
}

void ServiceState::SweepParked() {
  std::vector<SessionState> expired;  // freed after unlocking
  {
    std::lock_guard lock(sessions_mu);
    const Clock::time_point now = Clock::now();
    for (auto it = parked.begin(); it != parked.end();) {
      if (now >= it->second.expires) {
        Log().info("Stream session={} not resumed within {} s: dropped", it->second.state.id,
                   options.resume_grace_s);
        expired.push_back(std::move(it->second.state));
        it = parked.erase(it);
      } else {
        ++it;
      }
    }
  }
}

}  // namespace tessera::server
