#pragma once
// Stream: one viewer's session, a gRPC bidi reactor and a client of the render loop. It
// validates and applies the client's events to the session's state (scene lease, settings,
// camera, profile), and leaves every decision about frames (which, when, at which profile,
// when the stream ends) to its StreamSchedule (stream_schedule.h).
//
// Everything that changes session state happens under mu_, which decides what to do next
// (write, enqueue, park, finish); the gRPC calls and the render-loop calls happen after
// unlocking, so reactions that run inline cannot deadlock. Lock order: a session's mu_ may be
// held while taking ServiceState::sessions_mu (parking), never the other way round.
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "common/video.h"
#include "server/render_loop.h"
#include "server/service.h"
#include "server/stream_schedule.h"
#include "tessera/v1/render_service.grpc.pb.h"

namespace tessera::server {

class StreamSession final : public grpc::ServerBidiReactor<v1::ClientEvent, v1::Frame>,
                            public RenderClient,
                            public std::enable_shared_from_this<StreamSession> {
 public:
  StreamSession(ServiceState* state, grpc::CallbackServerContext* ctx,
                std::shared_ptr<const Principal> principal);

  // After construction by make_shared: the reactor keeps itself alive until OnDone. A failed
  // `admission` ends the stream with it at once.
  void Begin(const absl::Status& admission);

  void OnReadDone(bool ok) override;
  void OnWriteDone(bool ok) override;
  void OnCancel() override;
  void OnDone() override;

  std::optional<RenderWork> TakeWork() override;
  void Deliver(const RenderWork& work, absl::StatusOr<EncodedFrame> frame) override;

  // The server is stopping: no new frames; the stream ends with UNAVAILABLE once the frames
  // in flight are written.
  void Stop();

  // Another stream resumes this session (its client reconnected before this stream noticed
  // the old connection was gone): gives up the state and ends this stream with ABORTED.
  // nullopt when the state is not here or belongs to someone else.
  std::optional<SessionState> Handover(const std::string& principal);

 private:
  // One event, under mu_: opens, resumes or updates the session; the stream fails with an
  // error it returns.
  void ApplyEventLocked(Clock::time_point now, std::optional<absl::StatusOr<SessionState>> resumed);
  // OnReadDone once the opening event's scene is in memory (or could not be loaded).
  void HandleRead(bool ok, bool opened);
  absl::Status OpenLocked(Clock::time_point now);
  absl::Status ResumeLocked(Clock::time_point now, absl::StatusOr<SessionState> resumed);
  absl::Status ApplyUpdateLocked(Clock::time_point now);
  absl::Status CheckTargetFpsLocked(float fps, const char* field);
  void MarkDirtyLocked(Clock::time_point now);
  StreamPacing PacingLocked() const;
  void Register();

  RenderWork MakeWorkLocked(const FrameStart& start);
  // A rendered frame into the slot (or dropped), as the schedule decides.
  // `pixels` (video sessions' unencoded frames) is taken when the frame is kept.
  void KeepFrameLocked(Arrival arrival, v1::Frame frame, std::optional<Frame>* pixels);
  void Drop();

  // Applies `change` under mu_, then performs what the schedule decides after unlocking.
  template <typename Change>
  void React(Change&& change) {
    StreamDecision decision;
    {
      std::lock_guard lock(mu_);
      change();
      decision = DecideLocked(Clock::now());
    }
    Perform(decision);
  }
  // The schedule's next steps; the parts that move session state (the frame to write, the
  // parked state) happen here under mu_, the rest in Perform after unlocking.
  StreamDecision DecideLocked(Clock::time_point now);
  void Perform(const StreamDecision& d);
  void FinishCounted(const grpc::Status& status);

  ServiceState* const state_;
  grpc::CallbackServerContext* const ctx_;
  const std::shared_ptr<const Principal> principal_;
  const Clock::time_point opened_at_;
  std::shared_ptr<StreamSession> self_;  // until OnDone
  v1::ClientEvent event_;                // read buffer (one read at a time)
  absl::Status scene_load_;              // loading the opening event's scene, if it failed

  std::mutex mu_;
  StreamSchedule schedule_;
  SessionState st_;                // moved out when parked or handed over
  std::string fps_note_;           // target_fps was lowered to the cap
  std::optional<v1::Frame> slot_;  // the newest encoded frame not yet written
  v1::Frame writing_frame_;        // owned by gRPC while a write is outstanding

  // Video (h264) sessions. A frame waits in the slot unencoded, with its pixels; a newer one
  // replaces it (latest wins) before it costs an encode. The write decision takes it with what
  // its encode needs, and the encode runs on the encoder pool, then the write starts: so the
  // encoder sees exactly the frames the client gets, in order, and no reference is ever
  // missing. Only that one encode-and-write touches encoder_ and writing_pixels_.
  struct VideoWrite {
    VideoSettings video;
    uint64_t generation = 0;
    bool keyframe = false;  // the client asked for one
    uint32_t crf = 0;       // this frame's: interactive_crf while the camera moves
  };
  void EncodeAndWrite();
  std::optional<Frame> slot_pixels_;  // the rendered frame, for its pixels (owned or lent)
  Frame writing_pixels_;
  std::optional<VideoWrite> writing_video_;
  bool keyframe_requested_ = false;
  std::unique_ptr<video::Encoder> encoder_;
  uint64_t encoder_generation_ = 0;
  uint64_t frames_sent_ = 0;
  uint64_t frames_dropped_ = 0;
  std::string end_status_;
};

}  // namespace tessera::server
