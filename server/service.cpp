#include "server/service.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <optional>

#include "absl/strings/str_cat.h"
#include "common/status_macros.h"
#include "renderer/log.h"
#include "renderer/scene/gltf_import.h"
#include "server/convert.h"
#include "common/job_spec.h"
#include "common/video.h"
#include "server/jobs.h"
#include "server/fs_util.h"
#include "server/metrics.h"
#include "server/scene_archive.h"
#include "server/upload.h"

namespace tessera::server {
namespace {

std::string Peer(grpc::CallbackServerContext* ctx) { return ctx->peer(); }

}  // namespace

double MsSince(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

float Aspect(const Settings& s) { return float(s.width) / float(s.height); }

absl::Status Unavailable() { return absl::UnavailableError("server is shutting down"); }

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

  void Deliver(const RenderWork&, absl::StatusOr<EncodedFrame> frame) override {
    if (frame.ok()) ToProto(*frame, response_);
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

namespace {

// The frame a Render request asks for, once everything the client sent is checked.
absl::StatusOr<RenderWork> RenderRequestWork(const ServiceState& state,
                                             const v1::RenderRequest& req) {
  ASSIGN_OR_RETURN(std::shared_ptr<StoredScene> scene, state.store->Find(req.scene_id()));
  RenderWork work;
  ASSIGN_OR_RETURN(work.settings, MergeSettings(state.default_settings, req.settings()));
  ASSIGN_OR_RETURN(work.camera,
                   ResolveCamera(req.camera(), scene->scene->info(), Aspect(work.settings)));
  if (!v1::ImageEncoding_IsValid(req.encoding()))
    return absl::InvalidArgumentError(
        absl::StrCat("encoding: unknown value ", static_cast<int>(req.encoding())));
  if (req.encoding() == v1::VIDEO_H264)
    return absl::InvalidArgumentError(
        "encoding: VIDEO_H264 is for Stream sessions (OpenSession.video); a Render is one "
        "image: IMAGE_JPEG or IMAGE_PNG");
  work.scene = scene->scene;
  work.scene_id = scene->id;
  work.format = req.encoding() == v1::IMAGE_PNG ? ImageFormat::kPng : ImageFormat::kJpeg;
  work.sequence = 1;
  work.kind = req.background() ? "background" : "render";
  if (work.settings.aa == AaMode::kTaa) {
    // TAA in one call: a view of its own, from an empty history, accumulated as a resting
    // stream or a job frame would be, so the same request gives the same bytes (not whatever
    // the shared default view's last frame left).
    work.view = state.jobs->NewView();
    work.fresh_view = true;
    work.accumulate = jobs::kDefaultTaaFrames;
  }
  return work;
}

}  // namespace

grpc::ServerUnaryReactor* RenderServiceImpl::Render(grpc::CallbackServerContext* ctx,
                                                    const v1::RenderRequest* req,
                                                    v1::Frame* response) {
  grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
  ServiceState* state = state_;
  auto fail = [state, ctx, req, reactor](const absl::Status& st) {
    Log().info("Render scene={} -> {} peer={}", req->scene_id().substr(0, 80), st.ToString(),
               Peer(ctx));
    state->CountRpc("Render", ToGrpc(st));
    reactor->Finish(ToGrpc(st));
  };
  // After the scene is in memory (at once, or loaded from the shared scene store). The render
  // holds its place in the queue's limit from before the load, so renders waiting on loads
  // are bounded too.
  auto render = [state, ctx, req, response, reactor, fail](const absl::Status& loaded) {
    absl::StatusOr<RenderWork> work =
        loaded.ok() ? RenderRequestWork(*state, *req)
                    : absl::StatusOr<RenderWork>(files::WithPrefix(loaded, "scene_id: "));
    if (!work.ok()) {
      --state->unary_queued;
      return fail(work.status());
    }
    work->requested = Clock::now();
    state->loop->Enqueue(
        MakeUnaryRender(state, ctx, reactor, response, *std::move(work), "Render"),
        req->background() ? Priority::kBackground : Priority::kNormal);
  };
  if (absl::Status st = state_->Authorize(ctx).status(); !st.ok()) {
    fail(st);
  } else if (state_->shutting_down) {
    fail(Unavailable());
  } else if (state_->unary_queued.fetch_add(1) >= kMaxQueuedRenders) {
    --state_->unary_queued;
    fail(absl::ResourceExhaustedError(absl::StrCat(
        "render queue: ", kMaxQueuedRenders, " renders are waiting (limit); retry later")));
  } else {
    state_->EnsureSceneLoaded(req->scene_id(), std::move(render));
  }
  return reactor;
}

void ServiceState::EnsureSceneLoaded(const std::string& scene_id,
                                     std::function<void(absl::Status)> then) {
  if (!jobs || store->FindExact(scene_id) || !jobs->HasArchived(scene_id))
    return then(absl::OkStatus());
  jobs->LoadArchived(scene_id, [then = std::move(then)](
                                   absl::StatusOr<std::shared_ptr<StoredScene>> s) {
    // The caller finds it in the store; not held meanwhile (an unused scene is evictable).
    then(s.status());
  });
}

bool ServiceState::AcceptingSessions(std::optional<bool> serving) const {
  if (shutting_down || session_count() >= options.max_sessions) return false;
  if (serving) return *serving;
  return !health || health().serving;
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
      const uint32_t allowed = (*principal)->max_uploads.value_or(0);
      admission = absl::ResourceExhaustedError(
          allowed == 0
              ? absl::StrCat("uploads: token \"", (*principal)->name,
                             "\" may not upload (max_uploads=0 in the token file)")
              : absl::StrCat("uploads: token \"", (*principal)->name, "\" already has ",
                             allowed, " uploads in progress, its max_uploads; retry when one "
                             "ends"));
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
      ToProto(SceneStore::Describe(*existing), response_);  // same content: nothing to parse
      existing.reset();  // not held while the client hears back (eviction)
      auto src = std::make_shared<GltfSource>(*std::move(source));
      if (state_->shared_scenes && !state_->shared_scenes->Has(scene_id)) {
        // Loaded here before the store had it (or the store evicted it): saved there before
        // the client hears back, as a new upload is.
        state_->loader->Submit([this, scene_id, src] {
          Share(scene_id, *src);
          if (state_->jobs) state_->jobs->ArchiveScene(scene_id, *src);
          Done(absl::OkStatus(), "already loaded");
        });
        return;
      }
      if (state_->jobs && state_->jobs->options().persistent)
        state_->loader->Submit(
            [jobs = state_->jobs, scene_id, src] { jobs->ArchiveScene(scene_id, *src); });
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
    ToProto(SceneStore::Describe(**stored), response_);
    stored->reset();  // before the client hears back: an unused scene is evictable at once
    // Replicas sharing a scene store find it there, and a persistent daemon keeps the files
    // for its jobs, before the client hears back: a stream or job that another replica (or
    // this one, after an eviction) opens next finds them.
    Share(scene_id, source);
    if (state_->jobs) state_->jobs->ArchiveScene(scene_id, source);
    Done(absl::OkStatus(), "loaded");
  }

  // Saves the upload in the shared scene store (--scene_store_dir), if there is one. A failure
  // (a full disk, a scene larger than the store) does not fail the upload, which this replica
  // has: the client gets a warning that other replicas cannot load it.
  void Share(const std::string& scene_id, const GltfSource& source) {
    if (!state_->shared_scenes) return;
    const Clock::time_point t0 = Clock::now();
    absl::Status st = state_->shared_scenes->Save(scene_id, source);
    Log().info("scene {}: shared scene store: {} ({:.1f} ms)", scene_id.substr(0, 16),
               st.ok() ? "saved" : st.ToString(), MsSince(t0));
    if (!st.ok())
      response_->add_warnings(absl::StrCat(
          "scene_store_dir: not saved, so other replicas cannot load this scene: ",
          st.message()));
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
  for (const DeviceFallback& f : d.fallbacks) {
    v1::DeviceFallback* out = dev->add_fallbacks();
    out->set_missing(f.missing);
    out->set_path(f.path);
  }
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
  if (state_->health) {
    const ServerHealth h = state_->health();
    r->set_serving(h.serving);
    r->set_unhealthy_reason(h.reason);
  }
  for (std::string_view e : SupportedGltfExtensions()) r->add_gltf_extensions(std::string(e));
  for (const std::string& e : video::EncoderNames()) r->add_video_encoders(e);
  r->set_scene_store(state_->shared_scenes != nullptr);
  r->set_accepting_sessions(state_->AcceptingSessions());
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
    ToProto(SceneStore::Describe(*s), r->mutable_info());
  } else if (state_->shared_scenes && state_->shared_scenes->Has(req->scene_id())) {
    r->set_present(true);  // any Render, Stream or job here loads it from the store
  }
  Log().info("HasScene {} -> {} peer={}", req->scene_id().substr(0, 80), r->present(), Peer(ctx));
  return Reply(state_, ctx, "HasScene", absl::OkStatus());
}

grpc::ServerUnaryReactor* RenderServiceImpl::ListScenes(grpc::CallbackServerContext* ctx,
                                                        const v1::ListScenesRequest*,
                                                        v1::ListScenesResponse* r) {
  if (absl::Status st = state_->Authorize(ctx).status(); !st.ok())
    return Reply(state_, ctx, "ListScenes", st);
  for (const SceneListing& scene : state_->store->List()) ToProto(scene, r->add_scenes());
  Log().info("ListScenes -> {} scenes peer={}", r->scenes_size(), Peer(ctx));
  return Reply(state_, ctx, "ListScenes", absl::OkStatus());
}

grpc::ServerUnaryReactor* RenderServiceImpl::DeleteScene(grpc::CallbackServerContext* ctx,
                                                         const v1::DeleteSceneRequest* req,
                                                         v1::DeleteSceneResponse* r) {
  if (absl::Status st = state_->Authorize(ctx).status(); !st.ok())
    return Reply(state_, ctx, "DeleteScene", st);
  // The full id, for the shared store (which a unique prefix of a loaded scene also names).
  std::string full_id = req->scene_id();
  if (absl::StatusOr<std::shared_ptr<StoredScene>> s = state_->store->Find(full_id); s.ok())
    full_id = (*s)->id;
  absl::StatusOr<uint32_t> users = state_->store->Delete(req->scene_id());
  if (state_->shared_scenes && SceneArchive::ValidSceneId(full_id) &&
      (users.ok() || (absl::IsNotFound(users.status()) && state_->shared_scenes->Has(full_id)))) {
    // Gone for every replica's new requests; their loaded copies go when they evict them.
    if (absl::Status st = state_->shared_scenes->Remove(full_id); !st.ok()) {
      users = absl::Status(st.code(), absl::StrCat("scene_store_dir: ", st.message()));
    } else if (!users.ok()) {
      users = 0u;
    }
  }
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
