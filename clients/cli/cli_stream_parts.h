#pragma once
// The moving parts of a live session (`tessera stream`, `tessera bench`): the orbit camera
// path, the event writer thread and the event-to-frame latency bookkeeping.
#include <grpcpp/grpcpp.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "tessera/v1/render_service.grpc.pb.h"

namespace tessera::cli {

using Clock = std::chrono::steady_clock;

// A camera circling a centre point around the world's Y axis at a fixed distance and height.
class Orbit {
 public:
  // Around the centre of `bounds`, far enough out that the bounding sphere stays in view from
  // every side, starting from the server's default framing direction.
  static Orbit FromBounds(const v1::Aabb& bounds, float yfov, float aspect);
  // Around `look_at.target`, through `look_at.eye`.
  static Orbit FromLookAt(const v1::LookAt& look_at);

  // The camera `step` steps along, with `base`'s yfov/znear/zfar. One turn takes
  // `steps_per_turn` steps.
  v1::Camera CameraAt(uint64_t step, uint64_t steps_per_turn, const v1::Camera& base) const;

 private:
  float centre_[3] = {0, 0, 0};
  float distance_ = 1;
  float elevation_ = 0;  // radians above the horizontal plane
  float azimuth_ = 0;    // radians, 0 = looking from +Z
};

// Send time of every event, and the time from sending event k until the first frame that
// reflects it (Frame.event_id >= k).
class LatencyTracker {
 public:
  void Sent(uint64_t event_id, Clock::time_point when);
  // Latencies (ms) of every event up to `event_id` that no earlier frame answered, in id order.
  std::vector<std::pair<uint64_t, double>> Answered(uint64_t event_id, Clock::time_point now);

 private:
  std::mutex mu_;
  std::map<uint64_t, Clock::time_point> pending_;
};

// Owns every write on the stream, from one thread (gRPC allows one writer and one reader at a
// time), so the reading thread never waits on the network to send.
//
// Events come from `next_event`, called on the writer thread; it may return nullopt when no
// event can be made yet. They are sent when requested (RequestEvent, one per call) or, with a
// period, at a steady rate. On Close() the writer half-closes the stream and then guards the
// end of the call: if the server has not ended it within `close_grace`, it cancels it. SIGINT
// (see InstallInterruptHandler) cancels the call too.
class EventWriter {
 public:
  using EventSource = std::function<std::optional<v1::ClientEvent>()>;

  EventWriter(grpc::ClientContext* context,
              grpc::ClientReaderWriter<v1::ClientEvent, v1::Frame>* stream, LatencyTracker* latency,
              EventSource next_event, std::optional<std::chrono::duration<double>> period);
  ~EventWriter();  // Close() and Join()

  // Writes `event` now, from the calling thread; only before the writer thread runs.
  bool WriteNow(const v1::ClientEvent& event);
  void Start();
  void RequestEvent();
  void Close();
  // Waits for the thread; call after the last Read and before Finish.
  void Join();

  bool write_failed() const { return write_failed_; }

 private:
  void Loop();
  bool Send(const v1::ClientEvent& event);
  // Waits for something to do; false when closing.
  bool WaitForWork(std::unique_lock<std::mutex>& lock);
  void GuardClose(std::unique_lock<std::mutex>& lock);

  grpc::ClientContext* context_;
  grpc::ClientReaderWriter<v1::ClientEvent, v1::Frame>* stream_;
  LatencyTracker* latency_;
  EventSource next_event_;
  std::optional<Clock::duration> period_;
  static constexpr std::chrono::seconds kCloseGrace{10};

  std::mutex mu_;
  std::condition_variable cv_;
  uint32_t requested_ = 0;
  bool closing_ = false;
  bool joined_ = false;
  Clock::time_point next_tick_;
  std::atomic<bool> write_failed_{false};
  std::thread thread_;
};

// SIGINT sets a flag the writer thread turns into a cancelled call, so Ctrl-C still prints the
// summary of the frames received so far. Restores the previous handler when destroyed.
class InterruptHandler {
 public:
  InterruptHandler();
  ~InterruptHandler();
  static bool interrupted();

 private:
  void (*previous_)(int);
};

}  // namespace tessera::cli
