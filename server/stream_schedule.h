#pragma once
// The scheduling rules of one Stream session, apart from gRPC, threads and the clock: what the
// session renders next, when, and at which profile, and when its stream ends. The reactor
// (stream_session.cpp) tells it what happened (an event from the client, a frame taken,
// rendered or written, the client gone) with the time, and asks Next(now) what to do; it owns
// the frames and the session's settings, the schedule only their timing.
//
// The rules:
//  - Latest wins: changes (camera, settings, refresh) only mark the session dirty; the frame
//    taken next reflects all of them, and its queue wait starts at the oldest one.
//  - Continuous sessions (target_fps > 0) also render on a cadence of 1/target_fps, which
//    never tries to catch up on ticks missed while busy. A half-closed stream stops it.
//  - Idle refinement: while the camera moved within the rest time, frames use the interactive
//    profile (when the session has one that reduces anything); after an interactive frame one
//    full-quality frame follows once the camera rests. A resumed session's first frame is full.
//  - Settling: with settle_frames (TAA), full frames keep coming once nothing has changed for
//    the rest time, until that many full frames reflect the newest change; then nothing.
//  - Never sooner than the max_session_fps interval after the previous frame started.
//  - Back-pressure: at most kMaxFramesInPipeline frames rendering or encoding, and nothing
//    new while an encoded frame waits for the client (a slow reader gets fewer frames). A frame
//    arriving while one waits replaces it (latest wins); an older one than delivered is stale.
//  - The end: a client that vanished gets CANCELLED and, unless it half-closed first, its
//    session is parked for a resume; an error ends the stream with it; a stopping server ends
//    it with UNAVAILABLE once the frames in flight are out; a half-closed stream ends OK once
//    nothing is in flight or owed. Never while a write is outstanding.
#include <chrono>
#include <cstdint>
#include <optional>

#include "absl/status/status.h"

namespace tessera::server {

using Clock = std::chrono::steady_clock;

// How a session paces its frames (its target_fps and interactive profile).
struct StreamPacing {
  float target_fps = 0.0f;  // continuous frames per second; 0: frames only when something changed
  // Frames while the camera moves may use the interactive profile (it is enabled and lowers
  // the render scale or the JPEG quality).
  bool interactive = false;
  // The camera rests this long after its newest event (InteractiveProfile.rest_ms).
  Clock::duration rest = std::chrono::milliseconds(250);
  // Full-quality frames owed after the newest change once the camera rests (`rest` after it),
  // one after another (within the fps cap): TAA's history converges on a resting camera
  // instead of stopping at the first frame (aa = taa: 16; 0 otherwise). A camera that keeps
  // moving gets one frame per change, as without settling.
  uint32_t settle_frames = 0;
};

enum class FrameProfile { kFull, kInteractive };

// A frame the session starts now (Take).
struct FrameStart {
  FrameProfile profile = FrameProfile::kFull;
  // Start of its queue wait: the oldest change it reflects, else the cadence tick it serves.
  Clock::time_point requested;
};

// What the reactor does next, after Next(now); every step is for the reactor to perform.
struct StreamDecision {
  bool write = false;    // write the waiting frame (it leaves the slot)
  bool park = false;     // keep the session's state for a resume, before finishing
  bool enqueue = false;  // put the session in the render loop's ready queue now
  std::optional<Clock::time_point> enqueue_at;  // set a render-loop timer
  std::optional<absl::Status> finish;           // end the stream with this status
};

// What becomes of a frame that comes back from the render loop (FrameDone).
enum class Arrival {
  kIgnored,       // dropped by the loop, failed, or the stream is ending: nothing to keep
  kStale,         // older than a frame already delivered (overtaken in the encoder pool): drop
  kToSlot,        // the newest frame: waits in the slot for the client
  kReplacesSlot,  // the newest frame; the one waiting in the slot is dropped (latest wins)
};

class StreamSchedule {
 public:
  static constexpr int kMaxFramesInPipeline = 2;  // frames rendering or encoding at once

  // `min_interval`: 1 / max_session_fps. `may_park`: a vanished client's session is kept for a
  // resume (resume_grace_s > 0).
  StreamSchedule(Clock::duration min_interval, bool may_park)
      : min_interval_(min_interval), may_park_(may_park) {}

  // --- The stream's life.
  // Admission refused: the stream ends before it starts.
  void Refuse() { phase_ = Phase::kFinished; }
  // The session opened: its first frame is due at once and the cadence starts now.
  void Open(Clock::time_point now, const StreamPacing& pacing);
  // A parked (or handed-over) session continues here; its first frame is full quality.
  // `newest_sequence`: the last frame made before.
  void Resume(Clock::time_point now, const StreamPacing& pacing, uint64_t newest_sequence);
  // The session's state went to another stream: this one ends with ABORTED (unless it has an
  // error already), and the frame waiting for the client is dropped (the caller drops its bytes).
  void HandOver();
  // The client half-closed its side (no more events).
  void ReadsDone() { reads_done_ = true; }
  // The client is gone (cancelled, or a write failed).
  void ClientGone() { client_gone_ = true; }
  // The server is stopping: no new frames.
  void Stop() { stopping_ = true; }
  // The stream ends with `status` (the first error wins): false when it had one already.
  bool Fail(const absl::Status& status);

  // --- Events from the client (already validated and applied by the reactor).
  void SetPacing(const StreamPacing& pacing) { pacing_ = pacing; }
  // Something the frame shows changed (settings, camera, refresh): a frame is due.
  void Changed(Clock::time_point now);
  // The camera moved (with Changed): the interactive profile applies for the rest time.
  void CameraMoved(Clock::time_point now) { last_motion_ = now; }
  // target_fps was set: the cadence restarts now.
  void RestartCadence(Clock::time_point now) { next_due_ = now; }

  // --- The render loop and the writer.
  // The loop gives the session its turn (a ready entry or a timer): the frame to start now, or
  // nullopt when none is due (call Next then).
  std::optional<FrameStart> Take(Clock::time_point now);
  // A frame taken earlier came back (`sequence` 0: the loop dropped the session's entry while
  // stopping, with UNAVAILABLE). An UNAVAILABLE failure stops the stream, any other ends it.
  Arrival FrameDone(uint64_t sequence, const absl::Status& status);
  // The write started by a `write` decision finished; `ok` false: the client is gone.
  void WriteDone(bool ok);

  // The next steps: start a write, queue or time the session in the render loop, park, finish.
  StreamDecision Next(Clock::time_point now);

  // --- State.
  bool opened() const { return phase_ != Phase::kAwaitingOpen; }
  bool finished() const { return phase_ == Phase::kFinished; }
  // Events are applied (open or update); false once the stream is ending or its state left.
  bool TakesEvents() const {
    return (phase_ == Phase::kAwaitingOpen || phase_ == Phase::kLive) && !error_;
  }
  // The session state is here and the stream not ending: it may be handed to a resume.
  bool CanHandOver() const { return phase_ == Phase::kLive; }
  bool failed() const { return error_.has_value(); }
  bool frame_waiting() const { return slot_full_; }
  uint64_t newest_delivered() const { return newest_delivered_; }

 private:
  enum class Phase {
    kAwaitingOpen,  // the first event opens the session
    kLive,          // the session's state is here
    kLeft,          // the state left (parked or handed to another stream); the stream is ending
    kFinished,      // the stream's end is decided (or it was never admitted)
  };
  // What the next frame owes the viewer beyond reflecting the newest change.
  enum class Owed {
    kNothing,
    kRestFrame,  // the newest frame was interactive: a full one once the camera rests
    kFullNow,    // the next frame is full quality (resume)
  };

  bool CanRender() const;
  bool Continuous() const { return pacing_.target_fps > 0.0f && !reads_done_; }
  bool Moving(Clock::time_point now) const;
  // When the session next wants the render thread (never: nullopt).
  std::optional<Clock::time_point> Wake() const;
  std::optional<absl::Status> End();

  const Clock::duration min_interval_;
  const bool may_park_;
  StreamPacing pacing_;
  Phase phase_ = Phase::kAwaitingOpen;

  // Demand.
  std::optional<Clock::time_point> dirty_since_;  // the oldest change no frame reflects yet
  Owed owed_ = Owed::kNothing;
  Clock::time_point next_due_;                    // the cadence's next tick
  std::optional<Clock::time_point> last_motion_;  // the newest camera event
  std::optional<Clock::time_point> last_start_;   // the newest frame's start (fps cap)
  uint32_t settled_ = 0;  // full frames taken since the newest change (settle_frames)
  std::optional<Clock::time_point> last_change_;  // the newest change (settling starts at rest)

  // The render loop's hold on the session.
  bool in_ready_ = false;                      // in the ready queue
  std::optional<Clock::time_point> armed_at_;  // the earliest timer set
  int in_pipeline_ = 0;                        // frames rendering or encoding

  // Frames on their way to the client.
  uint64_t newest_delivered_ = 0;
  bool slot_full_ = false;  // an encoded frame waits for the client
  bool writing_ = false;    // a write is outstanding

  // Why the stream ends.
  bool reads_done_ = false;
  bool client_gone_ = false;
  bool stopping_ = false;
  std::optional<absl::Status> error_;
};

}  // namespace tessera::server
