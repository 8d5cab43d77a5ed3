#pragma once
// The RenderService handlers (gRPC callback API). Handlers validate the request, then hand
// work to the render loop, the loader pool or the scene store; none of them blocks a gRPC
// thread on rendering, parsing or device uploads.
#include <atomic>
#include <chrono>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>

#include "renderer/renderer.h"
#include "server/auth.h"
#include "server/convert.h"
#include "server/render_loop.h"
#include "server/scene_store.h"
#include "server/server.h"
#include "tessera/v1/render_service.grpc.pb.h"

namespace tessera::server {

class StreamSession;
class Metrics;
class JobManager;
class SceneArchive;

// A session apart from its stream: what a resumed stream gets back.
// A session's renderer view (its TAA history, occlusion bits, exposure): forgotten when the last
// holder lets go, i.e. when the session ends for good (closed, or parked and not resumed).
// Streams never rendered with fresh views, so each one's state used to stay with the scene.
class ViewLease {
 public:
  ViewLease(Renderer* renderer, SceneHandle scene, uint64_t view)
      : renderer_(renderer), scene_(std::move(scene)), view_(view) {}
  ~ViewLease() {
    if (renderer_ && scene_) renderer_->ForgetView(*scene_, view_);
  }
  ViewLease(const ViewLease&) = delete;
  ViewLease& operator=(const ViewLease&) = delete;

 private:
  Renderer* renderer_;
  SceneHandle scene_;
  uint64_t view_;
};

struct SessionState {
  uint64_t id = 0;        // the session id, also its renderer view (TAA, occlusion history)
  std::shared_ptr<ViewLease> view;  // forgets the view with the last holder (see ViewLease)
  std::string token;      // resume token: 128 random bits, hex
  std::string principal;  // who opened it: only they can resume it
  std::shared_ptr<SceneLease> lease;
  Settings settings;
  v1::Camera camera;
  float target_fps = 0.0f;
  InteractiveProfile profile;
  VideoSettings video;
  uint64_t video_generation = 0;  // counts changes that need a new encoder (SameStream)
  uint64_t sequence = 0;      // of the last frame made
  uint64_t newest_event = 0;  // the newest event applied
  // settings.play: the scene time is play_base plus the wall-clock time since play_origin.
  Clock::time_point play_origin{};
  double play_base = 0.0;
};

// What the handlers share. Owned by the Server; outlives every call.
struct ServiceState {
  ServerOptions options;
  Renderer* renderer = nullptr;
  SceneStore* store = nullptr;
  RenderLoop* loop = nullptr;
  ThreadPool* loader = nullptr;
  Authenticator* auth = nullptr;
  Metrics* metrics = nullptr;  // may be null
  JobManager* jobs = nullptr;
  SceneArchive* shared_scenes = nullptr;  // --scene_store_dir, or null
  std::function<ServerHealth()> health;  // what grpc.health.v1 says now, and why
  Clock::time_point started = Clock::now();
  Settings default_settings;
  UsageCounter principal_sessions;  // open streams per principal (token limits)
  UsageCounter principal_uploads;   // uploads in progress per principal

  std::atomic<bool> shutting_down{false};  // set under sessions_mu by ShutdownSessions
  std::atomic<uint32_t> uploads_in_progress{0};
  std::atomic<uint32_t> unary_queued{0};
  std::atomic<uint64_t> frames_dropped{0};
  std::atomic<uint64_t> pending_frame_bytes{0};
  std::atomic<uint64_t> next_session_id{1};

  mutable std::mutex sessions_mu;
  std::set<std::shared_ptr<StreamSession>> sessions;  // open Stream calls
  std::map<std::string, std::weak_ptr<StreamSession>> live_tokens;  // token -> open stream
  struct Parked {
    SessionState state;
    Clock::time_point expires;
  };
  std::map<std::string, Parked> parked;  // broken streams' sessions, by token

  uint32_t session_count() const;
  uint32_t parked_count() const;
  // A new Stream session would be taken now: serving, not shutting down, and fewer than
  // max_sessions open (readiness: grpc.health.v1 "tessera.v1.RenderService"). `serving`:
  // the health to assume (the health check passes its own), else health() is asked.
  bool AcceptingSessions(std::optional<bool> serving = std::nullopt) const;
  // Runs `then` once the scene `scene_id` names is in memory, if it can be: at once when it
  // is there or nowhere to load from (the caller's own lookup then answers), else after the
  // loader thread has loaded it from the job journal or the shared scene store
  // (JobManager::LoadArchived), with the load's error if it failed.
  void EnsureSceneLoaded(const std::string& scene_id, std::function<void(absl::Status)> then);
  // Ends every open stream with UNAVAILABLE after its in-flight frame.
  void ShutdownSessions();

  // Keeps a broken stream's session for resume_grace_s (the oldest parked one goes when
  // max_sessions are parked).
  void Park(SessionState state);
  // The session named by `token` for `principal`: a parked one, or an open one whose stream
  // is then ended with ABORTED (its client has reconnected before the server noticed the old
  // connection was gone). NOT_FOUND when unknown, expired or someone else's.
  absl::StatusOr<SessionState> Resume(const std::string& token, const std::string& principal);
  // Drops parked sessions past their grace period (their scene leases with them).
  void SweepParked();

  // The caller of a handler: the authenticated principal or UNAUTHENTICATED.
  absl::StatusOr<std::shared_ptr<const Principal>> Authorize(
      grpc::CallbackServerContext* ctx) const;
  // Counts a finished call in the metrics.
  void CountRpc(const char* method, const grpc::Status& status) const;
};

class RenderServiceImpl final : public v1::RenderService::CallbackService {
 public:
  explicit RenderServiceImpl(ServiceState* state) : state_(state) {}

  grpc::ServerUnaryReactor* GetServerInfo(grpc::CallbackServerContext* ctx,
                                          const v1::GetServerInfoRequest* request,
                                          v1::ServerInfo* response) override;
  grpc::ServerReadReactor<v1::UploadRequest>* UploadScene(grpc::CallbackServerContext* ctx,
                                                          v1::SceneInfo* response) override;
  grpc::ServerUnaryReactor* HasScene(grpc::CallbackServerContext* ctx,
                                     const v1::HasSceneRequest* request,
                                     v1::HasSceneResponse* response) override;
  grpc::ServerUnaryReactor* ListScenes(grpc::CallbackServerContext* ctx,
                                       const v1::ListScenesRequest* request,
                                       v1::ListScenesResponse* response) override;
  grpc::ServerUnaryReactor* DeleteScene(grpc::CallbackServerContext* ctx,
                                        const v1::DeleteSceneRequest* request,
                                        v1::DeleteSceneResponse* response) override;
  grpc::ServerUnaryReactor* Render(grpc::CallbackServerContext* ctx,
                                   const v1::RenderRequest* request, v1::Frame* response) override;
  grpc::ServerBidiReactor<v1::ClientEvent, v1::Frame>* Stream(
      grpc::CallbackServerContext* ctx) override;

  // Jobs (job_service.cpp).
  grpc::ServerUnaryReactor* SubmitJob(grpc::CallbackServerContext* ctx,
                                      const v1::SubmitJobRequest* request,
                                      v1::Job* response) override;
  grpc::ServerWriteReactor<v1::JobProgress>* WatchJob(grpc::CallbackServerContext* ctx,
                                                      const v1::WatchJobRequest* request) override;
  grpc::ServerUnaryReactor* CancelJob(grpc::CallbackServerContext* ctx,
                                      const v1::CancelJobRequest* request,
                                      v1::Job* response) override;
  grpc::ServerUnaryReactor* DeleteJob(grpc::CallbackServerContext* ctx,
                                      const v1::DeleteJobRequest* request,
                                      v1::DeleteJobResponse* response) override;
  grpc::ServerUnaryReactor* ListJobs(grpc::CallbackServerContext* ctx,
                                     const v1::ListJobsRequest* request,
                                     v1::ListJobsResponse* response) override;
  grpc::ServerWriteReactor<v1::JobFrame>* FetchJobFrames(
      grpc::CallbackServerContext* ctx, const v1::FetchJobFramesRequest* request) override;
  grpc::ServerUnaryReactor* RenderJobFrame(grpc::CallbackServerContext* ctx,
                                           const v1::RenderJobFrameRequest* request,
                                           v1::Frame* response) override;

 private:
  ServiceState* state_;
};

inline constexpr uint32_t kMaxQueuedRenders = 64;  // unary renders waiting for the render thread

// Milliseconds from `t` to now.
double MsSince(Clock::time_point t);
// The aspect ratio of frames of these settings (width / height).
float Aspect(const Settings& s);
// UNAVAILABLE: what every call gets once the server is shutting down.
absl::Status Unavailable();

// absl::Status -> grpc::Status (same codes, same message).
grpc::Status ToGrpc(const absl::Status& status);

// Finishes a unary call with `status` from the handler's thread, counted under `method`.
grpc::ServerUnaryReactor* Reply(const ServiceState* state, grpc::CallbackServerContext* ctx,
                                const char* method, const absl::Status& status);

// A unary call answered by one frame from the render loop (Render, RenderJobFrame): fails with
// DEADLINE_EXCEEDED / CANCELLED instead of rendering when the call is gone; counted and logged
// under `method`. The caller has counted it in state->unary_queued.
std::shared_ptr<RenderClient> MakeUnaryRender(ServiceState* state,
                                              grpc::CallbackServerContext* ctx,
                                              grpc::ServerUnaryReactor* reactor,
                                              v1::Frame* response, RenderWork work,
                                              const char* method);

}  // namespace tessera::server
