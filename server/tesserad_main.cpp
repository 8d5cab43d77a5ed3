// tesserad: the Tessera render daemon. Flags (or a --flagfile with one --flag=value per line)
// set the address, the device and the limits; SIGTERM/SIGINT stop it cleanly; SIGHUP reloads
// the token file.
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <string>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
#include "absl/strings/str_cat.h"
#include "renderer/log.h"
#include "renderer/vk/vk_check.h"
#include "server/server.h"

ABSL_FLAG(std::string, listen, "127.0.0.1:50051",
          "address to serve on, host:port (port 0 picks a free port; 0.0.0.0:PORT for all "
          "interfaces)");
ABSL_FLAG(std::string, device, "",
          "Vulkan device: a substring of its name (default: $TESSERA_DEVICE, else the best "
          "device: discrete > integrated > virtual > cpu)");
ABSL_FLAG(bool, validation, false, "enable the Vulkan validation layers (slow; for debugging)");
ABSL_FLAG(std::string, log_level, "info", "trace, debug, info, warn, error or off");
ABSL_FLAG(uint64_t, max_upload_bytes, 1ull << 30, "limit: total bytes of one upload");
ABSL_FLAG(uint32_t, max_upload_files, 1024, "limit: files in one upload");
ABSL_FLAG(uint32_t, max_chunk_bytes, 1u << 20, "limit: data bytes in one upload chunk");
ABSL_FLAG(uint32_t, max_scenes, 32, "limit: uploaded scenes in memory");
ABSL_FLAG(uint32_t, max_sessions, 64, "limit: concurrent streaming sessions");
ABSL_FLAG(uint32_t, max_concurrent_uploads, 4, "limit: uploads in progress at once");
ABSL_FLAG(float, max_session_fps, 60.0f, "limit: frames per second one streaming session gets");
ABSL_FLAG(uint64_t, scene_memory_budget_mb, 0,
          "limit: device memory (MiB) for uploaded scenes; unused scenes are evicted least "
          "recently used first (0: no budget)");
ABSL_FLAG(std::string, import_limits, "",
          "limits of one uploaded glTF asset, as name=value,... (e.g. max_nodes=10000,"
          "max_image_dimension=8192); names: max_json_bytes, max_json_depth, max_nodes, "
          "max_node_depth, max_meshes, max_primitives, max_accessor_elements, "
          "max_accessor_bytes, max_vertices, max_indices, max_image_dimension, max_image_bytes, "
          "max_total_image_bytes, max_textures, max_materials, max_lights, max_drawables, "
          "max_json_values, max_decoded_bytes, max_animation_keys, max_skin_joints, "
          "max_morph_targets (defaults in "
          "`tessera info`)");
ABSL_FLAG(uint64_t, max_scene_device_mb, 4096,
          "limit: device memory (MiB) one scene may take, estimated before its upload (0: none)");
ABSL_FLAG(uint32_t, resume_grace_s, 30,
          "how long the session of a broken stream can be resumed with its token (0: never)");
ABSL_FLAG(uint32_t, encoder_threads, 0, "JPEG/PNG encoder threads (0: one per core)");
ABSL_FLAG(uint32_t, max_frames_in_flight, 3,
          "rendered frames out on the encoders at once (the render thread waits beyond that)");
ABSL_FLAG(std::string, tls_cert, "", "TLS: server certificate chain (PEM file)");
ABSL_FLAG(std::string, tls_key, "", "TLS: server private key (PEM file)");
ABSL_FLAG(std::string, tls_client_ca, "",
          "mTLS: clients must present a certificate signed by this CA (PEM file)");
ABSL_FLAG(std::string, token_file, "",
          "bearer tokens, one per line: TOKEN NAME [max_sessions=N] [max_uploads=N]; every "
          "call then needs 'authorization: Bearer TOKEN' (health stays open); SIGHUP reloads");
ABSL_FLAG(std::string, metrics_listen, "",
          "serve Prometheus metrics at http://HOST:PORT/metrics (empty: off)");
ABSL_FLAG(std::string, state_dir, "",
          "jobs: keep the job journal, returned frames and the scenes jobs need here, so a "
          "restarted daemon resumes unfinished jobs (empty: a temporary directory, removed at exit)");
ABSL_FLAG(std::string, scene_store_dir, "",
          "replicas: a scene store shared by every tesserad given the same directory (a shared "
          "volume): uploads are saved there, and a scene not loaded here is loaded from there "
          "(empty: off)");
ABSL_FLAG(uint64_t, scene_store_max_mb, 20480,
          "limit: MiB of scene files in --scene_store_dir; past it the least recently used "
          "scenes are evicted (never one a replica is loading)");
ABSL_FLAG(std::string, job_output_root, "",
          "jobs: SERVER_DIR outputs are written under this directory (empty: not offered)");
ABSL_FLAG(uint32_t, max_jobs, 64, "limit: jobs kept (queued, running and finished)");
ABSL_FLAG(uint32_t, max_job_frames, 100000, "limit: frames in one job");
ABSL_FLAG(double, background_share, 0.12,
          "while viewers are active, the share of the render thread jobs and background renders "
          "may take (0..1]");
ABSL_FLAG(std::string, health_listen, "",
          "host:port serving grpc.health.v1 alone, in plaintext, for probes that cannot speak "
          "TLS (Kubernetes gRPC probes when --tls_cert is set); empty: off");
ABSL_FLAG(double, render_stall_s, 60.0,
          "health turns NOT_SERVING while one frame has been rendering for longer than this "
          "(a stuck device or driver), and back once it finishes; a lost device makes tesserad "
          "exit with status 75 so that its supervisor restarts it");
ABSL_FLAG(uint32_t, shutdown_grace_ms, 3000,
          "on SIGTERM, how long open calls may take to finish before they are cancelled");
ABSL_FLAG(std::string, port_file, "",
          "write the bound port to this file once serving (for scripts using port 0)");

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "tesserad [--listen=HOST:PORT] [--device=NAME] [limits...] [--flagfile=FILE]\n"
      "The Tessera render server. See --help for every flag; a config file is a --flagfile\n"
      "with one --flag=value per line.");
  absl::ParseCommandLine(argc, argv);

  const std::string level = absl::GetFlag(FLAGS_log_level);
  const spdlog::level::level_enum lvl = spdlog::level::from_str(level);
  if (lvl == spdlog::level::off && level != "off") {
    std::fprintf(stderr, "tesserad: --log_level: unknown level '%s'\n", level.c_str());
    return 2;
  }
  tessera::Log().set_level(lvl);

  // Signals are taken synchronously by this thread; every other thread inherits the mask.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGHUP);
  sigaddset(&signals, SIGUSR1);  // raised by the server itself when the device is lost
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  tessera::server::ServerOptions options;
  options.listen = absl::GetFlag(FLAGS_listen);
  options.device = absl::GetFlag(FLAGS_device);
  options.validation = absl::GetFlag(FLAGS_validation);
  options.max_upload_bytes = absl::GetFlag(FLAGS_max_upload_bytes);
  options.max_upload_files = absl::GetFlag(FLAGS_max_upload_files);
  options.max_chunk_bytes = absl::GetFlag(FLAGS_max_chunk_bytes);
  options.max_scenes = absl::GetFlag(FLAGS_max_scenes);
  options.max_sessions = absl::GetFlag(FLAGS_max_sessions);
  options.max_concurrent_uploads = absl::GetFlag(FLAGS_max_concurrent_uploads);
  options.encoder_threads = absl::GetFlag(FLAGS_encoder_threads);
  options.max_session_fps = absl::GetFlag(FLAGS_max_session_fps);
  options.scene_memory_budget_bytes = absl::GetFlag(FLAGS_scene_memory_budget_mb) << 20;
  options.resume_grace_s = absl::GetFlag(FLAGS_resume_grace_s);
  if (const std::string problem =
          tessera::ParseImportLimits(absl::GetFlag(FLAGS_import_limits), &options.import_limits);
      !problem.empty()) {
    std::fprintf(stderr, "tesserad: --import_limits: %s\n", problem.c_str());
    return 2;
  }
  options.max_scene_device_bytes =
      std::min<uint64_t>(absl::GetFlag(FLAGS_max_scene_device_mb), UINT64_MAX >> 20) << 20;
  options.max_frames_in_flight = absl::GetFlag(FLAGS_max_frames_in_flight);
  options.tls_cert_file = absl::GetFlag(FLAGS_tls_cert);
  options.tls_key_file = absl::GetFlag(FLAGS_tls_key);
  options.tls_client_ca_file = absl::GetFlag(FLAGS_tls_client_ca);
  options.token_file = absl::GetFlag(FLAGS_token_file);
  options.metrics_listen = absl::GetFlag(FLAGS_metrics_listen);
  options.state_dir = absl::GetFlag(FLAGS_state_dir);
  options.scene_store_dir = absl::GetFlag(FLAGS_scene_store_dir);
  options.scene_store_max_bytes = absl::GetFlag(FLAGS_scene_store_max_mb) << 20;
  options.job_output_root = absl::GetFlag(FLAGS_job_output_root);
  options.max_jobs = absl::GetFlag(FLAGS_max_jobs);
  options.max_job_frames = absl::GetFlag(FLAGS_max_job_frames);
  options.background_share = absl::GetFlag(FLAGS_background_share);
  options.render_stall_s = absl::GetFlag(FLAGS_render_stall_s);
  options.health_listen = absl::GetFlag(FLAGS_health_listen);
  options.on_device_lost = [] { kill(getpid(), SIGUSR1); };

  auto server = tessera::server::Server::Start(options);
  if (!server.ok()) {
    std::fprintf(stderr, "tesserad: %s\n", std::string(server.status().message()).c_str());
    return 1;
  }
  if (const std::string path = absl::GetFlag(FLAGS_port_file); !path.empty()) {
    if (FILE* f = std::fopen(path.c_str(), "w")) {
      std::fprintf(f, "%d\n", (*server)->port());
      std::fclose(f);
    }
  }
  // The hint has what a client needs for this daemon: TLS and its CA, a token.
  std::string hint = absl::StrCat("tessera --server ", (*server)->address());
  if (!options.tls_cert_file.empty())
    absl::StrAppend(&hint, " --tls --tls-ca CA.pem (the CA that signed ", options.tls_cert_file,
                    ")");
  if (!options.token_file.empty()) absl::StrAppend(&hint, " --token-file FILE");
  tessera::Log().info("ready: try `{} info`", hint);

  int sig = 0;
  for (;;) {
    sigwait(&signals, &sig);
    if (sig != SIGHUP) break;
    tessera::Log().info("SIGHUP received: reloading {}", options.token_file.empty()
                                                             ? "nothing (no --token_file)"
                                                             : options.token_file);
    (void)(*server)->ReloadTokens();
  }
  if (sig == SIGUSR1) {
    // The device is lost and will not come back in this process: health is NOT_SERVING, open
    // calls end with UNAVAILABLE, and a non-zero exit makes systemd (Restart=on-failure) or
    // Kubernetes start a fresh tesserad; journalled jobs resume there.
    tessera::Log().critical("the GPU device was lost: shutting down, exit status {}",
                            tessera::vk::kDeviceLostExitCode);
    (*server)->Shutdown(std::chrono::milliseconds(absl::GetFlag(FLAGS_shutdown_grace_ms)));
    server->reset();
    return tessera::vk::kDeviceLostExitCode;
  }
  tessera::Log().info("{} received", sig == SIGTERM ? "SIGTERM" : "SIGINT");
  (*server)->Shutdown(std::chrono::milliseconds(absl::GetFlag(FLAGS_shutdown_grace_ms)));
  server->reset();
  return 0;
}
