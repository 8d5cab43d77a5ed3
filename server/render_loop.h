#pragma once
// The render thread and the encoder pool.
//
// Anything that wants frames is a RenderClient: a unary Render request or a streaming session.
// Clients with work wait in a FIFO ready queue; the render thread takes the front one, asks
// it for a snapshot of what to render (TakeWork), renders it, and hands the pixels to the
// encoder pool, then moves to the next client. A client that still has work afterwards goes to
// the back of the queue, so every client gets a turn: round-robin, nobody starves. Background
// work (batch renders, jobs) has its own queue, served when the normal one is empty, and while
// normal clients are active at background_share of the render thread's time (no more when the
// thread has idle moments, no less when viewers keep it busy).
//
// Encoding (bicubic upscale for interactive frames, JPEG/PNG) runs on the encoder pool, so the
// render thread renders frame N+1 while frame N is encoded. At most max_frames_in_flight
// rendered frames wait for or run on the encoders; the render thread waits when that many are
// out, which bounds the memory a slow encoder can pile up. With pipelined = false the render
// thread encodes each frame itself (the benchmark's serial baseline).
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <queue>
#include <thread>
#include <vector>

#include "absl/status/statusor.h"
#include "renderer/renderer.h"

namespace tessera::server {

class Metrics;

using Clock = std::chrono::steady_clock;

// A fixed set of worker threads running tasks in FIFO order.
class ThreadPool {
 public:
  ThreadPool(const char* name, uint32_t threads);
  ~ThreadPool();  // runs the queued tasks, then joins
  void Submit(std::function<void()> task);
  size_t pending() const;

 private:
  void Run();
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> tasks_;
  bool stop_ = false;
  std::vector<std::thread> threads_;
};

// One frame to render: a snapshot taken by the client under its own lock.
struct RenderWork {
  SceneHandle scene;
  Camera camera;
  Settings settings;
  ImageFormat format = ImageFormat::kJpeg;
  uint64_t sequence = 0;
  uint64_t event_id = 0;
  std::string scene_id;
  // The renderer view the frame belongs to: a stream's session id, so gpu_occlusion culling
  // starts from what that session saw last frame (0 for unary renders).
  uint64_t view = 0;
  Clock::time_point requested;  // the newest change or the request: start of queue wait
  // Interactive frames are rendered smaller and upscaled to this size before encoding (0: the
  // rendered size).
  uint32_t output_width = 0;
  uint32_t output_height = 0;
  const char* profile = "";      // Frame.profile ("full", "interactive"; "" for Render)
  const char* kind = "render";   // metrics label: "stream", "render", "background" or "job"
  // Job frames: the view starts from reset temporal state and is forgotten afterwards, and
  // `accumulate` frames are rendered at the camera (taa converging from a reset history) of
  // which the last is delivered. Deterministic: the same work gives the same pixels.
  bool fresh_view = false;
  uint32_t accumulate = 1;
};

// A rendered frame as the loop delivers it: the renderer's frame and its encoded bytes, with
// what the work asked for. Clients convert it for the wire themselves (ToProto in convert.h).
struct EncodedFrame {
  // The renderer's frame: timings (encode_ms includes an interactive frame's upscale), stats,
  // effective settings. Its pixels are released once encoded (format kRgba: they stay, for
  // the client to encode); image.width/height stay: the encoded size.
  Frame frame;
  std::vector<uint8_t> data;  // the encoded image
  ImageFormat format = ImageFormat::kJpeg;
  uint32_t render_width = 0;  // the rendered size (smaller than the image when upscaled)
  uint32_t render_height = 0;
  Camera camera;
  uint64_t sequence = 0;
  uint64_t event_id = 0;
  std::string scene_id;
  const char* profile = "";
  double queue_wait_ms = 0.0;  // from RenderWork::requested to the render's start
  double total_ms = 0.0;       // from RenderWork::requested to the encoded frame
};

enum class Priority { kNormal, kBackground };

struct RenderLoopOptions {
  uint32_t encoder_threads = 0;       // 0: one per core
  uint32_t max_frames_in_flight = 3;  // rendered frames out on the encoders at once
  bool pipelined = true;              // false: encode on the render thread (serial baseline)
  Metrics* metrics = nullptr;         // optional; outlives the loop
  // While normal clients are active (one was rendered in the last half second), background
  // frames take this share of the render thread: at most this much when viewers leave the
  // thread idle at times, and at least this much when they keep it busy. A live viewer's frame
  // rate drops by about this much while a job runs. 1: background runs whenever nothing else
  // waits (and never ahead of normal work).
  double background_share = 0.12;
  // Called once, on the render thread, when a frame fails because the Vulkan device was lost
  // (the renderer cannot go on; the server turns unhealthy and exits).
  std::function<void()> on_device_lost;
};

class RenderClient {
 public:
  virtual ~RenderClient() = default;
  // Render thread. What to render now, or nullopt if nothing (any more). Called once per turn.
  virtual std::optional<RenderWork> TakeWork() = 0;
  // Encoder thread (or render thread for errors and shutdown). The finished frame, or why
  // there is none (UNAVAILABLE when the loop stops).
  virtual void Deliver(const RenderWork& work, absl::StatusOr<EncodedFrame> frame) = 0;
};

class RenderLoop {
 public:
  RenderLoop(Renderer* renderer, const RenderLoopOptions& options);
  ~RenderLoop();  // Stop()

  // Puts `client` at the back of its priority's ready queue (callers avoid queueing one client
  // twice). After Stop(), the client is failed with UNAVAILABLE instead (without TakeWork).
  void Enqueue(std::shared_ptr<RenderClient> client, Priority priority = Priority::kNormal);
  // Enqueues `client` at `when` (continuous streaming at a target fps).
  void EnqueueAt(std::shared_ptr<RenderClient> client, Clock::time_point when);

  // Runs `task` on the encoder pool (a video session's encode, in its own order); on the
  // calling thread once the loop has stopped.
  void SubmitEncode(std::function<void()> task);

  // Finishes the frame being rendered, fails everything queued with UNAVAILABLE, waits for the
  // encoders, and joins the render thread. Idempotent.
  void Stop();

  uint32_t queue_depth() const;             // normal + background clients waiting
  uint32_t background_queue_depth() const;
  uint32_t frames_in_flight() const;        // rendered, not yet encoded and delivered
  uint64_t frames_rendered() const;
  // How long the render thread has been inside the one Render call it is in now; 0 when it is
  // not rendering. A frame takes milliseconds to seconds: much longer is a wedged device.
  double busy_seconds() const;
  const RenderLoopOptions& options() const { return options_; }

 private:
  void Run();
  // A frame accumulated over several renders (RenderWork::accumulate) that gave way to normal
  // work between renders: it goes on before any other background work.
  struct Accumulation {
    std::shared_ptr<RenderClient> client;
    RenderWork work;
    uint32_t rendered = 0;
    Clock::time_point started;
  };
  // Renders one turn of `client`; false when it had nothing to render.
  bool RenderOne(const std::shared_ptr<RenderClient>& client, bool background);
  // Renders the rest of `acc` (or until normal work waits, for background work), then hands
  // the frame to the encoders.
  void Accumulate(Accumulation acc, bool background);
  void EncodeAndDeliver(const std::shared_ptr<RenderClient>& client, const RenderWork& work,
                        Frame& frame, double queue_wait_ms);

  Renderer* renderer_;
  const RenderLoopOptions options_;
  std::mutex stop_mu_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::shared_ptr<RenderClient>> ready_;
  std::deque<std::shared_ptr<RenderClient>> background_;
  std::optional<Accumulation> accumulating_;
  std::condition_variable encoded_cv_;  // frames_in_flight_ went down
  uint32_t frames_in_flight_ = 0;
  using Timed = std::pair<Clock::time_point, std::shared_ptr<RenderClient>>;
  struct Later {
    bool operator()(const Timed& a, const Timed& b) const { return a.first > b.first; }
  };
  std::priority_queue<Timed, std::vector<Timed>, Later> timers_;
  bool stopping_ = false;
  uint64_t frames_rendered_ = 0;
  Clock::time_point last_normal_{};         // when a normal frame last finished rendering
  Clock::time_point background_not_before_{};  // background_share: the next background start
  std::unique_ptr<ThreadPool> encoders_;
  std::atomic<int64_t> busy_since_ns_{0};  // steady-clock time the current Render began; 0: idle
  std::atomic<bool> device_lost_reported_{false};
  std::thread thread_;
};

}  // namespace tessera::server
