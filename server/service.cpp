#include "server/service.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include <optional>

#include "absl/strings/str_cat.h"
#include "renderer/log.h"
#include "renderer/scene/gltf_import.h"
#include "server/convert.h"
#include "server/jobs.h"
#include "server/metrics.h"
#include "server/upload.h"

namespace tessera::server {
namespace {

constexpr float kMaxTargetFps = 240.0f;

double MsSince(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

std::string Peer(grpc::CallbackServerContext* ctx) { return ctx->peer(); }

absl::Status CheckTargetFps(float fps, const char* field) {
  if (!std::isfinite(fps) || fps < 0.0f || fps > kMaxTargetFps)
    return absl::InvalidArgumentError(
        absl::StrCat(field, ": ", fps, " is out of range (0..", kMaxTargetFps, ")"));
  return absl::OkStatus();
}

float Aspect(const Settings& s) { return float(s.width) / float(s.height); }

absl::Status Unavailable() { return absl::UnavailableError("server is shutting down"); }


}  // namespace

grpc::Status ToGrpc(const absl::Status& s) {
  return grpc::Status(static_cast<grpc::StatusCode>(s.code()), std::string(s.message()));
}

// ---------------------------------------------------------------------------------------------
// Render: one frame, queued on the render thread like every session's frames.

class UnaryRender final : public RenderClient {
 public:
  UnaryRender(ServiceState* state, grpc::CallbackServerContext* ctx,
              grpc::ServerUnaryReactor* reactor, v1::Frame* response, RenderWork work,
              const char* method)
      : state_(state),
        ctx_(ctx),
        reactor_(reactor),
        response_(response),
        work_(std::move(work)),
        method_(method) {}

  std::optional<RenderWork> TakeWork() override {
    if (std::chrono::system_clock::now() >= ctx_->deadline()) {
      Finish(absl::DeadlineExceededError(absl::StrCat(
          "deadline: passed after ", static_cast<int>(MsSince(work_.requested)),
          " ms in the render queue (", state_->loop->queue_depth(), " waiting); not rendered")));
      return std::nullopt;
    }
    if (ctx_->IsCancelled()) {
      Finish(absl::CancelledError("client cancelled the render"));
      return std::nullopt;
    }
    return work_;
  }

  void Deliver(const RenderWork&, absl::StatusOr<v1::Frame> frame) override {
    if (frame.ok()) *response_ = *std::move(frame);
    Finish(frame.status());
  }

 private:
  void Finish(const absl::Status& status) {
    if (finished_.exchange(true)) return;
    --state_->unary_queued;
    Log().info("{} scene={} {}x{} -> {} bytes, {} ({:.1f} ms) peer={}", method_, work_.scene_id,
               work_.settings.width, work_.settings.height, response_->data().size(),
               status.ok() ? "OK" : status.ToString(), MsSince(work_.requested), Peer(ctx_));
    state_->CountRpc(method_, ToGrpc(status));
    reactor_->Finish(ToGrpc(status));
  }

  ServiceState* state_;
  grpc::CallbackServerContext* ctx_;
  grpc::ServerUnaryReactor* reactor_;
  v1::Frame* response_;
  RenderWork work_;
  const char* method_;
  std::atomic<bool> finished_{false};
};

std::shared_ptr<RenderClient> MakeUnaryRender(ServiceState* state,
                                              grpc::CallbackServerContext* ctx,
                                              grpc::ServerUnaryReactor* reactor,
                                              v1::Frame* response, RenderWork work,
                                              const char* method) {
  return std::make_shared<UnaryRender>(state, ctx, reactor, response, std::move(work), method);
}

grpc::ServerUnaryReactor* RenderServiceImpl::Render(grpc::CallbackServerContext* ctx,
                                                    const v1::RenderRequest* req,
                                                    v1::Frame* response) {
  grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
  auto fail = [&](const absl::Status& st) {
    Log().info("Render scene={} -> {} peer={}", req->scene_id().substr(0, 80), st.ToString(),
               Peer(ctx));
    state_->CountRpc("Render", ToGrpc(st));
    reactor->Finish(ToGrpc(st));
    return reactor;
  };
  if (absl::Status st = state_->Authorize(ctx).status(); !st.ok()) return fail(st);
  if (state_->shutting_down) return fail(Unavailable());
  absl::StatusOr<std::shared_ptr<StoredScene>> scene = state_->store->Find(req->scene_id());
  if (!scene.ok()) return fail(scene.status());
  absl::StatusOr<Settings> settings = MergeSettings(state_->default_settings, req->settings());
  if (!settings.ok()) return fail(settings.status());
  absl::StatusOr<Camera> camera =
      ResolveCamera(req->camera(), (*scene)->scene->info(), Aspect(*settings));
  if (!camera.ok()) return fail(camera.status());
  if (!v1::ImageEncoding_IsValid(req->encoding()))
    return fail(absl::InvalidArgumentError(
        absl::StrCat("encoding: unknown value ", static_cast<int>(req->encoding()))));
  if (state_->unary_queued.fetch_add(1) >= kMaxQueuedRenders) {
    --state_->unary_queued;
    return fail(absl::ResourceExhaustedError(absl::StrCat(
        "render queue: ", kMaxQueuedRenders, " renders are waiting (limit); retry later")));
  }
  RenderWork work;
  work.scene = (*scene)->scene;
  work.scene_id = (*scene)->id;
  work.camera = *camera;
  work.settings = *settings;
  work.format = req->encoding() == v1::IMAGE_PNG ? ImageFormat::kPng : ImageFormat::kJpeg;
  work.sequence = 1;
  work.requested = Clock::now();
  work.kind = req->background() ? "background" : "render";
  state_->loop->Enqueue(
      MakeUnaryRender(state_, ctx, reactor, response, std::move(work), "Render"),
      req->background() ? Priority::kBackground : Priority::kNormal);
  return reactor;
}

// ---------------------------------------------------------------------------------------------
// Stream: a session. Everything that changes session state happens under mu_, which decides
// what to do next (write, enqueue, finish); the gRPC calls and the render-loop calls happen
// after unlocking, so reactions that run inline cannot deadlock. Lock order: a session's mu_
// may be held while taking ServiceState::sessions_mu (parking), never the other way round.

class StreamSession final : public grpc::ServerBidiReactor<v1::ClientEvent, v1::Frame>,
                            public RenderClient,
                            public std::enable_shared_from_this<StreamSession> {
 public:
  StreamSession(ServiceState* state, grpc::CallbackServerContext* ctx,
                std::shared_ptr<const Principal> principal)
      : state_(state), ctx_(ctx), principal_(std::move(principal)), opened_at_(Clock::now()) {
    st_.id = state->next_session_id++;
    st_.principal = principal_ ? principal_->name : "";
    min_interval_ = std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(1.0 / std::max(0.001f, state->options.max_session_fps)));
  }

  // After construction by make_shared: the reactor keeps itself alive until OnDone.
  void Begin(const absl::Status& admission) {
    self_ = shared_from_this();
    if (!admission.ok()) {
      Log().info("Stream session={} refused: {} peer={}", st_.id, admission.ToString(),
                 Peer(ctx_));
      finished_ = true;  // nothing else runs before the reactor is returned
      FinishCounted(ToGrpc(admission));
      return;
    }
    StartRead(&event_);
  }

  void OnReadDone(bool ok) override {
    // A resume takes the session from another stream (whose lock it needs) or the parked set:
    // done before taking this session's lock. Only this thread reads events, so opened_ is not
    // changed behind its back.
    std::optional<absl::StatusOr<SessionState>> resumed;
    if (ok && !opened_ && event_.has_open() && !event_.open().resume_token().empty())
      resumed = state_->Resume(event_.open().resume_token(), st_.principal);
    Actions actions;
    bool read_more = false;
    {
      std::lock_guard lock(mu_);
      if (!ok) {
        // A half-close, or the call is cancelled (the client or its connection went away),
        // which can show up here before OnCancel does.
        if (ctx_->IsCancelled())
          cancelled_ = true;
        else
          reading_done_ = true;
      } else if (!finished_ && !error_ && !handed_over_ && !parked_) {
        absl::Status st = resumed ? ResumeLocked(*std::move(resumed))
                          : opened_ ? ApplyUpdateLocked()
                                    : OpenLocked();
        if (!st.ok() && !error_) {
          Log().info("Stream session={} event={}: {}", st_.id, event_.event_id(), st.ToString());
          error_ = st;
        }
      } else if (resumed && resumed->ok()) {
        state_->Park(*std::move(*resumed));  // this stream died meanwhile: put it back
      }
      actions = NextActionsLocked();
      read_more = ok && !error_ && !finished_;
    }
    Perform(actions);
    if (read_more) StartRead(&event_);
  }

  void OnWriteDone(bool ok) override {
    Actions actions;
    {
      std::lock_guard lock(mu_);
      writing_ = false;
      state_->pending_frame_bytes -= writing_frame_.data().size();
      if (ok) {
        ++frames_sent_;
      } else {
        cancelled_ = true;  // the client is gone
      }
      actions = NextActionsLocked();
    }
    Perform(actions);
  }

  void OnCancel() override {
    Actions actions;
    {
      std::lock_guard lock(mu_);
      cancelled_ = true;
      actions = NextActionsLocked();
    }
    Perform(actions);
  }

  void OnDone() override {
    std::shared_ptr<StreamSession> keep = std::move(self_);
    {
      std::lock_guard lock(state_->sessions_mu);
      // principal_, not st_.principal: the state may have moved to a parked or resumed session.
      if (state_->sessions.erase(keep) != 0 && principal_)
        state_->principal_sessions.Release(principal_->name);
      if (auto it = state_->live_tokens.find(st_.token);
          it != state_->live_tokens.end() && it->second.lock() == keep)
        state_->live_tokens.erase(it);
    }
    {
      std::lock_guard lock(mu_);
      if (slot_) state_->pending_frame_bytes -= slot_->data().size();
      slot_.reset();
      st_.lease.reset();  // a deleted scene is freed with its last session
    }
    Log().info("Stream session={} ended: {} frames sent, {} dropped, {:.1f} s, {}", st_.id,
               frames_sent_, frames_dropped_, MsSince(opened_at_) / 1000.0, end_status_);
  }

  std::optional<RenderWork> TakeWork() override {
    Actions actions;
    std::optional<RenderWork> work;
    {
      std::lock_guard lock(mu_);
      // The loop cannot say whether a ready entry or a timer brought us here: clear the ready
      // flag, and the timer once it is due; a stale duplicate entry only costs a TakeWork that
      // finds nothing due.
      const Clock::time_point now = Clock::now();
      in_ready_ = false;
      if (armed_at_ && now >= *armed_at_) armed_at_.reset();
      if (DueLocked(now)) work = MakeWorkLocked(now);
      if (!work) actions = NextActionsLocked();
    }
    Perform(actions);
    return work;
  }

  void Deliver(const RenderWork& work, absl::StatusOr<v1::Frame> frame) override {
    Actions actions;
    {
      std::lock_guard lock(mu_);
      if (work.sequence == 0) {
        in_ready_ = false;  // dropped from the queue by a stopping render loop
        armed_at_.reset();
        stopping_ = true;
      } else {
        --in_pipeline_;
      }
      if (!frame.ok()) {
        if (frame.status().code() == absl::StatusCode::kUnavailable)
          stopping_ = true;
        else if (!error_)
          error_ = frame.status();
      } else if (!finished_ && !cancelled_ && !handed_over_) {
        if (frame->sequence() < newest_delivered_) {
          Drop();  // a newer frame overtook it in the encoder pool
        } else {
          if (slot_) {
            state_->pending_frame_bytes -= slot_->data().size();
            Drop();  // the client has not taken the previous one yet: latest wins
          }
          newest_delivered_ = frame->sequence();
          state_->pending_frame_bytes += frame->data().size();
          frame->set_session_token(st_.token);
          if (!fps_note_.empty()) {
            v1::SettingNote* note = frame->add_notes();
            note->set_field("target_fps");
            note->set_message(fps_note_);
          }
          slot_ = *std::move(frame);
        }
      }
      actions = NextActionsLocked();
    }
    Perform(actions);
  }

  // The server is stopping: no new frames; the stream ends with UNAVAILABLE once the frames
  // in flight are written.
  void Stop() {
    Actions actions;
    {
      std::lock_guard lock(mu_);
      stopping_ = true;
      actions = NextActionsLocked();
    }
    Perform(actions);
  }

  // Another stream resumes this session (its client reconnected before this stream noticed
  // the old connection was gone): gives up the state and ends this stream with ABORTED.
  std::optional<SessionState> Handover(const std::string& principal) {
    Actions actions;
    std::optional<SessionState> out;
    {
      std::lock_guard lock(mu_);
      if (!opened_ || handed_over_ || parked_ || finished_ || st_.principal != principal)
        return std::nullopt;
      handed_over_ = true;
      out = std::move(st_);
      st_.id = out->id;  // for the log lines of this (ending) stream
      st_.token = out->token;
      if (slot_) state_->pending_frame_bytes -= slot_->data().size();
      slot_.reset();
      if (!error_) error_ = absl::AbortedError("session resumed by another stream");
      actions = NextActionsLocked();
    }
    Perform(actions);
    return out;
  }

 private:
  struct Actions {
    bool write = false;
    bool enqueue = false;
    std::optional<Clock::time_point> enqueue_at;
    std::optional<grpc::Status> finish;
  };

  void Drop() {
    ++frames_dropped_;
    ++state_->frames_dropped;
    if (state_->metrics) state_->metrics->FrameDropped();
  }

  void FinishCounted(const grpc::Status& status) {
    state_->CountRpc("Stream", status);
    Finish(status);
  }

  absl::Status CheckTargetFpsLocked(float fps, const char* field) {
    if (absl::Status st = CheckTargetFps(fps, field); !st.ok()) return st;
    const float cap = state_->options.max_session_fps;
    fps_note_.clear();
    if (fps > cap) {
      fps_note_ = absl::StrCat("lowered from ", fps, " to ", cap, " (the server's max_session_fps)");
      fps = cap;
    }
    st_.target_fps = fps;
    return absl::OkStatus();
  }

  absl::Status OpenLocked() {
    if (!event_.has_open())
      return absl::InvalidArgumentError("open: the first ClientEvent must open the session");
    const v1::OpenSession& open = event_.open();
    absl::StatusOr<std::shared_ptr<StoredScene>> scene = state_->store->Find(open.scene_id());
    if (!scene.ok()) return scene.status();
    absl::StatusOr<Settings> settings = MergeSettings(state_->default_settings, open.settings());
    if (!settings.ok()) return settings.status();
    absl::StatusOr<Camera> camera =
        ResolveCamera(open.camera(), (*scene)->scene->info(), Aspect(*settings));
    if (!camera.ok()) return camera.status();
    absl::StatusOr<InteractiveProfile> profile =
        MergeProfile(InteractiveProfile{}, open.interactive(), "open.interactive");
    if (!profile.ok()) return profile.status();
    if (absl::Status st = CheckTargetFpsLocked(open.target_fps(), "open.target_fps"); !st.ok())
      return st;
    st_.lease = std::make_shared<SceneLease>(*scene);
    st_.settings = *settings;
    st_.camera = open.camera();
    st_.profile = *profile;
    st_.token = RandomHex(16);  // 128 bits
    next_due_ = Clock::now();  // the first tick is the first frame; the cadence starts there
    opened_ = true;
    Register();
    MarkDirtyLocked();
    if (state_->metrics) state_->metrics->SessionOpened(false);
    Log().info("Stream session={} opened scene={} {}x{} fps={} interactive={} peer={}", st_.id,
               (*scene)->id, st_.settings.width, st_.settings.height, st_.target_fps,
               st_.profile.enabled ? absl::StrCat(st_.profile.render_scale) : "off", Peer(ctx_));
    return absl::OkStatus();
  }

  absl::Status ResumeLocked(absl::StatusOr<SessionState> resumed) {
    if (!resumed.ok()) return resumed.status();
    const uint64_t fresh_id = st_.id;
    st_ = *std::move(resumed);
    newest_delivered_ = st_.sequence;
    next_due_ = Clock::now();
    opened_ = true;
    force_full_ = true;  // a resumed viewer gets a full-quality frame at once
    Register();
    dirty_ = true;
    dirty_since_ = Clock::now();
    if (state_->metrics) state_->metrics->SessionOpened(true);
    Log().info("Stream session={} resumed (stream {}) scene={} at frame {} peer={}", st_.id,
               fresh_id, st_.lease->get().id, st_.sequence, Peer(ctx_));
    return absl::OkStatus();
  }

  void Register() {
    std::lock_guard lock(state_->sessions_mu);
    state_->live_tokens[st_.token] = weak_from_this();
  }

  absl::Status ApplyUpdateLocked() {
    if (event_.has_open()) return absl::InvalidArgumentError("open: the session is already open");
    if (!st_.lease) return absl::OkStatus();  // the state has left (parked or handed over)
    Settings settings = st_.settings;
    if (event_.has_settings()) {
      absl::StatusOr<Settings> merged = MergeSettings(st_.settings, event_.settings());
      if (!merged.ok()) return merged.status();
      settings = *merged;
    }
    std::optional<InteractiveProfile> profile;
    if (event_.has_interactive()) {
      absl::StatusOr<InteractiveProfile> merged =
          MergeProfile(st_.profile, event_.interactive(), "interactive");
      if (!merged.ok()) return merged.status();
      profile = *merged;
    }
    if (event_.has_camera()) {
      absl::StatusOr<Camera> camera =
          ResolveCamera(event_.camera(), st_.lease->get().scene->info(), Aspect(settings));
      if (!camera.ok()) return camera.status();
      st_.camera = event_.camera();
      last_motion_ = Clock::now();
    }
    if (event_.has_target_fps()) {
      if (absl::Status st = CheckTargetFpsLocked(event_.target_fps(), "target_fps"); !st.ok())
        return st;
      next_due_ = Clock::now();
    }
    st_.settings = settings;
    if (profile) st_.profile = *profile;
    if (event_.has_settings() || event_.has_camera() || event_.refresh()) MarkDirtyLocked();
    else if (event_.event_id() > st_.newest_event) st_.newest_event = event_.event_id();
    return absl::OkStatus();
  }

  void MarkDirtyLocked() {
    if (!dirty_) dirty_since_ = Clock::now();
    dirty_ = true;
    st_.newest_event = event_.event_id();
  }

  bool CanRenderLocked() const {
    return opened_ && !finished_ && !cancelled_ && !stopping_ && !error_ && !handed_over_ &&
           !parked_ && in_pipeline_ < 2 && !slot_;
  }
  bool ContinuousLocked() const { return st_.target_fps > 0.0f && !reading_done_; }
  // The camera moved within the rest time: frames use the interactive profile.
  bool MovingLocked(Clock::time_point now) const {
    return st_.profile.enabled && last_motion_ &&
           now < *last_motion_ + std::chrono::milliseconds(st_.profile.rest_ms);
  }

  // When the session next wants the render thread (never: nullopt). Something changed, the
  // continuous cadence, or the full-quality frame after the camera rests; never sooner than
  // the max_session_fps interval after the previous frame started.
  std::optional<Clock::time_point> WakeLocked() const {
    if (!CanRenderLocked()) return std::nullopt;
    std::optional<Clock::time_point> t;
    auto earliest = [&t](Clock::time_point x) { t = t ? std::min(*t, x) : x; };
    if (dirty_) earliest(Clock::time_point::min());
    if (ContinuousLocked()) earliest(next_due_);
    if (need_refine_ && last_motion_)
      earliest(*last_motion_ + std::chrono::milliseconds(st_.profile.rest_ms));
    if (!t) return std::nullopt;
    if (last_start_) return std::max(*t, *last_start_ + min_interval_);
    return t;
  }
  bool DueLocked(Clock::time_point now) const {
    std::optional<Clock::time_point> wake = WakeLocked();
    return wake && *wake <= now;
  }

  RenderWork MakeWorkLocked(Clock::time_point now) {
    RenderWork w;
    w.scene = st_.lease->get().scene;
    w.scene_id = st_.lease->get().id;
    w.view = st_.id;
    w.settings = st_.settings;
    // Validated when the event arrived; framing depends only on the scene and aspect ratio.
    absl::StatusOr<Camera> camera =
        ResolveCamera(st_.camera, w.scene->info(), Aspect(st_.settings));
    w.camera = camera.ok() ? *camera : Camera{};
    w.format = ImageFormat::kJpeg;
    w.kind = "stream";
    const bool interactive = !force_full_ && MovingLocked(now) &&
                             (st_.profile.render_scale < 1.0f ||
                              st_.profile.jpeg_quality < st_.settings.jpeg_quality);
    if (interactive) {
      auto scaled = [&](uint32_t v) {
        return std::max(1u, static_cast<uint32_t>(std::lround(v * st_.profile.render_scale)));
      };
      w.settings.width = scaled(st_.settings.width);
      w.settings.height = scaled(st_.settings.height);
      w.settings.jpeg_quality = std::min(st_.profile.jpeg_quality, st_.settings.jpeg_quality);
      w.output_width = st_.settings.width;
      w.output_height = st_.settings.height;
      w.profile = "interactive";
      need_refine_ = true;
    } else {
      w.profile = "full";
      need_refine_ = false;
    }
    force_full_ = false;
    w.sequence = ++st_.sequence;
    w.event_id = st_.newest_event;
    w.requested = dirty_ ? dirty_since_ : ContinuousLocked() ? std::min(now, next_due_) : now;
    dirty_ = false;
    if (ContinuousLocked()) {
      const auto period = std::chrono::duration_cast<Clock::duration>(
          std::chrono::duration<double>(1.0 / st_.target_fps));
      // Keep the cadence, but never try to catch up on frames missed while busy.
      next_due_ = std::max(next_due_ + period, now);
    }
    last_start_ = now;
    ++in_pipeline_;
    return w;
  }

  // Decides the next steps from the state; the caller performs them after unlocking.
  Actions NextActionsLocked() {
    Actions a;
    if (finished_) return a;
    if (!writing_ && slot_ && !cancelled_) {
      writing_frame_ = std::move(*slot_);
      slot_.reset();
      writing_ = true;
      a.write = true;
    }
    const Clock::time_point now = Clock::now();
    if (!in_ready_) {
      if (std::optional<Clock::time_point> wake = WakeLocked()) {
        if (*wake <= now) {
          in_ready_ = true;  // a change jumps the queue even while a timer is armed
          a.enqueue = true;
        } else if (!armed_at_ || *wake < *armed_at_) {
          armed_at_ = *wake;
          a.enqueue_at = *wake;
        }
      }
    }
    if (writing_) return a;  // never finish with a write outstanding
    const bool idle = in_pipeline_ == 0 && !slot_;
    std::optional<grpc::Status> finish;
    if (cancelled_) {
      // The client vanished without closing: keep the session for a resume.
      if (opened_ && !handed_over_ && !parked_ && !stopping_ && !error_ && !reading_done_ &&
          state_->options.resume_grace_s > 0) {
        parked_ = true;
        st_.sequence = std::max(st_.sequence, newest_delivered_);
        state_->Park(std::move(st_));
      }
      finish = grpc::Status(grpc::StatusCode::CANCELLED, "client cancelled the stream");
    } else if (error_) {
      finish = ToGrpc(*error_);
    } else if (stopping_ && idle) {
      finish = ToGrpc(Unavailable());
    } else if (reading_done_ && idle && !dirty_ && !need_refine_) {
      finish = grpc::Status::OK;
    }
    if (finish) {
      finished_ = true;
      end_status_ =
          finish->ok() ? "OK" : absl::StrCat(finish->error_code(), ": ", finish->error_message());
      a.finish = std::move(finish);
    }
    return a;
  }

  void Perform(const Actions& a) {
    if (a.write) StartWrite(&writing_frame_);
    if (a.enqueue) state_->loop->Enqueue(shared_from_this());
    if (a.enqueue_at) state_->loop->EnqueueAt(shared_from_this(), *a.enqueue_at);
    if (a.finish) FinishCounted(*a.finish);
  }

  ServiceState* const state_;
  grpc::CallbackServerContext* const ctx_;
  const std::shared_ptr<const Principal> principal_;
  const Clock::time_point opened_at_;
  Clock::duration min_interval_{};       // 1 / max_session_fps
  std::shared_ptr<StreamSession> self_;  // until OnDone
  v1::ClientEvent event_;                // read buffer (one read at a time)

  std::mutex mu_;
  SessionState st_;  // moved out when parked or handed over
  bool opened_ = false;
  bool parked_ = false;
  bool handed_over_ = false;
  std::string fps_note_;  // target_fps was lowered to the cap
  bool dirty_ = false;
  Clock::time_point dirty_since_;
  Clock::time_point next_due_;
  std::optional<Clock::time_point> last_motion_;  // the newest camera event
  std::optional<Clock::time_point> last_start_;   // the newest frame's start (fps cap)
  bool need_refine_ = false;  // the newest frame was interactive: a full one is owed
  bool force_full_ = false;   // the next frame is full quality (resume)
  bool in_ready_ = false;                      // in the render loop's ready queue
  std::optional<Clock::time_point> armed_at_;  // the earliest render-loop timer set
  int in_pipeline_ = 0;                        // frames being rendered or encoded
  uint64_t newest_delivered_ = 0;
  std::optional<v1::Frame> slot_;  // the newest encoded frame not yet written
  v1::Frame writing_frame_;        // owned by gRPC while writing_
  bool writing_ = false;
  bool reading_done_ = false;
  bool cancelled_ = false;
  bool stopping_ = false;
  std::optional<absl::Status> error_;
  bool finished_ = false;
  uint64_t frames_sent_ = 0;
  uint64_t frames_dropped_ = 0;
  std::string end_status_;
};

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
      admission = absl::ResourceExhaustedError(absl::StrCat(
          "sessions: token \"", p.name, "\" has its max_sessions (", p.max_sessions.value_or(0),
          ") streams open"));
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
  parked[token] = Parked{std::move(state),
                         Clock::now() + std::chrono::seconds(options.resume_grace_s)};
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

absl::StatusOr<std::shared_ptr<const Principal>> ServiceState::Authorize(
    grpc::CallbackServerContext* ctx) const {
  std::string_view header;
  const auto& md = ctx->client_metadata();
  if (auto it = md.find("authorization"); it != md.end())
    header = std::string_view(it->second.data(), it->second.size());
  return auth->Authenticate(header);
}

void ServiceState::CountRpc(const char* method, const grpc::Status& status) const {
  if (metrics) metrics->RpcFinished(method, static_cast<int>(status.error_code()));
}


// ---------------------------------------------------------------------------------------------
// UploadScene: chunks are assembled on the gRPC thread (cheap checks and copies); parsing and
// the device upload run on the loader pool.

class UploadReactor final : public grpc::ServerReadReactor<v1::UploadRequest> {
 public:
  UploadReactor(ServiceState* state, grpc::CallbackServerContext* ctx, v1::SceneInfo* response)
      : state_(state),
        ctx_(ctx),
        response_(response),
        assembler_(UploadLimits{state->options.max_upload_bytes, state->options.max_upload_files,
                                state->options.max_chunk_bytes}),
        started_(Clock::now()) {
    // Unauthenticated calls are refused before they take an upload slot.
    absl::StatusOr<std::shared_ptr<const Principal>> principal = state_->Authorize(ctx);
    if (!principal.ok()) {
      Done(principal.status());
      return;
    }
    const uint32_t uploads = ++state_->uploads_in_progress;
    in_progress_ = true;
    absl::Status admission = absl::OkStatus();
    if (state_->shutting_down) {
      admission = Unavailable();
    } else if (uploads > state_->options.max_concurrent_uploads) {
      admission = absl::ResourceExhaustedError(
          absl::StrCat("uploads: more than the max_concurrent_uploads limit (",
                       state_->options.max_concurrent_uploads, ") at once; retry later"));
    } else if (!state_->principal_uploads.TryAcquire((*principal)->name,
                                                     (*principal)->max_uploads)) {
      admission = absl::ResourceExhaustedError(
          absl::StrCat("uploads: token \"", (*principal)->name, "\" has its max_uploads (",
                       (*principal)->max_uploads.value_or(0), ") uploads in progress"));
    } else {
      principal_ = (*principal)->name;
      counted_ = true;
      admission = state_->store->CheckRoom();
    }
    if (!admission.ok()) {
      Done(admission);
      return;
    }
    StartRead(&request_);
  }

  void OnReadDone(bool ok) override {
    if (ok) {
      absl::Status st;
      if (request_.has_manifest()) {
        st = assembler_.Begin(request_.manifest());
      } else if (request_.has_chunk()) {
        st = assembler_.Add(request_.mutable_chunk());
      } else {
        st = absl::InvalidArgumentError("UploadRequest: has neither manifest nor chunk");
      }
      if (!st.ok()) return Done(st);
      StartRead(&request_);
      return;
    }
    if (ctx_->IsCancelled()) return Done(absl::CancelledError("client cancelled the upload"));
    if (state_->shutting_down) return Done(Unavailable());
    std::string scene_id;
    absl::StatusOr<GltfSource> source = assembler_.Finish(&scene_id);
    if (!source.ok()) return Done(source.status());
    if (std::shared_ptr<StoredScene> existing = state_->store->FindExact(scene_id)) {
      *response_ = existing->info;  // same content: nothing to parse
      SceneStore::FillLiveFields(*existing, response_);
      existing.reset();  // not held while the client hears back (eviction)
      if (state_->jobs && state_->jobs->options().persistent)
        state_->loader->Submit([jobs = state_->jobs, scene_id,
                                src = std::make_shared<GltfSource>(*std::move(source))] {
          jobs->ArchiveScene(scene_id, *src);
        });
      return Done(absl::OkStatus(), "already loaded");
    }
    // Parsing and the device upload can take seconds: off the gRPC thread.
    state_->loader->Submit(
        [this, scene_id, src = std::make_shared<GltfSource>(*std::move(source))] {
          Load(scene_id, *src);
        });
  }

  void OnDone() override {
    if (in_progress_) --state_->uploads_in_progress;
    if (counted_) state_->principal_uploads.Release(principal_);
    delete this;
  }

 private:
  void Load(const std::string& scene_id, const GltfSource& source) {
    if (state_->shutting_down) return Done(Unavailable());
    if (std::chrono::system_clock::now() >= ctx_->deadline())
      return Done(absl::DeadlineExceededError("deadline: passed before the scene was parsed"));
    if (ctx_->IsCancelled()) return Done(absl::CancelledError("client cancelled the upload"));
    absl::StatusOr<std::shared_ptr<StoredScene>> stored =
        LoadIntoStore(state_->renderer, state_->store, scene_id, source,
                      {state_->options.import_limits, state_->options.max_scene_device_bytes});
    if (!stored.ok()) return Done(stored.status());
    *response_ = (*stored)->info;
    SceneStore::FillLiveFields(**stored, response_);
    stored->reset();  // before the client hears back: an unused scene is evictable at once
    // A persistent daemon keeps the files for its jobs, before the client hears back, so a
    // job submitted next finds them even if the scene is evicted meanwhile.
    if (state_->jobs) state_->jobs->ArchiveScene(scene_id, source);
    Done(absl::OkStatus(), "loaded");
  }

  void Done(const absl::Status& st, const char* what = "") {
    Log().info("UploadScene {} ({} files, {} of {} bytes) -> {} {} ({:.1f} ms) peer={}",
               response_->scene_id().empty() ? assembler_.main_file() : response_->scene_id(),
               assembler_.file_count(), assembler_.received_bytes(), assembler_.declared_bytes(),
               st.ok() ? "OK" : st.ToString(), what, MsSince(started_), Peer(ctx_));
    state_->CountRpc("UploadScene", ToGrpc(st));
    if (state_->metrics)
      state_->metrics->UploadFinished(!st.ok()                         ? "error"
                                      : std::string_view(what) == "loaded" ? "loaded"
                                                                           : "cached",
                                      assembler_.received_bytes());
    Finish(ToGrpc(st));
  }

  ServiceState* state_;
  grpc::CallbackServerContext* ctx_;
  v1::SceneInfo* response_;
  UploadAssembler assembler_;
  v1::UploadRequest request_;
  Clock::time_point started_;
  std::string principal_;  // counted against its max_uploads while counted_
  bool counted_ = false;
  bool in_progress_ = false;  // counted in uploads_in_progress
};

grpc::ServerReadReactor<v1::UploadRequest>* RenderServiceImpl::UploadScene(
    grpc::CallbackServerContext* ctx, v1::SceneInfo* response) {
  return new UploadReactor(state_, ctx, response);
}

// ---------------------------------------------------------------------------------------------
// Small unary calls: answered on the gRPC thread from in-memory state.

grpc::ServerUnaryReactor* Reply(const ServiceState* state, grpc::CallbackServerContext* ctx,
                                const char* method, const absl::Status& status) {
  grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
  state->CountRpc(method, ToGrpc(status));
  reactor->Finish(ToGrpc(status));
  return reactor;
}

grpc::ServerUnaryReactor* RenderServiceImpl::GetServerInfo(grpc::CallbackServerContext* ctx,
                                                           const v1::GetServerInfoRequest*,
                                                           v1::ServerInfo* r) {
  if (absl::Status st = state_->Authorize(ctx).status(); !st.ok())
    return Reply(state_, ctx, "GetServerInfo", st);
  const DeviceInfo& d = state_->renderer->device_info();
  const ServerOptions& o = state_->options;
  r->set_version(TESSERA_VERSION);
  v1::DeviceDescription* dev = r->mutable_device();
  dev->set_name(d.name);
  dev->set_type(d.type);
  dev->set_driver_name(d.driver_name);
  dev->set_driver_info(d.driver_info);
  dev->set_api_version(d.api_version);
  v1::Limits* l = r->mutable_limits();
  const DeviceCaps caps = state_->renderer->caps();
  l->set_max_samples(std::min(caps.max_samples, kMaxSamples));  // as SettingChoices.samples
  l->set_max_width(std::min(caps.max_image_dimension, 16384u));
  l->set_max_height(std::min(caps.max_image_dimension, 16384u));
  l->set_max_upload_bytes(o.max_upload_bytes);
  l->set_max_upload_files(o.max_upload_files);
  l->set_max_chunk_bytes(o.max_chunk_bytes);
  l->set_max_scenes(o.max_scenes);
  l->set_max_sessions(o.max_sessions);
  l->set_max_synthetic_lights(65536);
  r->set_uptime_s(MsSince(state_->started) / 1000.0);
  r->set_scenes_loaded(state_->store->count());
  r->set_active_sessions(state_->session_count());
  r->set_queue_depth(state_->loop->queue_depth());
  r->set_frames_rendered(state_->loop->frames_rendered());
  FillChoices(caps.sample_counts != 0 ? caps.sample_counts : caps.max_samples * 2 - 1,
              r->mutable_choices());
  ToProto(state_->default_settings, r->mutable_default_settings());
  l->set_max_session_fps(o.max_session_fps);
  l->set_scene_memory_budget_bytes(o.scene_memory_budget_bytes);
  l->set_resume_grace_s(o.resume_grace_s);
  l->set_max_frames_in_flight(state_->loop->options().max_frames_in_flight);
  r->set_parked_sessions(state_->parked_count());
  r->set_background_queue_depth(state_->loop->background_queue_depth());
  r->set_frames_in_flight(state_->loop->frames_in_flight());
  r->set_scene_device_bytes(state_->store->device_bytes());
  r->set_auth_required(state_->auth->enabled());
  r->set_tls(!o.tls_cert_file.empty());
  l->set_max_jobs(o.max_jobs);
  l->set_max_job_frames(o.max_job_frames);
  ImportLimitsToProto(o.import_limits, l->mutable_scene_import());
  l->set_max_scene_device_bytes(o.max_scene_device_bytes);
  r->set_jobs_active(state_->jobs->active());
  r->set_job_output_root(!o.job_output_root.empty());
  r->set_jobs_persistent(!o.state_dir.empty());
  r->set_device_memory_bytes(Renderer::DeviceMemoryBytes());
  Log().debug("GetServerInfo peer={}", Peer(ctx));
  return Reply(state_, ctx, "GetServerInfo", absl::OkStatus());
}

grpc::ServerUnaryReactor* RenderServiceImpl::HasScene(grpc::CallbackServerContext* ctx,
                                                      const v1::HasSceneRequest* req,
                                                      v1::HasSceneResponse* r) {
  if (absl::Status st = state_->Authorize(ctx).status(); !st.ok())
    return Reply(state_, ctx, "HasScene", st);
  if (req->scene_id().empty())
    return Reply(state_, ctx, "HasScene", absl::InvalidArgumentError("scene_id: is empty"));
  if (std::shared_ptr<StoredScene> s = state_->store->FindExact(req->scene_id())) {
    r->set_present(true);
    *r->mutable_info() = s->info;
    SceneStore::FillLiveFields(*s, r->mutable_info());
  }
  Log().info("HasScene {} -> {} peer={}", req->scene_id().substr(0, 80), r->present(), Peer(ctx));
  return Reply(state_, ctx, "HasScene", absl::OkStatus());
}

grpc::ServerUnaryReactor* RenderServiceImpl::ListScenes(grpc::CallbackServerContext* ctx,
                                                        const v1::ListScenesRequest*,
                                                        v1::ListScenesResponse* r) {
  if (absl::Status st = state_->Authorize(ctx).status(); !st.ok())
    return Reply(state_, ctx, "ListScenes", st);
  for (v1::SceneInfo& info : state_->store->List()) *r->add_scenes() = std::move(info);
  Log().info("ListScenes -> {} scenes peer={}", r->scenes_size(), Peer(ctx));
  return Reply(state_, ctx, "ListScenes", absl::OkStatus());
}

grpc::ServerUnaryReactor* RenderServiceImpl::DeleteScene(grpc::CallbackServerContext* ctx,
                                                         const v1::DeleteSceneRequest* req,
                                                         v1::DeleteSceneResponse* r) {
  if (absl::Status st = state_->Authorize(ctx).status(); !st.ok())
    return Reply(state_, ctx, "DeleteScene", st);
  absl::StatusOr<uint32_t> users = state_->store->Delete(req->scene_id());
  Log().info("DeleteScene {} -> {} peer={}", req->scene_id().substr(0, 80),
             users.ok() ? absl::StrCat("OK, ", *users, " sessions still using it")
                        : users.status().ToString(),
             Peer(ctx));
  if (users.ok()) r->set_sessions_still_using(*users);
  if (users.ok() && state_->jobs && state_->jobs->options().persistent)
    state_->loader->Submit([jobs = state_->jobs] { jobs->PruneArchive(); });
  return Reply(state_, ctx, "DeleteScene", users.status());
}

}  // namespace tessera::server
