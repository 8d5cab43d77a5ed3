#include "server/server.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "common/status_macros.h"
#include "common/video.h"
#include "renderer/log.h"
#include "renderer/scene/demo_scene.h"
#include "server/auth.h"
#include "server/convert.h"
#include "server/job_journal.h"
#include "server/jobs.h"
#include "server/metrics.h"
#include "server/scene_archive.h"
#include "server/service.h"

namespace tessera::server {

namespace {

absl::StatusOr<std::string> ReadPem(const std::string& path, const char* flag) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat(flag, ": cannot read \"", path, "\""));
  std::ostringstream text;
  text << in.rdbuf();
  if (text.str().find("-----BEGIN ") == std::string::npos)
    return absl::InvalidArgumentError(absl::StrCat(flag, ": \"", path, "\" is not a PEM file"));
  return text.str();
}

absl::StatusOr<std::shared_ptr<grpc::ServerCredentials>> Credentials(const ServerOptions& o) {
  if (o.tls_cert_file.empty() != o.tls_key_file.empty())
    return absl::InvalidArgumentError("tls_cert / tls_key: give both, or neither");
  if (o.tls_cert_file.empty()) {
    if (!o.tls_client_ca_file.empty())
      return absl::InvalidArgumentError("tls_client_ca: needs tls_cert and tls_key");
    return grpc::InsecureServerCredentials();
  }
  ASSIGN_OR_RETURN(std::string cert, ReadPem(o.tls_cert_file, "tls_cert"));
  ASSIGN_OR_RETURN(std::string key, ReadPem(o.tls_key_file, "tls_key"));
  grpc::SslServerCredentialsOptions ssl(GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE);
  if (!o.tls_client_ca_file.empty()) {
    ASSIGN_OR_RETURN(ssl.pem_root_certs, ReadPem(o.tls_client_ca_file, "tls_client_ca"));
    ssl.client_certificate_request = GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY;
  }
  ssl.pem_key_cert_pairs.push_back({key, cert});
  return grpc::SslServerCredentials(ssl);
}

bool IsLoopback(const std::string& listen) {
  const std::string host = listen.substr(0, listen.rfind(':'));
  return host == "127.0.0.1" || host == "localhost" || host == "[::1]";
}

}  // namespace

struct Server::Impl {
  ServerOptions options;
  std::unique_ptr<Authenticator> auth;
  std::unique_ptr<Metrics> metrics;
  int metrics_port = 0;
  std::unique_ptr<Renderer> renderer;
  std::unique_ptr<SceneStore> store;
  std::unique_ptr<ThreadPool> loader;
  std::unique_ptr<RenderLoop> loop;
  std::unique_ptr<JobManager> jobs;
  std::unique_ptr<SceneArchive> shared_scenes;  // --scene_store_dir
  std::string temp_state_dir;  // jobs without --state_dir: removed at exit
  ServiceState state;
  std::unique_ptr<RenderServiceImpl> service;
  std::unique_ptr<grpc::Server> grpc_server;
  std::unique_ptr<grpc::Server> health_server;  // --health_listen: grpc.health.v1 only
  int port = 0;
  int health_port = 0;
  std::string host;
  std::mutex shutdown_mu;
  bool shut_down = false;

  // Health: what grpc.health.v1 says now, and why not SERVING.
  mutable std::mutex health_mu;
  ServerHealth health_now;
  int ready_now = -1;  // readiness (kReadinessService) as last set: -1 not yet, 0, 1
  uint64_t stalls = 0;  // times the render thread was found stalled
  void CheckHealth();
  ServerHealth Health() const {
    std::lock_guard lock(health_mu);
    return health_now;
  }

  // Housekeeping: drops parked sessions past their grace period, checks health.
  std::thread sweeper;
  std::mutex sweeper_mu;
  std::condition_variable sweeper_cv;
  bool sweeper_stop = false;

  // The steps of Server::Start, in its order.
  absl::Status OpenAuth();
  absl::Status LoadDemo();
  void StartMetricsAndLoop();
  absl::Status StartJobs();
  void StartService();  // the handlers' ServiceState, and the jobs restored from the journal
  absl::Status Listen(const std::shared_ptr<grpc::ServerCredentials>& credentials);
  void StartSweeper();

  void StopSweeper() {
    {
      std::lock_guard lock(sweeper_mu);
      sweeper_stop = true;
    }
    sweeper_cv.notify_all();
    if (sweeper.joinable()) sweeper.join();
  }
  ~Impl() {
    StopSweeper();
    // The metrics endpoint reads the loop, store and sessions: it goes first, once the loop's
    // encoders (which report to it) are drained.
    if (loop) loop->Stop();
    metrics.reset();
    loader.reset();  // queued scene loads call into the jobs
    jobs.reset();
    if (!temp_state_dir.empty()) {
      std::error_code ec;
      std::filesystem::remove_all(temp_state_dir, ec);
    }
  }
};

namespace {

// The limits that have no meaningful value outside their range (INVALID_ARGUMENT naming them).
absl::Status CheckOptions(const ServerOptions& options) {
  if (options.max_chunk_bytes == 0 || options.max_chunk_bytes > (64u << 20))
    return absl::InvalidArgumentError("max_chunk_bytes: must be 1..67108864");
  if (options.max_upload_files == 0 || options.max_sessions == 0 ||
      options.max_concurrent_uploads == 0)
    return absl::InvalidArgumentError(
        "limits: max_upload_files, max_sessions and max_concurrent_uploads must be > 0");
  if (!(options.max_session_fps >= 1.0f && options.max_session_fps <= 1000.0f))
    return absl::InvalidArgumentError("max_session_fps: must be 1..1000");
  if (options.max_frames_in_flight == 0 || options.max_frames_in_flight > 16)
    return absl::InvalidArgumentError("max_frames_in_flight: must be 1..16");
  if (options.resume_grace_s > 86400)
    return absl::InvalidArgumentError("resume_grace_s: must be 0..86400");
  if (options.max_jobs == 0 || options.max_job_frames == 0)
    return absl::InvalidArgumentError("max_jobs, max_job_frames: must be > 0");
  if (!(options.background_share > 0.0 && options.background_share <= 1.0))
    return absl::InvalidArgumentError("background_share: must be in (0, 1]");
  if (!(options.render_stall_s > 0.0))
    return absl::InvalidArgumentError("render_stall_s: must be more than 0 seconds");
  if (!options.scene_store_dir.empty() && options.scene_store_max_bytes == 0)
    return absl::InvalidArgumentError("scene_store_max_mb: must be > 0");
  return absl::OkStatus();
}

}  // namespace

absl::Status Server::Impl::OpenAuth() {
  if (options.token_file.empty()) {
    auth = std::make_unique<Authenticator>();
    return absl::OkStatus();
  }
  ASSIGN_OR_RETURN(auth, Authenticator::FromFile(options.token_file));
  if (options.tls_cert_file.empty() && !IsLoopback(options.listen))
    Log().warn("bearer tokens without TLS on {}: tokens cross the network in clear text",
               options.listen);
  return absl::OkStatus();
}

absl::Status Server::Impl::LoadDemo() {
  const auto t0 = std::chrono::steady_clock::now();
  ASSIGN_OR_RETURN(SceneHandle demo, renderer->LoadScene(BuildDemoScene()));
  StoredSceneInfo info;
  info.scene = demo->info();
  info.scene.name = "demo";
  info.load_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  store->AddDemo(std::move(demo), std::move(info));
  return absl::OkStatus();
}

void Server::Impl::StartMetricsAndLoop() {
  Impl* raw = this;
  metrics = std::make_unique<Metrics>([raw] {
    MetricsGauges g;
    g.sessions = raw->state.session_count();
    g.parked_sessions = raw->state.parked_count();
    g.queue_depth = raw->loop->queue_depth();
    g.frames_in_flight = raw->loop->frames_in_flight();
    g.uploads_in_progress = raw->state.uploads_in_progress;
    g.scenes = raw->store->count();
    g.scene_device_bytes = raw->store->device_bytes();
    g.scene_memory_budget_bytes = raw->store->memory_budget();
    g.pending_frame_bytes = raw->state.pending_frame_bytes;
    g.jobs_active = raw->jobs ? raw->jobs->active() : 0;
    g.render_busy_seconds = raw->loop->busy_seconds();
    g.device_lost = raw->renderer->device_lost() ? 1 : 0;
    {
      std::lock_guard lock(raw->health_mu);
      g.serving = raw->health_now.serving ? 1 : 0;
      g.render_stalls = raw->stalls;
    }
    g.accepting_sessions = raw->state.AcceptingSessions(g.serving == 1) ? 1 : 0;
    g.scene_store_evictions = raw->shared_scenes ? raw->shared_scenes->evictions() : 0;
    return g;
  });
  store->set_eviction_listener([raw](const StoredScene& s) {
    Log().info("scene {} evicted (unused; {} bytes of device memory)", s.id, s.device_bytes);
    raw->metrics->SceneEvicted();
  });
  RenderLoopOptions loop_options;
  loop_options.encoder_threads = options.encoder_threads;
  loop_options.max_frames_in_flight = options.max_frames_in_flight;
  loop_options.pipelined = options.pipelined;
  loop_options.metrics = metrics.get();
  loop_options.background_share = options.background_share;
  loop_options.on_device_lost = [this] {
    CheckHealth();  // NOT_SERVING at once, before the process winds down
    if (options.on_device_lost) options.on_device_lost();
  };
  loop = std::make_unique<RenderLoop>(renderer.get(), loop_options);
}

absl::Status Server::Impl::StartJobs() {
  std::string state_dir = options.state_dir;
  if (state_dir.empty()) {
    const char* tmp = std::getenv("TMPDIR");
    std::string templ = absl::StrCat(tmp && *tmp ? tmp : "/tmp", "/tesserad-jobs-XXXXXX");
    if (::mkdtemp(templ.data()) == nullptr)
      return absl::FailedPreconditionError(
          absl::StrCat("jobs: cannot make a temporary directory ", templ, ": ",
                       std::strerror(errno), " (or give --state_dir)"));
    temp_state_dir = state_dir = templ;
  }
  absl::StatusOr<std::unique_ptr<JobJournal>> journal = JobJournal::Open(state_dir);
  if (!journal.ok()) return absl::Status(journal.status().code(),
                                         absl::StrCat("state_dir: ", journal.status().message()));
  if (!options.job_output_root.empty()) {
    struct stat sb;
    if (::stat(options.job_output_root.c_str(), &sb) != 0 || !S_ISDIR(sb.st_mode))
      return absl::FailedPreconditionError(absl::StrCat(
          "job_output_root: ", options.job_output_root, " is not a directory"));
  }
  JobManagerOptions job_options;
  job_options.max_jobs = options.max_jobs;
  job_options.max_job_frames = options.max_job_frames;
  job_options.output_root = options.job_output_root;
  job_options.persistent = !options.state_dir.empty();
  job_options.max_scene_bytes = options.max_upload_bytes;
  job_options.scene_limits = {options.import_limits, options.max_scene_device_bytes};
  job_options.shared_scenes = shared_scenes.get();
  jobs = std::make_unique<JobManager>(job_options, *std::move(journal), renderer.get(),
                                      store.get(), loop.get(), loader.get(),
                                      state.default_settings);
  return absl::OkStatus();
}

void Server::Impl::StartService() {
  state.options = options;
  state.renderer = renderer.get();
  state.store = store.get();
  state.loop = loop.get();
  state.loader = loader.get();
  state.auth = auth.get();
  state.metrics = metrics.get();
  state.jobs = jobs.get();
  state.shared_scenes = shared_scenes.get();
  state.health = [this] { return Health(); };
  service = std::make_unique<RenderServiceImpl>(&state);
  std::vector<std::string> lines;
  jobs->Restore(&lines);
  for (const std::string& line : lines) Log().info("{}", line);
}

absl::Status Server::Impl::Listen(const std::shared_ptr<grpc::ServerCredentials>& credentials) {
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  builder.AddListeningPort(options.listen, credentials, &port);
  builder.RegisterService(service.get());
  // A chunk plus the message framing, or a job spec with an explicit camera per frame (about
  // 60 bytes each); anything larger is refused by gRPC itself.
  builder.SetMaxReceiveMessageSize(
      std::max(static_cast<int>(options.max_chunk_bytes) + (64 << 10), 16 << 20));
  builder.SetMaxSendMessageSize(256 << 20);  // a 16384^2 PNG frame
  // Clients keep idle connections alive with pings (the web gateway every 30 s): a resting
  // session's stream carries no data for minutes. gRPC's default policy (one ping per 5 min
  // without data, 2 strikes) would close such a connection with "too_many_pings", ending every
  // stream on it; allow one every 10 s, also between calls.
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, 10000);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  grpc_server = builder.BuildAndStart();
  if (!grpc_server || port == 0)
    return absl::UnavailableError(absl::StrCat("listen: cannot listen on \"", options.listen,
                                               "\" (in use or not an address)"));
  host = options.listen.substr(0, options.listen.rfind(':'));
  if (host.empty() || host == "0.0.0.0" || host == "[::]") host = "127.0.0.1";
  if (!options.health_listen.empty()) {
    // grpc.health.v1 alone, in plaintext: what Kubernetes' gRPC probes (which cannot speak TLS)
    // ask when the service port has TLS. No other service is registered on it.
    grpc::ServerBuilder health_builder;
    health_builder.AddListeningPort(options.health_listen, grpc::InsecureServerCredentials(),
                                    &health_port);
    health_server = health_builder.BuildAndStart();
    if (!health_server || health_port == 0) {
      grpc_server->Shutdown();
      return absl::UnavailableError(absl::StrCat("health_listen: cannot listen on \"",
                                                 options.health_listen,
                                                 "\" (in use or not an address)"));
    }
    Log().info("health (grpc.health.v1, plaintext): {}:{}", host, health_port);
  }
  if (!options.metrics_listen.empty()) {
    absl::StatusOr<int> serving = metrics->Serve(options.metrics_listen);
    if (!serving.ok()) {
      grpc_server->Shutdown();
      return serving.status();
    }
    metrics_port = *serving;
    Log().info("metrics: http://{}:{}/metrics", host, metrics_port);
  }
  return absl::OkStatus();
}

void Server::Impl::StartSweeper() {
  sweeper = std::thread([this] {
    std::unique_lock lock(sweeper_mu);
    for (uint64_t tick = 1; !sweeper_cv.wait_for(lock, std::chrono::milliseconds(250),
                                                  [this] { return sweeper_stop; });
         ++tick) {
      state.SweepParked();
      CheckHealth();
      // Scenes this replica serves from memory are in use: their entries in the shared store
      // are marked used each minute, so its LRU eviction takes scenes nobody holds.
      if (shared_scenes && tick % 240 == 0)
        for (const SceneListing& s : store->List())
          if (s.id != kDemoSceneId && !s.deleted) shared_scenes->MarkUsed(s.id);
    }
  });
}

void Server::Impl::CheckHealth() {
  ServerHealth h;
  const double busy = loop ? loop->busy_seconds() : 0.0;
  if (renderer->device_lost()) {
    h = {false, "the GPU device was lost; tesserad exits so that a fresh process takes over"};
  } else if (busy > options.render_stall_s) {
    h = {false, absl::StrFormat("the render thread has been in one frame for %.0f s "
                                "(--render_stall_s %g): the device or its driver is stuck",
                                busy, options.render_stall_s)};
  }
  // Readiness: the service name says whether a new session would be taken (load included),
  // so that Kubernetes and the gateway stop sending sessions to a full replica while its
  // liveness ("") stays SERVING. (ServiceState::AcceptingSessions, with this health.)
  const bool ready = h.serving && state.AcceptingSessions(/*serving=*/true);
  std::lock_guard lock(health_mu);
  if (static_cast<int>(ready) != ready_now) {
    ready_now = ready;
    for (grpc::Server* server : {grpc_server.get(), health_server.get()})
      if (server)
        if (auto* service = server->GetHealthCheckService())
          service->SetServingStatus(kReadinessService, ready);
  }
  if (h.serving == health_now.serving && h.reason == health_now.reason) return;
  if (h.serving != health_now.serving) {
    if (h.serving) {
      Log().info("health: SERVING again");
    } else {
      Log().error("health: NOT_SERVING: {}", h.reason);
      if (!renderer->device_lost()) ++stalls;
    }
    // After Shutdown the service reports NOT_SERVING whatever is set here.
    for (grpc::Server* server : {grpc_server.get(), health_server.get()})
      if (server)
        if (auto* service = server->GetHealthCheckService()) service->SetServingStatus(h.serving);
  }
  health_now = std::move(h);
}

absl::StatusOr<std::unique_ptr<Server>> Server::Start(const ServerOptions& options) {
  RETURN_IF_ERROR(CheckOptions(options));
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  ASSIGN_OR_RETURN(std::shared_ptr<grpc::ServerCredentials> credentials, Credentials(options));
  RETURN_IF_ERROR(impl->OpenAuth());
  RendererOptions renderer_options{options.device, options.validation};
  // Encoded straight from the readback buffers: the frames out on the encoders, the one
  // rendering, and one a video session holds.
  renderer_options.lent_buffers = options.max_frames_in_flight + 2;
  ASSIGN_OR_RETURN(impl->renderer, Renderer::Create(renderer_options));
  impl->store =
      std::make_unique<SceneStore>(options.max_scenes, options.scene_memory_budget_bytes);
  if (options.load_demo_scene) RETURN_IF_ERROR(impl->LoadDemo());
  // Probed once here (opening NVENC starts CUDA): sessions ask under their locks.
  Log().info("video: h264 encoders {}", absl::StrJoin(video::EncoderNames(), ", "));
  impl->loader = std::make_unique<ThreadPool>("load", std::max(1u, options.loader_threads));
  impl->StartMetricsAndLoop();
  if (!options.scene_store_dir.empty()) {
    // Shared with other replicas: a ".tmp-*" name younger than an hour may be one of their
    // writes in progress, not a crash's leftover.
    ASSIGN_OR_RETURN(impl->shared_scenes,
                     SceneArchive::Open(options.scene_store_dir,
                                        {options.scene_store_max_bytes, std::chrono::hours(1)},
                                        "scene_store_dir"));
    // Not its size: walking every file of a shared store (NFS) would slow every start.
    Log().info("scene store: {} (up to {} MiB)", impl->shared_scenes->dir(),
               options.scene_store_max_bytes >> 20);
  }
  RETURN_IF_ERROR(impl->StartJobs());
  impl->StartService();
  RETURN_IF_ERROR(impl->Listen(credentials));
  impl->CheckHealth();  // readiness set before the first probe
  impl->StartSweeper();
  Log().info("tesserad {} listening on {}:{}{}{}", TESSERA_VERSION, impl->host, impl->port,
             options.tls_cert_file.empty() ? "" : " (TLS)",
             impl->auth->enabled() ? absl::StrCat(", ", impl->auth->token_count(), " tokens")
                                   : "");
  return std::unique_ptr<Server>(new Server(std::move(impl)));
}

Server::Server(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Server::~Server() { Shutdown(); }

int Server::port() const { return impl_->port; }

int Server::health_port() const { return impl_->health_port; }

std::string Server::address() const { return absl::StrCat(impl_->host, ":", impl_->port); }

void Server::Shutdown(std::chrono::milliseconds grace) {
  std::lock_guard lock(impl_->shutdown_mu);
  if (impl_->shut_down) return;
  impl_->shut_down = true;
  const auto t0 = std::chrono::steady_clock::now();
  Log().info("shutting down: {} sessions, {} frames queued", impl_->state.session_count(),
             impl_->loop->queue_depth());
  for (grpc::Server* server : {impl_->grpc_server.get(), impl_->health_server.get()})
    if (server)
      if (auto* health = server->GetHealthCheckService()) health->Shutdown();
  // Streams end with UNAVAILABLE after their in-flight frame; queued renders fail.
  impl_->state.ShutdownSessions();
  impl_->jobs->Shutdown();  // watches end; running jobs stay in the journal
  impl_->loop->Stop();
  // Waits for every call to finish; calls still open at the deadline are cancelled.
  impl_->grpc_server->Shutdown(std::chrono::system_clock::now() + grace);
  impl_->grpc_server->Wait();
  if (impl_->health_server) impl_->health_server->Shutdown(std::chrono::system_clock::now());
  impl_->loader.reset();
  impl_->StopSweeper();
  Log().info(
      "stopped in {:.0f} ms",
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
}

ServerHealth Server::health() const { return impl_->Health(); }

void Server::CheckHealth() { impl_->CheckHealth(); }

void Server::StallNextRenderForTesting(uint32_t ms) {
  impl_->renderer->StallNextRenderForTesting(ms);
}

void Server::SimulateDeviceLossForTesting() { impl_->renderer->SimulateDeviceLossForTesting(); }

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
  s.parked_sessions = st.parked_count();
  s.frames_in_flight = impl_->loop->frames_in_flight();
  s.scene_device_bytes = impl_->store->device_bytes();
  s.scenes_evicted = impl_->store->evictions();
  s.jobs_active = impl_->jobs->active();
  return s;
}

absl::Status Server::ReloadTokens() {
  absl::Status st = impl_->auth->Reload();
  if (st.ok())
    Log().info("tokens reloaded: {} tokens", impl_->auth->token_count());
  else
    Log().error("tokens not reloaded (the previous ones stay in use): {}", std::string(st.message()));
  return st;
}

int Server::metrics_port() const { return impl_->metrics_port; }

std::string Server::MetricsText() const { return impl_->metrics->Text(); }

}  // namespace tessera::server
