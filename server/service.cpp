#include "server/service.h"

#include <cmath>
#include <optional>

#include "absl/strings/str_cat.h"
#include "renderer/log.h"
#include "renderer/scene/gltf_import.h"
#include "server/convert.h"
#include "server/upload.h"

namespace tessera::server {
namespace {

constexpr uint32_t kMaxQueuedRenders = 64;  // unary renders waiting for the render thread
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
              grpc::ServerUnaryReactor* reactor, v1::Frame* response, RenderWork work)
      : state_(state), ctx_(ctx), reactor_(reactor), response_(response), work_(std::move(work)) {}

  std::optional<RenderWork> TakeWork() override {
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
    Log().info("Render scene={} {}x{} -> {} bytes, {} ({:.1f} ms) peer={}", work_.scene_id,
               work_.settings.width, work_.settings.height, response_->data().size(),
               status.ok() ? "OK" : status.ToString(), MsSince(work_.requested), Peer(ctx_));
    reactor_->Finish(ToGrpc(status));
  }

  ServiceState* state_;
  grpc::CallbackServerContext* ctx_;
  grpc::ServerUnaryReactor* reactor_;
  v1::Frame* response_;
  RenderWork work_;
  std::atomic<bool> finished_{false};
};

grpc::ServerUnaryReactor* RenderServiceImpl::Render(grpc::CallbackServerContext* ctx,
                                                    const v1::RenderRequest* req,
                                                    v1::Frame* response) {
  grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
  auto fail = [&](const absl::Status& st) {
    Log().info("Render scene={} -> {} peer={}", req->scene_id().substr(0, 80), st.ToString(),
               Peer(ctx));
    reactor->Finish(ToGrpc(st));
    return reactor;
  };
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
  state_->loop->Enqueue(
      std::make_shared<UnaryRender>(state_, ctx, reactor, response, std::move(work)));
  return reactor;
}

// ---------------------------------------------------------------------------------------------
// Stream: a session. Everything that changes session state happens under mu_, which decides
// what to do next (write, enqueue, finish); the gRPC calls and the render-loop calls happen
// after unlocking, so reactions that run inline cannot deadlock.

class StreamSession final : public grpc::ServerBidiReactor<v1::ClientEvent, v1::Frame>,
                            public RenderClient,
                            public std::enable_shared_from_this<StreamSession> {
 public:
  StreamSession(ServiceState* state, grpc::CallbackServerContext* ctx)
      : state_(state), ctx_(ctx), id_(state->next_session_id++), opened_at_(Clock::now()) {}

  // After construction by make_shared: the reactor keeps itself alive until OnDone.
  void Begin(const absl::Status& admission) {
    self_ = shared_from_this();
    if (!admission.ok()) {
      Log().info("Stream session={} refused: {} peer={}", id_, admission.ToString(), Peer(ctx_));
      finished_ = true;  // nothing else runs before the reactor is returned
      Finish(ToGrpc(admission));
      return;
    }
    StartRead(&event_);
  }

  void OnReadDone(bool ok) override {
    Actions actions;
    bool read_more = false;
    {
      std::lock_guard lock(mu_);
      if (!ok) {
        reading_done_ = true;  // the client half-closed (or went away: OnCancel says which)
      } else if (!finished_) {
        absl::Status st = opened_ ? ApplyUpdateLocked() : OpenLocked();
        if (!st.ok() && !error_) {
          Log().info("Stream session={} event={}: {}", id_, event_.event_id(), st.ToString());
          error_ = st;
        }
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
      state_->sessions.erase(keep);
    }
    {
      std::lock_guard lock(mu_);
      if (slot_) state_->pending_frame_bytes -= slot_->data().size();
      slot_.reset();
      lease_.reset();  // a deleted scene is freed with its last session
    }
    Log().info("Stream session={} ended: {} frames sent, {} dropped, {:.1f} s, {}", id_,
               frames_sent_, frames_dropped_, MsSince(opened_at_) / 1000.0, end_status_);
  }

  std::optional<RenderWork> TakeWork() override {
    Actions actions;
    std::optional<RenderWork> work;
    {
      std::lock_guard lock(mu_);
      // The loop cannot say whether a ready entry or a timer brought us here: clear both; a
      // stale duplicate entry only costs a TakeWork that finds nothing due.
      in_ready_ = false;
      timer_armed_ = false;
      if (CanRenderLocked() && DueLocked(Clock::now())) work = MakeWorkLocked();
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
        timer_armed_ = false;
        stopping_ = true;
      } else {
        --in_pipeline_;
      }
      if (!frame.ok()) {
        if (frame.status().code() == absl::StatusCode::kUnavailable)
          stopping_ = true;
        else if (!error_)
          error_ = frame.status();
      } else if (!finished_ && !cancelled_) {
        if (frame->sequence() < newest_delivered_) {
          Drop();  // a newer frame overtook it in the encoder pool
        } else {
          if (slot_) {
            state_->pending_frame_bytes -= slot_->data().size();
            Drop();  // the client has not taken the previous one yet: latest wins
          }
          newest_delivered_ = frame->sequence();
          state_->pending_frame_bytes += frame->data().size();
          frame->set_profile("full");
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
    if (absl::Status st = CheckTargetFps(open.target_fps(), "open.target_fps"); !st.ok()) return st;
    lease_ = std::make_unique<SceneLease>(*scene);
    settings_ = *settings;
    camera_ = open.camera();
    target_fps_ = open.target_fps();
    next_due_ = Clock::now();  // the first tick is the first frame; the cadence starts there
    opened_ = true;
    MarkDirtyLocked();
    Log().info("Stream session={} opened scene={} {}x{} fps={} peer={}", id_, (*scene)->id,
               settings_.width, settings_.height, target_fps_, Peer(ctx_));
    return absl::OkStatus();
  }

  absl::Status ApplyUpdateLocked() {
    if (event_.has_open()) return absl::InvalidArgumentError("open: the session is already open");
    Settings settings = settings_;
    if (event_.has_settings()) {
      absl::StatusOr<Settings> merged = MergeSettings(settings_, event_.settings());
      if (!merged.ok()) return merged.status();
      settings = *merged;
    }
    if (event_.has_camera()) {
      absl::StatusOr<Camera> camera =
          ResolveCamera(event_.camera(), lease_->get().scene->info(), Aspect(settings));
      if (!camera.ok()) return camera.status();
      camera_ = event_.camera();
    }
    if (event_.has_target_fps()) {
      if (absl::Status st = CheckTargetFps(event_.target_fps(), "target_fps"); !st.ok()) return st;
      target_fps_ = event_.target_fps();
      next_due_ = Clock::now();
    }
    settings_ = settings;
    if (event_.has_settings() || event_.has_camera() || event_.refresh()) MarkDirtyLocked();
    return absl::OkStatus();
  }

  void MarkDirtyLocked() {
    if (!dirty_) dirty_since_ = Clock::now();
    dirty_ = true;
    newest_event_ = event_.event_id();
  }

  bool CanRenderLocked() const {
    return opened_ && !finished_ && !cancelled_ && !stopping_ && !error_ && in_pipeline_ < 2 &&
           !slot_;
  }
  bool ContinuousLocked() const { return target_fps_ > 0.0f && !reading_done_; }
  bool DueLocked(Clock::time_point now) const {
    return dirty_ || (ContinuousLocked() && now >= next_due_);
  }

  RenderWork MakeWorkLocked() {
    const Clock::time_point now = Clock::now();
    RenderWork w;
    w.scene = lease_->get().scene;
    w.scene_id = lease_->get().id;
    w.view = id_;
    w.settings = settings_;
    // Validated when the event arrived; framing depends only on the scene and aspect ratio.
    absl::StatusOr<Camera> camera = ResolveCamera(camera_, w.scene->info(), Aspect(settings_));
    w.camera = camera.ok() ? *camera : Camera{};
    w.format = ImageFormat::kJpeg;
    w.sequence = ++sequence_;
    w.event_id = newest_event_;
    w.requested = dirty_ ? dirty_since_ : std::min(now, next_due_);
    dirty_ = false;
    if (ContinuousLocked()) {
      const auto period = std::chrono::duration_cast<Clock::duration>(
          std::chrono::duration<double>(1.0 / target_fps_));
      // Keep the cadence, but never try to catch up on frames missed while busy.
      next_due_ = std::max(next_due_ + period, now);
    }
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
    if (CanRenderLocked()) {
      // A change jumps the queue even while a continuous session waits for its next tick.
      if (!in_ready_ && DueLocked(Clock::now())) {
        in_ready_ = true;
        a.enqueue = true;
      } else if (!in_ready_ && !timer_armed_ && ContinuousLocked()) {
        timer_armed_ = true;
        a.enqueue_at = next_due_;
      }
    }
    if (writing_) return a;  // never finish with a write outstanding
    const bool idle = in_pipeline_ == 0 && !slot_;
    std::optional<grpc::Status> finish;
    if (cancelled_) {
      finish = grpc::Status(grpc::StatusCode::CANCELLED, "client cancelled the stream");
    } else if (error_) {
      finish = ToGrpc(*error_);
    } else if (stopping_ && idle) {
      finish = ToGrpc(Unavailable());
    } else if (reading_done_ && idle && !dirty_) {
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
    if (a.finish) Finish(*a.finish);
  }

  ServiceState* const state_;
  grpc::CallbackServerContext* const ctx_;
  const uint64_t id_;
  const Clock::time_point opened_at_;
  std::shared_ptr<StreamSession> self_;  // until OnDone
  v1::ClientEvent event_;                // read buffer (one read at a time)

  std::mutex mu_;
  bool opened_ = false;
  std::unique_ptr<SceneLease> lease_;
  Settings settings_;
  v1::Camera camera_;
  float target_fps_ = 0.0f;
  uint64_t newest_event_ = 0;
  bool dirty_ = false;
  Clock::time_point dirty_since_;
  Clock::time_point next_due_;
  bool in_ready_ = false;     // in the render loop's ready queue
  bool timer_armed_ = false;  // a render-loop timer will bring it back (continuous mode)
  int in_pipeline_ = 0;       // frames being rendered or encoded
  uint64_t sequence_ = 0;
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
  auto session = std::make_shared<StreamSession>(state_, ctx);
  absl::Status admission = absl::OkStatus();
  {
    // Under the lock ShutdownSessions takes, so no session slips in after its snapshot.
    std::lock_guard lock(state_->sessions_mu);
    if (state_->shutting_down)
      admission = Unavailable();
    else if (state_->sessions.size() >= state_->options.max_sessions)
      admission = absl::ResourceExhaustedError(absl::StrCat(
          "sessions: ", state_->sessions.size(), " open streams reach the max_sessions limit (",
          state_->options.max_sessions, ")"));
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

void ServiceState::ShutdownSessions() {
  std::vector<std::shared_ptr<StreamSession>> open;
  {
    std::lock_guard lock(sessions_mu);
    shutting_down = true;
    open.assign(sessions.begin(), sessions.end());
  }
  for (auto& s : open) s->Stop();
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
    const uint32_t uploads = ++state_->uploads_in_progress;
    absl::Status admission = absl::OkStatus();
    if (state_->shutting_down) {
      admission = Unavailable();
    } else if (uploads > state_->options.max_concurrent_uploads) {
      admission = absl::ResourceExhaustedError(
          absl::StrCat("uploads: more than the max_concurrent_uploads limit (",
                       state_->options.max_concurrent_uploads, ") at once; retry later"));
    } else {
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
      return Done(absl::OkStatus(), "already loaded");
    }
    // Parsing and the device upload can take seconds: off the gRPC thread.
    state_->loader->Submit(
        [this, scene_id, src = std::make_shared<GltfSource>(*std::move(source))] {
          Load(scene_id, *src);
        });
  }

  void OnDone() override {
    --state_->uploads_in_progress;
    delete this;
  }

 private:
  void Load(const std::string& scene_id, const GltfSource& source) {
    if (state_->shutting_down) return Done(Unavailable());
    const Clock::time_point t0 = Clock::now();
    absl::StatusOr<CpuScene> cpu = ImportGltf(source);
    if (!cpu.ok()) return Done(cpu.status());
    absl::StatusOr<SceneHandle> gpu = state_->renderer->LoadScene(*cpu);
    if (!gpu.ok()) return Done(gpu.status());
    v1::SceneInfo info;
    ToProto((*gpu)->info(), &info);
    info.set_name(source.main_file);
    uint64_t bytes = 0;
    for (const auto& [name, data] : source.files) bytes += data.size();
    info.set_upload_bytes(bytes);
    info.set_load_ms(MsSince(t0));
    absl::StatusOr<std::shared_ptr<StoredScene>> stored =
        state_->store->Add(scene_id, *std::move(gpu), std::move(info));
    if (!stored.ok()) return Done(stored.status());
    *response_ = (*stored)->info;
    SceneStore::FillLiveFields(**stored, response_);
    Done(absl::OkStatus(), "loaded");
  }

  void Done(const absl::Status& st, const char* what = "") {
    Log().info("UploadScene {} ({} files, {} of {} bytes) -> {} {} ({:.1f} ms) peer={}",
               response_->scene_id().empty() ? assembler_.main_file() : response_->scene_id(),
               assembler_.file_count(), assembler_.received_bytes(), assembler_.declared_bytes(),
               st.ok() ? "OK" : st.ToString(), what, MsSince(started_), Peer(ctx_));
    Finish(ToGrpc(st));
  }

  ServiceState* state_;
  grpc::CallbackServerContext* ctx_;
  v1::SceneInfo* response_;
  UploadAssembler assembler_;
  v1::UploadRequest request_;
  Clock::time_point started_;
};

grpc::ServerReadReactor<v1::UploadRequest>* RenderServiceImpl::UploadScene(
    grpc::CallbackServerContext* ctx, v1::SceneInfo* response) {
  return new UploadReactor(state_, ctx, response);
}

// ---------------------------------------------------------------------------------------------
// Small unary calls: answered on the gRPC thread from in-memory state.

grpc::ServerUnaryReactor* RenderServiceImpl::GetServerInfo(grpc::CallbackServerContext* ctx,
                                                           const v1::GetServerInfoRequest*,
                                                           v1::ServerInfo* r) {
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
  l->set_max_samples(caps.max_samples);
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
  Log().debug("GetServerInfo peer={}", Peer(ctx));
  grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
  reactor->Finish(grpc::Status::OK);
  return reactor;
}

grpc::ServerUnaryReactor* RenderServiceImpl::HasScene(grpc::CallbackServerContext* ctx,
                                                      const v1::HasSceneRequest* req,
                                                      v1::HasSceneResponse* r) {
  grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
  if (req->scene_id().empty()) {
    reactor->Finish(ToGrpc(absl::InvalidArgumentError("scene_id: is empty")));
    return reactor;
  }
  if (std::shared_ptr<StoredScene> s = state_->store->FindExact(req->scene_id())) {
    r->set_present(true);
    *r->mutable_info() = s->info;
    SceneStore::FillLiveFields(*s, r->mutable_info());
  }
  Log().info("HasScene {} -> {} peer={}", req->scene_id().substr(0, 80), r->present(), Peer(ctx));
  reactor->Finish(grpc::Status::OK);
  return reactor;
}

grpc::ServerUnaryReactor* RenderServiceImpl::ListScenes(grpc::CallbackServerContext* ctx,
                                                        const v1::ListScenesRequest*,
                                                        v1::ListScenesResponse* r) {
  for (v1::SceneInfo& info : state_->store->List()) *r->add_scenes() = std::move(info);
  Log().info("ListScenes -> {} scenes peer={}", r->scenes_size(), Peer(ctx));
  grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
  reactor->Finish(grpc::Status::OK);
  return reactor;
}

grpc::ServerUnaryReactor* RenderServiceImpl::DeleteScene(grpc::CallbackServerContext* ctx,
                                                         const v1::DeleteSceneRequest* req,
                                                         v1::DeleteSceneResponse* r) {
  absl::StatusOr<uint32_t> users = state_->store->Delete(req->scene_id());
  Log().info("DeleteScene {} -> {} peer={}", req->scene_id().substr(0, 80),
             users.ok() ? absl::StrCat("OK, ", *users, " sessions still using it")
                        : users.status().ToString(),
             Peer(ctx));
  if (users.ok()) r->set_sessions_still_using(*users);
  grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
  reactor->Finish(ToGrpc(users.status()));
  return reactor;
}

}  // namespace tessera::server
