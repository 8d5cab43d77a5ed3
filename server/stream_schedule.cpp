#include "server/stream_schedule.h"

#include <algorithm>

namespace tessera::server {

void StreamSchedule::Open(Clock::time_point now, const StreamPacing& pacing) {
  pacing_ = pacing;
  next_due_ = now;  // the first tick is the first frame; the cadence starts there
  phase_ = Phase::kLive;
  Changed(now);
}

void StreamSchedule::Resume(Clock::time_point now, const StreamPacing& pacing,
                            uint64_t newest_sequence) {
  pacing_ = pacing;
  newest_delivered_ = newest_sequence;
  next_due_ = now;
  phase_ = Phase::kLive;
  owed_ = Owed::kFullNow;  // a resumed viewer gets a full-quality frame at once
  dirty_since_ = now;
}

void StreamSchedule::HandOver() {
  phase_ = Phase::kLeft;
  slot_full_ = false;
  Fail(absl::AbortedError("session resumed by another stream"));
}

bool StreamSchedule::Fail(const absl::Status& status) {
  if (error_) return false;
  error_ = status;
  return true;
}

void StreamSchedule::Changed(Clock::time_point now) {
  if (!dirty_since_) dirty_since_ = now;
  settled_ = 0;
  last_change_ = now;
}

bool StreamSchedule::CanRender() const {
  return phase_ == Phase::kLive && !client_gone_ && !stopping_ && !error_ &&
         in_pipeline_ < kMaxFramesInPipeline && !slot_full_;
}

bool StreamSchedule::Moving(Clock::time_point now) const {
  return pacing_.interactive && last_motion_ && now < *last_motion_ + pacing_.rest;
}

// Something changed, the continuous cadence, or the full-quality frame after the camera rests;
// never sooner than the max_session_fps interval after the previous frame started.
std::optional<Clock::time_point> StreamSchedule::Wake() const {
  if (!CanRender()) return std::nullopt;
  std::optional<Clock::time_point> t;
  auto earliest = [&t](Clock::time_point x) { t = t ? std::min(*t, x) : x; };
  if (dirty_since_) earliest(Clock::time_point::min());
  if (Continuous()) earliest(next_due_);
  if (owed_ == Owed::kRestFrame && last_motion_) earliest(*last_motion_ + pacing_.rest);
  if (settled_ < pacing_.settle_frames) {  // once nothing has changed for the rest time
    earliest(last_change_ ? *last_change_ + pacing_.rest : Clock::time_point::min());
  }
  if (!t) return std::nullopt;
  if (last_start_) return std::max(*t, *last_start_ + min_interval_);
  return t;
}

std::optional<FrameStart> StreamSchedule::Take(Clock::time_point now) {
  // The loop cannot say whether a ready entry or a timer brought us here: clear the ready
  // flag, and the timer once it is due; a stale duplicate entry only costs a turn that finds
  // nothing due.
  in_ready_ = false;
  if (armed_at_ && now >= *armed_at_) armed_at_.reset();
  const std::optional<Clock::time_point> wake = Wake();
  if (!wake || *wake > now) return std::nullopt;
  FrameStart frame;
  if (owed_ != Owed::kFullNow && Moving(now)) {
    frame.profile = FrameProfile::kInteractive;
    owed_ = Owed::kRestFrame;
  } else {
    frame.profile = FrameProfile::kFull;
    owed_ = Owed::kNothing;
    ++settled_;
  }
  frame.requested = dirty_since_ ? *dirty_since_ : Continuous() ? std::min(now, next_due_) : now;
  dirty_since_.reset();
  if (Continuous()) {
    const auto period = std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(1.0 / pacing_.target_fps));
    // Keep the cadence, but never try to catch up on frames missed while busy.
    next_due_ = std::max(next_due_ + period, now);
  }
  last_start_ = now;
  ++in_pipeline_;
  return frame;
}

Arrival StreamSchedule::FrameDone(uint64_t sequence, const absl::Status& status) {
  if (sequence == 0) {
    in_ready_ = false;  // dropped from the queue by a stopping render loop
    armed_at_.reset();
    stopping_ = true;
  } else {
    --in_pipeline_;
  }
  if (!status.ok()) {
    if (absl::IsUnavailable(status))
      stopping_ = true;
    else
      Fail(status);
    return Arrival::kIgnored;
  }
  if (phase_ != Phase::kLive || client_gone_) return Arrival::kIgnored;
  if (sequence < newest_delivered_) return Arrival::kStale;
  newest_delivered_ = sequence;
  if (slot_full_) return Arrival::kReplacesSlot;
  slot_full_ = true;
  return Arrival::kToSlot;
}

void StreamSchedule::WriteDone(bool ok) {
  writing_ = false;
  if (!ok) client_gone_ = true;
}

std::optional<absl::Status> StreamSchedule::End() {
  const bool idle = in_pipeline_ == 0 && !slot_full_;
  if (client_gone_) return absl::CancelledError("client cancelled the stream");
  if (error_) return *error_;
  if (stopping_ && idle) return absl::UnavailableError("server is shutting down");
  if (reads_done_ && idle && !dirty_since_ && owed_ != Owed::kRestFrame) return absl::OkStatus();
  return std::nullopt;
}

StreamDecision StreamSchedule::Next(Clock::time_point now) {
  StreamDecision d;
  if (finished()) return d;
  if (!writing_ && slot_full_ && !client_gone_) {
    slot_full_ = false;
    writing_ = true;
    d.write = true;
  }
  if (!in_ready_) {
    if (std::optional<Clock::time_point> wake = Wake()) {
      if (*wake <= now) {
        in_ready_ = true;  // a change jumps the queue even while a timer is armed
        d.enqueue = true;
      } else if (!armed_at_ || *wake < *armed_at_) {
        armed_at_ = *wake;
        d.enqueue_at = *wake;
      }
    }
  }
  if (writing_) return d;  // never finish with a write outstanding
  d.finish = End();
  if (!d.finish) return d;
  // A client that vanished without closing keeps its session for a resume.
  d.park =
      client_gone_ && phase_ == Phase::kLive && !stopping_ && !error_ && !reads_done_ && may_park_;
  phase_ = Phase::kFinished;
  return d;
}

}  // namespace tessera::server
