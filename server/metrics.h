#pragma once
// Prometheus metrics for tesserad: counters and histograms that the service, the render loop and
// the encoders record as things happen, plus gauges read from the Server at scrape time, served
// as GET /metrics on their own HTTP port.
//
// Why a second port (civetweb, through prometheus-cpp's pull library) and not the gRPC port:
// Prometheus scrapes with plain HTTP/1.1 GET requests and reads the text exposition format,
// while the gRPC port speaks HTTP/2 with length-prefixed protobuf messages, so a scraper cannot
// talk to it (and a metrics RPC would need a gRPC client, a proxy or a plugin). prometheus-cpp's
// Exposer is exactly that HTTP/1.1 endpoint, small and packaged in Debian.
//
// This header includes no prometheus header (it is included by widely used server files): the
// registry, the families and the endpoint live behind a pimpl.
//
// Label cardinality is bounded by construction: labels come from fixed sets in our own code
// (frame kinds and profiles, upload results, gRPC method names, the 17 status codes) or from the
// renderer (its fixed set of pass names). No client-controlled string (scene ids, file names,
// peers, messages) is ever a label value; callers must keep it that way.
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"

namespace tessera::server {

// Gauges read at scrape time (so they are never stale): filled by a callback the Server provides.
struct MetricsGauges {
  uint32_t sessions = 0;                   // open Stream sessions
  uint32_t parked_sessions = 0;            // disconnected sessions waiting to be resumed
  uint32_t queue_depth = 0;                // render work waiting for the render thread (all prios)
  uint32_t frames_in_flight = 0;           // rendered, being encoded
  uint32_t uploads_in_progress = 0;        // uploads receiving or parsing
  uint32_t scenes = 0;                     // scenes in memory
  uint64_t scene_device_bytes = 0;         // device memory held by scenes
  uint64_t scene_memory_budget_bytes = 0;  // 0 = unlimited
  uint64_t pending_frame_bytes = 0;        // frames held for slow clients (h264: unencoded)
  uint32_t jobs_active = 0;                // queued or running render-farm jobs
  uint32_t serving = 1;                    // grpc.health.v1: 1 SERVING, 0 NOT_SERVING
  double render_busy_seconds = 0.0;        // time in the current frame's Render; 0 when idle
  uint32_t device_lost = 0;                // 1 once the Vulkan device is lost
  uint64_t render_stalls = 0;              // times health turned NOT_SERVING for a stall
  uint32_t accepting_sessions = 1;         // readiness (tessera.v1.RenderService): 1 SERVING
  uint64_t scene_store_evictions = 0;      // scenes this replica evicted from --scene_store_dir
};

// The canonical upper-case name of a gRPC status code ("OK", "INVALID_ARGUMENT", ...,
// "UNAUTHENTICATED"); "UNKNOWN" for a number outside 0..16, as gRPC itself maps them.
std::string_view GrpcCodeName(int code);

// Every method is thread-safe. Recording is cheap: a few map lookups under one mutex that scrapes
// do not take, then atomic counter increments and briefly locked histogram observations.
class Metrics {
 public:
  // `gauges` is called on every scrape and every Text(), from the endpoint's HTTP threads (two,
  // possibly at once) or the caller of Text(): it must be thread-safe and cheap, and stay valid
  // until this object is destroyed. An empty function reports zeros.
  explicit Metrics(std::function<MetricsGauges()> gauges);
  // Stops the endpoint (waiting for a scrape in progress, typically well under 100 ms) before
  // anything else is torn down.
  ~Metrics();
  Metrics(const Metrics&) = delete;
  Metrics& operator=(const Metrics&) = delete;

  // Starts the HTTP endpoint serving GET /metrics in the Prometheus text format on "host:port"
  // (port 0 = a free port; host an IPv4 address, 0.0.0.0 or a name: Debian's civetweb is built
  // without IPv6). Returns the bound port. Errors: INVALID_ARGUMENT when `listen` is not
  // host:port; UNAVAILABLE naming the address when it cannot listen (in use, not a local
  // address); FAILED_PRECONDITION when already serving (a failed call may be retried).
  absl::StatusOr<int> Serve(const std::string& listen);

  // One encoded frame. kind: "stream", "render" (unary) or "background" (low-priority batch
  // work); profile: "full" or "interactive". pass_ms: (pass name, device ms) in execution order.
  // A negative or non-finite time (no GPU timer, a failed frame) is not observed.
  void FrameDone(std::string_view kind, std::string_view profile,
                 const std::vector<std::pair<std::string, double>>& pass_ms, double gpu_total_ms,
                 double encode_ms, double total_ms);
  // An encoded frame replaced in a session's slot before it was sent.
  void FrameDropped();
  // A video (h264) frame encoded for a session: its encode time, size and whether it was a
  // keyframe.
  void VideoFrameEncoded(double encode_ms, uint64_t bytes, bool keyframe);
  // A finished upload. result: "loaded", "cached" or "error"; bytes: file bytes received.
  void UploadFinished(std::string_view result, uint64_t bytes);
  // Every finished RPC. method: our own method name ("Render", "Stream", "UploadScene", ...);
  // grpc_code: the status code number, 0 = OK, labelled by its canonical name (GrpcCodeName).
  void RpcFinished(std::string_view method, int grpc_code);
  // A Stream session opened, new or resumed from a parked one.
  void SessionOpened(bool resumed);
  // A scene evicted from memory to stay within the scene memory budget.
  void SceneEvicted();

  // The exposition text of our metrics (tests, logs). The endpoint serves the same families
  // plus prometheus-cpp's own exposer_* metrics about the endpoint itself.
  std::string Text() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace tessera::server
