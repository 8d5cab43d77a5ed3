#pragma once
// The RenderService handlers (gRPC callback API). Handlers validate the request, then hand
// work to the render loop, the loader pool or the scene store; none of them blocks a gRPC
// thread on rendering, parsing or device uploads.
#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <set>

#include "renderer/renderer.h"
#include "server/render_loop.h"
#include "server/scene_store.h"
#include "server/server.h"
#include "tessera/v1/render_service.grpc.pb.h"

namespace tessera::server {

class StreamSession;

// What the handlers share. Owned by the Server; outlives every call.
struct ServiceState {
  ServerOptions options;
  Renderer* renderer = nullptr;
  SceneStore* store = nullptr;
  RenderLoop* loop = nullptr;
  ThreadPool* loader = nullptr;
  Clock::time_point started = Clock::now();
  Settings default_settings;

  std::atomic<bool> shutting_down{false};  // set under sessions_mu by ShutdownSessions
  std::atomic<uint32_t> uploads_in_progress{0};
  std::atomic<uint32_t> unary_queued{0};
  std::atomic<uint64_t> frames_dropped{0};
  std::atomic<uint64_t> pending_frame_bytes{0};
  std::atomic<uint64_t> next_session_id{1};

  mutable std::mutex sessions_mu;
  std::set<std::shared_ptr<StreamSession>> sessions;  // open Stream calls

  uint32_t session_count() const;
  // Ends every open stream with UNAVAILABLE after its in-flight frame.
  void ShutdownSessions();
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

 private:
  ServiceState* state_;
};

// absl::Status -> grpc::Status (same codes, same message).
grpc::Status ToGrpc(const absl::Status& status);

}  // namespace tessera::server
