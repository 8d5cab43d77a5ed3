#pragma once
// tesserad as a library: the gRPC RenderService (plus health and reflection) over one
// renderer. tesserad's main() parses flags into ServerOptions and calls Start; integration
// tests and benchmarks start it in-process on port 0.
//
// Threads: gRPC's callback threads run the handlers, which never block; one render thread
// owns the Vulkan queue and serves unary renders and streaming sessions round-robin; an
// encoder pool turns pixels into JPEG/PNG; a loader pool parses uploaded glTF files.
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "renderer/scene/import_limits.h"

namespace tessera::server {

// grpc.health.v1's service name for readiness: SERVING while a new Stream session would be
// taken (healthy, not shutting down, fewer than max_sessions open). "" is liveness.
inline constexpr char kReadinessService[] = "tessera.v1.RenderService";

struct ServerOptions {
  std::string listen = "127.0.0.1:50051";  // host:port; port 0 picks a free port
  std::string device;       // substring of the Vulkan device name; empty: best device
  bool validation = false;  // Vulkan validation layers (also TESSERA_VALIDATION=1)

  // Limits on what clients may ask for. Exceeding one is RESOURCE_EXHAUSTED naming it.
  uint64_t max_upload_bytes = 1ull << 30;  // total bytes of one upload's files
  uint32_t max_upload_files = 1024;        // files in one upload
  uint32_t max_chunk_bytes = 1u << 20;     // data bytes in one UploadChunk
  uint32_t max_scenes = 32;                // uploaded scenes in memory (demo not counted)
  uint32_t max_sessions = 64;              // concurrent Stream sessions
  uint32_t max_concurrent_uploads = 4;     // uploads receiving or parsing at once
  // What one uploaded glTF asset may hold (import_limits.h), and the device memory one scene
  // may take (0 = unlimited): RESOURCE_EXHAUSTED naming the limit, before allocating.
  ImportLimits import_limits;
  uint64_t max_scene_device_bytes = 4ull << 30;

  float max_session_fps = 60.0f;            // frames per second one Stream session may get
  uint64_t scene_memory_budget_bytes = 0;  // device memory for uploaded scenes; 0 = unlimited
  uint32_t resume_grace_s = 30;            // a broken stream's session waits this long; 0 = off

  uint32_t encoder_threads = 0;       // JPEG/PNG encoders; 0 = one per core
  uint32_t max_frames_in_flight = 3;  // rendered frames out on the encoders at once
  bool pipelined = true;              // false: encode on the render thread (benchmarks)
  uint32_t loader_threads = 1;        // glTF parsers
  bool load_demo_scene = true;        // scene "demo" (the built-in scene)

  // Security. TLS when both are set (PEM files); with a client CA, clients must present a
  // certificate it signed (mTLS). With a token file every RenderService call needs
  // "authorization: Bearer <token>" (the file format is in auth.h); health stays open.
  std::string tls_cert_file;
  std::string tls_key_file;
  std::string tls_client_ca_file;
  std::string token_file;

  // Prometheus text metrics over HTTP at /metrics on host:port (port 0 picks one); empty: off.
  std::string metrics_listen;

  // Jobs. With a state directory the job journal and the scenes jobs need are kept there, and
  // a restarted daemon resumes unfinished jobs; without one they live in a temporary
  // directory removed at exit. SERVER_DIR outputs go under job_output_root (empty: refused).
  std::string state_dir;
  std::string job_output_root;
  // Scenes shared by replicas: uploads are saved under this directory (a shared volume) and
  // a replica asked for a scene it has not loaded loads it from there. Empty: off. Past
  // scene_store_max_bytes the least recently used scenes are evicted (never one being loaded).
  std::string scene_store_dir;
  uint64_t scene_store_max_bytes = 20ull << 30;
  uint32_t max_jobs = 64;            // jobs kept (queued, running, finished)
  uint32_t max_job_frames = 100000;  // frames in one job
  // While viewers are active, background frames (jobs, background renders) take at most this
  // share of the render thread.
  double background_share = 0.12;
  // Health (grpc.health.v1, what the Kubernetes probes ask): NOT_SERVING while the render thread
  // has been inside one frame for longer than this (a wedged device or driver), and for good
  // once the device is lost.
  double render_stall_s = 60.0;
  // host:port serving grpc.health.v1 alone, in plaintext (empty: off), for probes that cannot
  // speak TLS (Kubernetes' gRPC probes) when the service port has TLS.
  std::string health_listen;
  // Called once, from the render thread, when the Vulkan device is lost. tesserad raises a
  // signal in itself and exits with status 75 after a graceful shutdown, so that its supervisor
  // starts a fresh process (journalled jobs resume there).
  std::function<void()> on_device_lost;
};

// What grpc.health.v1 says and why (GetServerInfo, metrics).
struct ServerHealth {
  bool serving = true;
  std::string reason;  // empty when serving
};

// Counters for tests, benchmarks and logs.
struct ServerStats {
  uint32_t scenes = 0;    // scenes in memory, incl. demo and deleted-but-in-use
  uint32_t sessions = 0;  // open Stream sessions
  uint32_t queue_depth = 0;
  uint64_t frames_rendered = 0;
  uint64_t frames_dropped = 0;       // encoded but replaced by a newer one before sending
  // Bytes held for sessions (slots + writes): encoded frames, and the RGBA pixels of h264
  // sessions' frames until they are encoded.
  uint64_t pending_frame_bytes = 0;
  uint32_t uploads_in_progress = 0;
  uint64_t validation_messages = 0;  // Vulkan validation-layer messages (tests require 0)
  uint32_t parked_sessions = 0;      // broken streams' sessions waiting for a resume
  uint32_t frames_in_flight = 0;     // rendered frames being encoded
  uint64_t scene_device_bytes = 0;   // device memory held by scenes
  uint64_t scenes_evicted = 0;       // unused scenes evicted for room
  uint32_t jobs_active = 0;          // queued or running jobs
};

class Server {
 public:
  // Opens the device, loads the demo scene, binds and starts serving. Errors: no Vulkan device,
  // address in use, bad options.
  static absl::StatusOr<std::unique_ptr<Server>> Start(const ServerOptions& options);
  ~Server();  // Shutdown() if not done

  int port() const;             // the bound port (useful with port 0)
  int health_port() const;      // --health_listen's bound port; 0 when off
  std::string address() const;  // "host:port" to connect to

  // Stops accepting, ends open streams with UNAVAILABLE after their in-flight frame, fails
  // queued work with UNAVAILABLE, and returns once every call is finished (or after `grace`,
  // when remaining calls are cancelled). Idempotent.
  void Shutdown(std::chrono::milliseconds grace = std::chrono::milliseconds(3000));

  ServerStats stats() const;
  ServerHealth health() const;
  // Re-evaluates health now (the housekeeping thread does every 250 ms).
  void CheckHealth();
  // Test hooks (Renderer::...ForTesting): the next frame blocks for `ms`; the next frame meets
  // a lost device.
  void StallNextRenderForTesting(uint32_t ms);
  void SimulateDeviceLossForTesting();

  // Re-reads the token file (SIGHUP). On error the old tokens stay in use.
  absl::Status ReloadTokens();
  int metrics_port() const;      // 0 when the metrics endpoint is off
  std::string MetricsText() const;  // what /metrics serves

  struct Impl;

 private:
  explicit Server(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace tessera::server
