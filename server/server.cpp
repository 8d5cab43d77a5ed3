#include "server/server.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>

#include "absl/strings/str_cat.h"
#include "renderer/log.h"
#include "renderer/scene/demo_scene.h"
#include "server/convert.h"
#include "server/service.h"

namespace tessera::server {

struct Server::Impl {
  ServerOptions options;
  std::unique_ptr<Renderer> renderer;
  std::unique_ptr<SceneStore> store;
  std::unique_ptr<ThreadPool> loader;
  std::unique_ptr<RenderLoop> loop;
  ServiceState state;
  std::unique_ptr<RenderServiceImpl> service;
  std::unique_ptr<grpc::Server> grpc_server;
  int port = 0;
  std::string host;
  std::mutex shutdown_mu;
  bool shut_down = false;
};

absl::StatusOr<std::unique_ptr<Server>> Server::Start(const ServerOptions& options) {
  if (options.max_chunk_bytes == 0 || options.max_chunk_bytes > (64u << 20))
    return absl::InvalidArgumentError("max_chunk_bytes: must be 1..67108864");
  if (options.max_upload_files == 0 || options.max_sessions == 0 ||
      options.max_concurrent_uploads == 0)
    return absl::InvalidArgumentError(
        "limits: max_upload_files, max_sessions and max_concurrent_uploads must be > 0");
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  absl::StatusOr<std::unique_ptr<Renderer>> renderer =
      Renderer::Create(RendererOptions{options.device, options.validation});
  if (!renderer.ok()) return renderer.status();
  impl->renderer = *std::move(renderer);

  impl->store = std::make_unique<SceneStore>(options.max_scenes);
  if (options.load_demo_scene) {
    const auto t0 = std::chrono::steady_clock::now();
    absl::StatusOr<SceneHandle> demo = impl->renderer->LoadScene(BuildDemoScene());
    if (!demo.ok()) return demo.status();
    v1::SceneInfo info;
    ToProto((*demo)->info(), &info);
    info.set_load_ms(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    info.set_name("demo");
    impl->store->AddDemo(*std::move(demo), std::move(info));
  }
  impl->loader = std::make_unique<ThreadPool>("load", std::max(1u, options.loader_threads));
  impl->loop = std::make_unique<RenderLoop>(impl->renderer.get(), options.encoder_threads);

  ServiceState& st = impl->state;
  st.options = options;
  st.renderer = impl->renderer.get();
  st.store = impl->store.get();
  st.loop = impl->loop.get();
  st.loader = impl->loader.get();
  impl->service = std::make_unique<RenderServiceImpl>(&st);

  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  builder.AddListeningPort(options.listen, grpc::InsecureServerCredentials(), &impl->port);
  builder.RegisterService(impl->service.get());
  // A chunk plus the message framing; anything larger is refused by gRPC itself.
  builder.SetMaxReceiveMessageSize(static_cast<int>(options.max_chunk_bytes) + (64 << 10));
  builder.SetMaxSendMessageSize(256 << 20);  // a 16384^2 PNG frame
  impl->grpc_server = builder.BuildAndStart();
  if (!impl->grpc_server || impl->port == 0)
    return absl::UnavailableError(absl::StrCat("listen: cannot listen on \"", options.listen,
                                               "\" (in use or not an address)"));
  impl->host = options.listen.substr(0, options.listen.rfind(':'));
  if (impl->host.empty() || impl->host == "0.0.0.0" || impl->host == "[::]")
    impl->host = "127.0.0.1";
  Log().info("tesserad {} listening on {}:{}", TESSERA_VERSION, impl->host, impl->port);
  return std::unique_ptr<Server>(new Server(std::move(impl)));
}

Server::Server(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Server::~Server() { Shutdown(); }

int Server::port() const { return impl_->port; }

std::string Server::address() const { return absl::StrCat(impl_->host, ":", impl_->port); }

void Server::Shutdown(std::chrono::milliseconds grace) {
  std::lock_guard lock(impl_->shutdown_mu);
  if (impl_->shut_down) return;
  impl_->shut_down = true;
  const auto t0 = std::chrono::steady_clock::now();
  Log().info("shutting down: {} sessions, {} frames queued", impl_->state.session_count(),
             impl_->loop->queue_depth());
  if (auto* health = impl_->grpc_server->GetHealthCheckService()) health->Shutdown();
  // Streams end with UNAVAILABLE after their in-flight frame; queued renders fail.
  impl_->state.ShutdownSessions();
  impl_->loop->Stop();
  // Waits for every call to finish; calls still open at the deadline are cancelled.
  impl_->grpc_server->Shutdown(std::chrono::system_clock::now() + grace);
  impl_->grpc_server->Wait();
  impl_->loader.reset();
  Log().info(
      "stopped in {:.0f} ms",
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
}

ServerStats Server::stats() const {
  const ServiceState& st = impl_->state;
  ServerStats s;
  s.scenes = impl_->store->count();
  s.sessions = st.session_count();
  s.queue_depth = impl_->loop->queue_depth();
  s.frames_rendered = impl_->loop->frames_rendered();
  s.frames_dropped = st.frames_dropped;
  s.pending_frame_bytes = st.pending_frame_bytes;
  s.uploads_in_progress = st.uploads_in_progress;
  s.validation_messages = impl_->renderer->validation_message_count();
  return s;
}

}  // namespace tessera::server
