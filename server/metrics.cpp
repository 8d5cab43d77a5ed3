// The metrics endpoint is prometheus-cpp's pull Exposer, a civetweb HTTP/1.1 server on a port of
// its own, and not a method on the gRPC port: Prometheus scrapes the text format with plain
// HTTP/1.1 GETs, which the HTTP/2-only gRPC port cannot answer (more in metrics.h).
#include "server/metrics.h"

#include <netdb.h>
#include <prometheus/collectable.h>
#include <prometheus/counter.h>
#include <prometheus/exposer.h>
#include <prometheus/family.h>
#include <prometheus/histogram.h>
#include <prometheus/metric_family.h>
#include <prometheus/metric_type.h>
#include <prometheus/registry.h>
#include <prometheus/text_serializer.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <exception>
#include <iterator>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"

namespace tessera::server {
namespace {

using prometheus::Counter;
using prometheus::Family;
using prometheus::Histogram;

// Milliseconds, from a cheap pass (0.1) to a very slow frame (5 s).
const Histogram::BucketBoundaries& MillisecondBuckets() {
  static const auto* buckets = new Histogram::BucketBoundaries{
      0.1, 0.25, 0.5, 1, 2.5, 5, 10, 25, 50, 100, 250, 500, 1000, 2500, 5000};
  return *buckets;
}

constexpr std::array<std::string_view, 17> kCodeNames = {
    "OK",                   // 0
    "CANCELLED",            // 1
    "UNKNOWN",              // 2
    "INVALID_ARGUMENT",     // 3
    "DEADLINE_EXCEEDED",    // 4
    "NOT_FOUND",            // 5
    "ALREADY_EXISTS",       // 6
    "PERMISSION_DENIED",    // 7
    "RESOURCE_EXHAUSTED",   // 8
    "FAILED_PRECONDITION",  // 9
    "ABORTED",              // 10
    "OUT_OF_RANGE",         // 11
    "UNIMPLEMENTED",        // 12
    "INTERNAL",             // 13
    "UNAVAILABLE",          // 14
    "DATA_LOSS",            // 15
    "UNAUTHENTICATED",      // 16
};
constexpr int kUnknownCode = 2;

int CodeIndex(int code) {
  return code >= 0 && code < static_cast<int>(kCodeNames.size()) ? code : kUnknownCode;
}

// A time worth observing: not a missing GPU timer (-1, NaN) or a failed frame.
bool Observable(double ms) { return std::isfinite(ms) && ms >= 0; }

// Caches of series by label value, looked up with a string_view (no allocation once created).
template <typename V>
using ByName = std::map<std::string, V, std::less<>>;

// The entry for `key`, value-initialized (null pointers) on first use.
template <typename V>
V& Slot(ByName<V>& map, std::string_view key) {
  auto it = map.find(key);
  if (it == map.end()) it = map.emplace(std::string(key), V{}).first;
  return it->second;
}

// The scrape-time gauges: Collect() calls the Server's callback, so the values are those of the
// moment of the scrape rather than of the last update.
class GaugeCollectable : public prometheus::Collectable {
 public:
  explicit GaugeCollectable(std::function<MetricsGauges()> gauges) : gauges_(std::move(gauges)) {}

  std::vector<prometheus::MetricFamily> Collect() const override {
    const MetricsGauges g = gauges_ ? gauges_() : MetricsGauges{};
    std::vector<prometheus::MetricFamily> families;
    families.reserve(14);
    auto add = [&families](const char* name, const char* help, double value) {
      prometheus::MetricFamily& family = families.emplace_back();
      family.name = name;
      family.help = help;
      family.type = prometheus::MetricType::Gauge;
      family.metric.emplace_back().gauge.value = value;
    };
    add("tessera_sessions", "Open Stream sessions.", g.sessions);
    add("tessera_parked_sessions", "Disconnected Stream sessions waiting to be resumed.",
        g.parked_sessions);
    add("tessera_queue_depth", "Render work waiting for the render thread, all priorities.",
        g.queue_depth);
    add("tessera_frames_in_flight", "Frames rendered and being encoded.", g.frames_in_flight);
    add("tessera_uploads_in_progress", "Uploads receiving or parsing.", g.uploads_in_progress);
    add("tessera_scenes", "Scenes in memory.", g.scenes);
    add("tessera_scene_device_bytes", "Device memory held by scenes, in bytes.",
        static_cast<double>(g.scene_device_bytes));
    add("tessera_scene_memory_budget_bytes",
        "Device memory budget for scenes, in bytes; 0 means unlimited.",
        static_cast<double>(g.scene_memory_budget_bytes));
    add("tessera_pending_frame_bytes",
        "Frame bytes held for slow clients: encoded frames, and h264 sessions' frames waiting "
        "to be encoded.",
        static_cast<double>(g.pending_frame_bytes));
    add("tessera_jobs_active", "Render-farm jobs queued or running.", g.jobs_active);
    add("tessera_serving",
        "1 while grpc.health.v1 says SERVING; 0 when the render thread is stalled "
        "(tessera_render_busy_seconds) or the device is lost (tessera_device_lost).",
        g.serving);
    add("tessera_render_busy_seconds",
        "Seconds the render thread has spent in the frame it is rendering now (0: idle).",
        g.render_busy_seconds);
    add("tessera_device_lost", "1 once the Vulkan device is lost (tesserad then exits).",
        g.device_lost);
    add("tessera_render_stalls", "Times health turned NOT_SERVING because a frame took longer "
        "than --render_stall_s.", static_cast<double>(g.render_stalls));
    add("tessera_accepting_sessions",
        "1 while a new Stream session would be taken (readiness, grpc.health.v1 service "
        "tessera.v1.RenderService): serving, not shutting down, below --max_sessions.",
        g.accepting_sessions);
    add("tessera_scene_store_evictions",
        "Scenes this replica evicted from the shared scene store (--scene_store_dir) to stay "
        "under --scene_store_max_mb.",
        static_cast<double>(g.scene_store_evictions));
    return families;
  }

 private:
  const std::function<MetricsGauges()> gauges_;
};

// An address that reaches the endpoint bound to `listen` on `port`: the listen host, or loopback
// for a wildcard host. nullopt when it does not resolve.
struct WakeAddress {
  sockaddr_storage addr{};
  socklen_t len = 0;
};
std::optional<WakeAddress> ResolveWakeAddress(const std::string& listen, int port) {
  std::string host = listen.substr(0, listen.rfind(':'));
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  if (host == "0.0.0.0") host = "127.0.0.1";
  if (host == "::") host = "::1";
  addrinfo hints{};
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_NUMERICSERV;
  addrinfo* found = nullptr;
  if (::getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &found) != 0 || !found)
    return std::nullopt;
  WakeAddress wake;
  if (found->ai_addrlen <= sizeof(wake.addr)) {
    std::memcpy(&wake.addr, found->ai_addr, found->ai_addrlen);
    wake.len = static_cast<socklen_t>(found->ai_addrlen);
  }
  ::freeaddrinfo(found);
  if (wake.len == 0) return std::nullopt;
  return wake;
}

// Destroys `exposer`, which stops civetweb and joins its threads (so no scrape runs afterwards).
// civetweb 1.15's master thread checks for a stop only between polls of its listening socket,
// and those polls wait up to 2 s (SOCKET_TIMEOUT_QUANTUM), so a bare stop takes up to 2 s of
// tesserad's shutdown (and of every test that serves). A connection wakes the poll, so a helper
// thread connects every 10 ms until the stop is done. Without `wake`, the stop just takes longer.
void StopEndpoint(std::unique_ptr<prometheus::Exposer> exposer,
                  const std::optional<WakeAddress>& wake) {
  std::mutex mu;
  std::condition_variable cv;
  bool stopped = false;
  std::thread waker;
  if (wake) {
    waker = std::thread([&] {
      std::unique_lock lock(mu);
      while (!cv.wait_for(lock, std::chrono::milliseconds(10), [&] { return stopped; })) {
        lock.unlock();
        const int fd = ::socket(wake->addr.ss_family, SOCK_STREAM | SOCK_CLOEXEC, 0);
        if (fd >= 0) {
          // Refused once the listening socket is closed; either way the poke is done.
          (void)::connect(fd, reinterpret_cast<const sockaddr*>(&wake->addr), wake->len);
          ::close(fd);
        }
        lock.lock();
      }
    });
  }
  exposer.reset();
  {
    std::lock_guard lock(mu);
    stopped = true;
  }
  cv.notify_all();
  if (waker.joinable()) waker.join();
}

}  // namespace

std::string_view GrpcCodeName(int code) { return kCodeNames[CodeIndex(code)]; }

struct Metrics::Impl {
  explicit Impl(std::function<MetricsGauges()> gauge_fn)
      : gauges(std::make_shared<GaugeCollectable>(std::move(gauge_fn))) {}

  std::shared_ptr<prometheus::Registry> registry = std::make_shared<prometheus::Registry>();
  std::shared_ptr<GaugeCollectable> gauges;

  // Families, owned by `registry`.
  Family<Counter>* frames = nullptr;
  Family<Counter>* frames_dropped = nullptr;
  Family<Counter>* uploads = nullptr;
  Family<Counter>* upload_bytes = nullptr;
  Family<Counter>* rpcs = nullptr;
  Family<Counter>* sessions_opened = nullptr;
  Family<Counter>* scenes_evicted = nullptr;
  Family<Histogram>* pass_gpu = nullptr;
  Family<Histogram>* frame_gpu = nullptr;
  Family<Histogram>* encode = nullptr;
  Family<Histogram>* frame_total = nullptr;
  Family<Histogram>* video_encode = nullptr;
  Family<Counter>* video_bytes = nullptr;
  Family<Counter>* video_frames = nullptr;

  // Series without labels, created up front.
  Counter* frames_dropped_series = nullptr;
  Counter* upload_bytes_series = nullptr;
  Counter* scenes_evicted_series = nullptr;
  std::array<Counter*, 2> sessions_opened_series{};  // [resumed]
  Histogram* frame_gpu_series = nullptr;
  Histogram* encode_series = nullptr;
  Histogram* video_encode_series = nullptr;
  Counter* video_bytes_series = nullptr;
  std::array<Counter*, 2> video_frames_series{};  // [keyframe]

  // Labelled series by label value. Family::Add would find an existing series by itself, but it
  // builds a Labels map and a new metric (for a histogram: its buckets) on every call, so the
  // hot paths look here first. Series are never removed, so the pointers stay valid. Counters are
  // atomic and histograms have their own lock; only FrameDone's per-pass observations are made
  // under `mu` (one acquisition for all passes rather than one per pass).
  std::mutex mu;
  ByName<ByName<Counter*>> frames_by_kind_profile;
  ByName<Histogram*> pass_gpu_by_pass;
  ByName<Histogram*> frame_total_by_kind;
  ByName<Counter*> uploads_by_result;
  ByName<std::array<Counter*, kCodeNames.size()>> rpcs_by_method;

  // mu held.
  Counter& FramesSeries(std::string_view kind, std::string_view profile) {
    Counter*& c = Slot(Slot(frames_by_kind_profile, kind), profile);
    if (!c) c = &frames->Add({{"kind", std::string(kind)}, {"profile", std::string(profile)}});
    return *c;
  }
  Counter& UploadsSeries(std::string_view result) {
    Counter*& c = Slot(uploads_by_result, result);
    if (!c) c = &uploads->Add({{"result", std::string(result)}});
    return *c;
  }
  Histogram& Labelled(ByName<Histogram*>& cache, Family<Histogram>& family, const char* label,
                      std::string_view value) {
    Histogram*& h = Slot(cache, value);
    if (!h) h = &family.Add({{label, std::string(value)}}, MillisecondBuckets());
    return *h;
  }

  // The endpoint, last so that it is destroyed first: civetweb joins its threads, so no scrape
  // runs (and calls the gauge callback) once the rest of Metrics goes away.
  std::mutex serve_mu;
  int port = 0;
  std::optional<WakeAddress> wake;  // see StopEndpoint
  std::unique_ptr<prometheus::Exposer> exposer;
};

Metrics::Metrics(std::function<MetricsGauges()> gauges)
    : impl_(std::make_unique<Impl>(std::move(gauges))) {
  Impl& m = *impl_;
  prometheus::Registry& r = *m.registry;
  m.frames = &prometheus::BuildCounter()
                  .Name("tessera_frames_total")
                  .Help(
                      "Frames rendered and encoded, by kind (stream, render, background) and "
                      "profile (full, interactive).")
                  .Register(r);
  m.frames_dropped = &prometheus::BuildCounter()
                          .Name("tessera_frames_dropped_total")
                          .Help(
                              "Encoded frames replaced in a session's slot by a newer frame "
                              "before they were sent.")
                          .Register(r);
  m.uploads = &prometheus::BuildCounter()
                   .Name("tessera_uploads_total")
                   .Help("Finished uploads, by result (loaded, cached, error).")
                   .Register(r);
  m.upload_bytes = &prometheus::BuildCounter()
                        .Name("tessera_upload_bytes_total")
                        .Help("File bytes received by finished uploads, whatever the result.")
                        .Register(r);
  m.rpcs = &prometheus::BuildCounter()
                .Name("tessera_rpcs_total")
                .Help("Finished RPCs, by method and gRPC status code name.")
                .Register(r);
  m.sessions_opened = &prometheus::BuildCounter()
                           .Name("tessera_sessions_opened_total")
                           .Help("Stream sessions opened, by whether they resumed a parked one.")
                           .Register(r);
  m.scenes_evicted = &prometheus::BuildCounter()
                          .Name("tessera_scenes_evicted_total")
                          .Help("Scenes evicted from memory to stay within the memory budget.")
                          .Register(r);
  m.pass_gpu = &prometheus::BuildHistogram()
                    .Name("tessera_pass_gpu_milliseconds")
                    .Help("GPU time of one render pass of one frame, in milliseconds, by pass.")
                    .Register(r);
  m.frame_gpu = &prometheus::BuildHistogram()
                     .Name("tessera_frame_gpu_milliseconds")
                     .Help("GPU time of one frame, all passes, in milliseconds.")
                     .Register(r);
  m.encode = &prometheus::BuildHistogram()
                  .Name("tessera_encode_milliseconds")
                  .Help("Time to encode one frame (JPEG/PNG), in milliseconds.")
                  .Register(r);
  m.frame_total = &prometheus::BuildHistogram()
                       .Name("tessera_frame_total_milliseconds")
                       .Help(
                           "Time from the request (or the newest change) to the encoded "
                           "frame, in milliseconds, by kind.")
                       .Register(r);

  m.frames_dropped_series = &m.frames_dropped->Add({});
  m.upload_bytes_series = &m.upload_bytes->Add({});
  m.scenes_evicted_series = &m.scenes_evicted->Add({});
  m.sessions_opened_series[0] = &m.sessions_opened->Add({{"resumed", "false"}});
  m.sessions_opened_series[1] = &m.sessions_opened->Add({{"resumed", "true"}});
  m.frame_gpu_series = &m.frame_gpu->Add({}, MillisecondBuckets());
  m.encode_series = &m.encode->Add({}, MillisecondBuckets());
  m.video_encode = &prometheus::BuildHistogram()
                        .Name("tessera_video_encode_milliseconds")
                        .Help("Time to encode one video (h264) frame, RGB->YUV included, in ms.")
                        .Register(r);
  m.video_bytes = &prometheus::BuildCounter()
                       .Name("tessera_video_bytes_total")
                       .Help("Bytes of encoded video (h264) frames sent to sessions.")
                       .Register(r);
  m.video_frames = &prometheus::BuildCounter()
                        .Name("tessera_video_frames_total")
                        .Help("Encoded video (h264) frames, by whether they were keyframes.")
                        .Register(r);
  m.video_encode_series = &m.video_encode->Add({}, MillisecondBuckets());
  m.video_bytes_series = &m.video_bytes->Add({});
  m.video_frames_series = {&m.video_frames->Add({{"keyframe", "false"}}),
                           &m.video_frames->Add({{"keyframe", "true"}})};
  // The known series start at 0 so that rate() and increase() see their first increment.
  std::lock_guard lock(m.mu);
  for (std::string_view kind : {"stream", "render", "background"}) {
    for (std::string_view profile : {"full", "interactive"}) m.FramesSeries(kind, profile);
  }
  for (std::string_view result : {"loaded", "cached", "error"}) m.UploadsSeries(result);
}

Metrics::~Metrics() {
  // Stop the endpoint explicitly, quickly, before the families and the gauge callback's owner go.
  std::lock_guard lock(impl_->serve_mu);
  if (impl_->exposer) StopEndpoint(std::move(impl_->exposer), impl_->wake);
}

absl::StatusOr<int> Metrics::Serve(const std::string& listen) {
  Impl& m = *impl_;
  std::lock_guard lock(m.serve_mu);
  if (m.exposer)
    return absl::FailedPreconditionError(
        absl::StrCat("metrics: already serving on port ", m.port, "; Serve is called once"));
  // host:port with a decimal port; civetweb would also refuse anything else, less clearly.
  const size_t colon = listen.rfind(':');
  const size_t digits = colon == std::string::npos ? 0 : listen.size() - colon - 1;
  uint32_t port = 0;
  for (size_t k = colon + 1; digits > 0 && digits <= 5 && k < listen.size(); ++k) {
    if (!absl::ascii_isdigit(static_cast<unsigned char>(listen[k]))) {
      port = ~0u;
      break;
    }
    port = port * 10 + static_cast<uint32_t>(listen[k] - '0');
  }
  if (colon == std::string::npos || colon == 0 || digits == 0 || digits > 5 || port > 65535)
    return absl::InvalidArgumentError(
        absl::StrCat("metrics listen \"", listen, "\": want host:port (port 0 picks one)"));

  // civetweb's CivetServer throws (CivetException) when it cannot bind; turn that into a status.
  std::unique_ptr<prometheus::Exposer> exposer;
  try {
    exposer = std::make_unique<prometheus::Exposer>(std::vector<std::string>{
        "listening_ports", listen, "num_threads", "2",
        // A client that connects and sends nothing gives up its thread after 10 s.
        "request_timeout_ms", "10000"});
  } catch (const std::exception& e) {
    return absl::UnavailableError(absl::StrCat("metrics: cannot listen on \"", listen,
                                               "\" (in use or not a local address): ", e.what()));
  } catch (...) {
    return absl::UnavailableError(
        absl::StrCat("metrics: cannot listen on \"", listen, "\" (in use or not a local address)"));
  }
  const std::vector<int> ports = exposer->GetListeningPorts();
  if (ports.empty() || ports.front() <= 0)
    return absl::UnavailableError(
        absl::StrCat("metrics: cannot listen on \"", listen, "\" (no bound port)"));
  exposer->RegisterCollectable(m.registry);
  exposer->RegisterCollectable(m.gauges);
  m.port = ports.front();
  m.wake = ResolveWakeAddress(listen, m.port);
  m.exposer = std::move(exposer);
  return m.port;
}

void Metrics::FrameDone(std::string_view kind, std::string_view profile,
                        const std::vector<std::pair<std::string, double>>& pass_ms,
                        double gpu_total_ms, double encode_ms, double total_ms) {
  Impl& m = *impl_;
  Counter* frames;
  Histogram* total;
  {
    std::lock_guard lock(m.mu);
    frames = &m.FramesSeries(kind, profile);
    total = &m.Labelled(m.frame_total_by_kind, *m.frame_total, "kind", kind);
    for (const auto& [pass, ms] : pass_ms) {
      if (Observable(ms)) m.Labelled(m.pass_gpu_by_pass, *m.pass_gpu, "pass", pass).Observe(ms);
    }
  }
  frames->Increment();
  if (Observable(gpu_total_ms)) m.frame_gpu_series->Observe(gpu_total_ms);
  if (Observable(encode_ms)) m.encode_series->Observe(encode_ms);
  if (Observable(total_ms)) total->Observe(total_ms);
}

void Metrics::FrameDropped() { impl_->frames_dropped_series->Increment(); }

void Metrics::VideoFrameEncoded(double encode_ms, uint64_t bytes, bool keyframe) {
  Impl& m = *impl_;
  if (Observable(encode_ms)) m.video_encode_series->Observe(encode_ms);
  m.video_bytes_series->Increment(static_cast<double>(bytes));
  m.video_frames_series[keyframe ? 1 : 0]->Increment();
}

void Metrics::UploadFinished(std::string_view result, uint64_t bytes) {
  Impl& m = *impl_;
  Counter* uploads;
  {
    std::lock_guard lock(m.mu);
    uploads = &m.UploadsSeries(result);
  }
  uploads->Increment();
  m.upload_bytes_series->Increment(static_cast<double>(bytes));
}

void Metrics::RpcFinished(std::string_view method, int grpc_code) {
  Impl& m = *impl_;
  const int code = CodeIndex(grpc_code);
  Counter* rpcs;
  {
    std::lock_guard lock(m.mu);
    Counter*& c = Slot(m.rpcs_by_method, method)[code];
    if (!c)
      c = &m.rpcs->Add({{"method", std::string(method)}, {"code", std::string(kCodeNames[code])}});
    rpcs = c;
  }
  rpcs->Increment();
}

void Metrics::SessionOpened(bool resumed) {
  impl_->sessions_opened_series[resumed ? 1 : 0]->Increment();
}

void Metrics::SceneEvicted() { impl_->scenes_evicted_series->Increment(); }

std::string Metrics::Text() const {
  std::vector<prometheus::MetricFamily> families = impl_->registry->Collect();
  std::vector<prometheus::MetricFamily> gauges = impl_->gauges->Collect();
  families.insert(families.end(), std::make_move_iterator(gauges.begin()),
                  std::make_move_iterator(gauges.end()));
  return prometheus::TextSerializer().Serialize(families);
}

}  // namespace tessera::server
