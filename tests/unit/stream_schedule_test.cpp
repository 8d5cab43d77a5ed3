// The scheduling rules of a Stream session (server/stream_schedule.h) with the times passed in:
// sequences of events and render-loop turns -> which frames start, when, at which profile, and
// how the stream ends. No gRPC, no threads, no clock.
#include "server/stream_schedule.h"

#include <gtest/gtest.h>

#include <chrono>
#include <optional>

namespace tessera::server {
namespace {

using std::chrono::milliseconds;

Clock::time_point T(int ms) { return Clock::time_point{} + milliseconds(ms); }

StreamPacing Pacing(float fps, bool interactive = false, int rest_ms = 250) {
  StreamPacing p;
  p.target_fps = fps;
  p.interactive = interactive;
  p.rest = milliseconds(rest_ms);
  return p;
}

// A frame taken at `now` must start, with this profile.
FrameStart MustTake(StreamSchedule& s, Clock::time_point now, FrameProfile profile) {
  std::optional<FrameStart> f = s.Take(now);
  EXPECT_TRUE(f.has_value()) << "no frame due at " << (now - T(0)) / milliseconds(1) << " ms";
  if (!f) return {};
  EXPECT_EQ(f->profile, profile);
  return *f;
}

// Frame `sequence` comes back encoded and goes out to the client, who takes it: the decision
// made when it came back.
StreamDecision DeliverAndWrite(StreamSchedule& s, uint64_t sequence, Clock::time_point now) {
  EXPECT_EQ(s.FrameDone(sequence, absl::OkStatus()), Arrival::kToSlot);
  StreamDecision d = s.Next(now);
  EXPECT_TRUE(d.write);
  s.WriteDone(true);
  return d;
}

// A session opened at 0 whose first frame (sequence 1) started at 0.
StreamSchedule FirstFrameTaken(const StreamPacing& pacing,
                               Clock::duration min_interval = milliseconds(0)) {
  StreamSchedule s(min_interval, true);
  s.Open(T(0), pacing);
  EXPECT_TRUE(s.Next(T(0)).enqueue);
  MustTake(s, T(0), FrameProfile::kFull);
  return s;
}

bool Quiet(const StreamDecision& d) {
  return !d.write && !d.enqueue && !d.enqueue_at && !d.finish && !d.park;
}

TEST(StreamScheduleTest, OpenRendersOneFullFrameThenWaitsForAChange) {
  StreamSchedule s(milliseconds(0), true);
  s.Open(T(0), Pacing(0));
  StreamDecision d = s.Next(T(0));
  EXPECT_TRUE(d.enqueue);
  EXPECT_FALSE(d.enqueue_at);
  EXPECT_FALSE(d.finish);
  FrameStart f = MustTake(s, T(5), FrameProfile::kFull);
  EXPECT_EQ(f.requested, T(0));  // its queue wait starts at the open
  DeliverAndWrite(s, 1, T(30));
  EXPECT_TRUE(Quiet(s.Next(T(40))));
  EXPECT_FALSE(s.Take(T(1000)));  // nothing changed: no frame
}

TEST(StreamScheduleTest, ChangesCoalesceIntoOneFrameFromTheOldest) {
  StreamSchedule s(milliseconds(0), true);
  s.Open(T(0), Pacing(0));
  EXPECT_TRUE(s.Next(T(0)).enqueue);
  MustTake(s, T(1), FrameProfile::kFull);
  DeliverAndWrite(s, 1, T(20));
  s.Changed(T(30));
  EXPECT_TRUE(s.Next(T(30)).enqueue);
  // More changes while it waits in the ready queue: no second entry, one frame for all.
  s.Changed(T(31));
  EXPECT_FALSE(s.Next(T(31)).enqueue);
  s.Changed(T(32));
  FrameStart f = MustTake(s, T(40), FrameProfile::kFull);
  EXPECT_EQ(f.requested, T(30));
  EXPECT_FALSE(s.Take(T(41)));
}

TEST(StreamScheduleTest, InteractiveWhileTheCameraMovesThenOneFullFrameAtRest) {
  StreamSchedule s(milliseconds(0), true);
  s.Open(T(0), Pacing(0, /*interactive=*/true, /*rest_ms=*/250));
  s.Next(T(0));
  MustTake(s, T(0), FrameProfile::kFull);  // the camera has not moved yet
  DeliverAndWrite(s, 1, T(10));

  s.CameraMoved(T(100));
  s.Changed(T(100));
  EXPECT_TRUE(s.Next(T(100)).enqueue);
  MustTake(s, T(100), FrameProfile::kInteractive);
  EXPECT_EQ(s.FrameDone(2, absl::OkStatus()), Arrival::kToSlot);
  StreamDecision d = s.Next(T(120));
  EXPECT_TRUE(d.write);
  ASSERT_TRUE(d.enqueue_at);
  EXPECT_EQ(*d.enqueue_at, T(350));  // the full frame is owed once the camera rests
  s.WriteDone(true);
  EXPECT_FALSE(s.Next(T(130)).enqueue_at);  // that timer is set already

  // The camera moves again within the rest time: interactive again, rest moves on.
  s.CameraMoved(T(300));
  s.Changed(T(300));
  EXPECT_TRUE(s.Next(T(300)).enqueue);
  MustTake(s, T(300), FrameProfile::kInteractive);
  DeliverAndWrite(s, 3, T(320));
  EXPECT_FALSE(s.Take(T(350)));  // the old timer fires: not yet at rest
  d = s.Next(T(350));
  ASSERT_TRUE(d.enqueue_at);
  EXPECT_EQ(*d.enqueue_at, T(550));
  FrameStart f = MustTake(s, T(550), FrameProfile::kFull);
  EXPECT_EQ(f.requested, T(550));
  DeliverAndWrite(s, 4, T(560));
  EXPECT_TRUE(Quiet(s.Next(T(570))));  // nothing more is owed
}

TEST(StreamScheduleTest, WithoutAnInteractiveProfileMovingFramesAreFull) {
  StreamSchedule s = FirstFrameTaken(Pacing(0, /*interactive=*/false));
  DeliverAndWrite(s, 1, T(10));
  s.CameraMoved(T(20));
  s.Changed(T(20));
  s.Next(T(20));
  MustTake(s, T(20), FrameProfile::kFull);
  DeliverAndWrite(s, 2, T(30));
  EXPECT_TRUE(Quiet(s.Next(T(40))));  // no rest frame owed
}

TEST(StreamScheduleTest, AResumedSessionsFirstFrameIsFullEvenWhileMoving) {
  StreamSchedule s(milliseconds(0), true);
  s.Resume(T(0), Pacing(0, /*interactive=*/true), /*newest_sequence=*/7);
  s.CameraMoved(T(0));
  s.Changed(T(0));
  EXPECT_TRUE(s.Next(T(0)).enqueue);
  MustTake(s, T(1), FrameProfile::kFull);
  DeliverAndWrite(s, 8, T(10));
  s.CameraMoved(T(20));
  s.Changed(T(20));
  s.Next(T(20));
  MustTake(s, T(20), FrameProfile::kInteractive);
  EXPECT_EQ(s.FrameDone(6, absl::OkStatus()), Arrival::kStale);  // older than before the resume
}

TEST(StreamScheduleTest, ContinuousCadenceNeverCatchesUp) {
  StreamSchedule s(milliseconds(0), true);
  s.Open(T(0), Pacing(10));  // a frame every 100 ms
  s.Next(T(0));
  EXPECT_EQ(MustTake(s, T(0), FrameProfile::kFull).requested, T(0));
  StreamDecision d = DeliverAndWrite(s, 1, T(20));
  ASSERT_TRUE(d.enqueue_at);
  EXPECT_EQ(*d.enqueue_at, T(100));
  EXPECT_EQ(MustTake(s, T(100), FrameProfile::kFull).requested, T(100));
  d = DeliverAndWrite(s, 2, T(120));
  ASSERT_TRUE(d.enqueue_at);
  EXPECT_EQ(*d.enqueue_at, T(200));
  // The render thread was busy: the 200 ms tick is served at 350, and the 300 ms tick is
  // skipped rather than rendered at once.
  EXPECT_EQ(MustTake(s, T(350), FrameProfile::kFull).requested, T(200));
  d = DeliverAndWrite(s, 3, T(360));
  EXPECT_TRUE(d.enqueue);  // the next tick is now (350), not two behind
  EXPECT_EQ(MustTake(s, T(360), FrameProfile::kFull).requested, T(350));
  d = DeliverAndWrite(s, 4, T(370));
  ASSERT_TRUE(d.enqueue_at);
  EXPECT_EQ(*d.enqueue_at, T(450));
}

TEST(StreamScheduleTest, PausingAndRestartingTheCadence) {
  StreamSchedule s = FirstFrameTaken(Pacing(10));
  DeliverAndWrite(s, 1, T(10));
  s.SetPacing(Pacing(0));  // target_fps 0: frames only on change
  s.RestartCadence(T(20));
  EXPECT_TRUE(Quiet(s.Next(T(20))));
  EXPECT_FALSE(s.Take(T(500)));
  s.SetPacing(Pacing(10));
  s.RestartCadence(T(600));
  EXPECT_TRUE(s.Next(T(600)).enqueue);
  EXPECT_EQ(MustTake(s, T(600), FrameProfile::kFull).requested, T(600));
}

TEST(StreamScheduleTest, MaxSessionFpsSpacesFrameStarts) {
  StreamSchedule s = FirstFrameTaken(Pacing(0), milliseconds(100));
  DeliverAndWrite(s, 1, T(10));
  s.Changed(T(20));
  StreamDecision d = s.Next(T(20));
  EXPECT_FALSE(d.enqueue);
  ASSERT_TRUE(d.enqueue_at);
  EXPECT_EQ(*d.enqueue_at, T(100));
  EXPECT_FALSE(s.Take(T(50)));  // a stale entry finds nothing due
  EXPECT_EQ(MustTake(s, T(100), FrameProfile::kFull).requested, T(20));
}

TEST(StreamScheduleTest, AtMostTwoFramesInThePipeline) {
  StreamSchedule s = FirstFrameTaken(Pacing(0));
  s.Changed(T(1));
  EXPECT_TRUE(s.Next(T(1)).enqueue);
  MustTake(s, T(1), FrameProfile::kFull);
  s.Changed(T(2));
  EXPECT_FALSE(s.Next(T(2)).enqueue);  // two rendering or encoding
  EXPECT_FALSE(s.Take(T(2)));
  EXPECT_EQ(s.FrameDone(1, absl::OkStatus()), Arrival::kToSlot);
  StreamDecision d = s.Next(T(3));
  EXPECT_TRUE(d.write);
  EXPECT_TRUE(d.enqueue);  // one left the pipeline: the pending change goes
  EXPECT_EQ(MustTake(s, T(3), FrameProfile::kFull).requested, T(2));
}

TEST(StreamScheduleTest, ASlowReaderGetsTheNewestFrameAndNoQueue) {
  StreamSchedule s = FirstFrameTaken(Pacing(0));
  EXPECT_EQ(s.FrameDone(1, absl::OkStatus()), Arrival::kToSlot);
  EXPECT_TRUE(s.Next(T(10)).write);  // frame 1 is being written, slowly
  for (int i = 0; i < 2; ++i) {      // frames 2 and 3
    s.Changed(T(11 + i));
    EXPECT_TRUE(s.Next(T(11 + i)).enqueue);
    MustTake(s, T(11 + i), FrameProfile::kFull);
  }
  EXPECT_EQ(s.FrameDone(2, absl::OkStatus()), Arrival::kToSlot);
  EXPECT_EQ(s.FrameDone(3, absl::OkStatus()), Arrival::kReplacesSlot);  // latest wins
  EXPECT_TRUE(s.frame_waiting());
  // While a frame waits for the client nothing new is rendered, however much changes.
  s.Changed(T(20));
  StreamDecision d = s.Next(T(20));
  EXPECT_FALSE(d.write);  // one write at a time
  EXPECT_FALSE(d.enqueue);
  EXPECT_FALSE(d.enqueue_at);
  EXPECT_FALSE(s.Take(T(20)));
  s.WriteDone(true);
  d = s.Next(T(30));
  EXPECT_TRUE(d.write);    // frame 3
  EXPECT_TRUE(d.enqueue);  // and the change at 20
  EXPECT_EQ(MustTake(s, T(30), FrameProfile::kFull).requested, T(20));
}

TEST(StreamScheduleTest, AFrameOvertakenInTheEncoderPoolIsStale) {
  StreamSchedule s = FirstFrameTaken(Pacing(0));
  s.Changed(T(1));
  s.Next(T(1));
  MustTake(s, T(1), FrameProfile::kFull);
  EXPECT_EQ(s.FrameDone(2, absl::OkStatus()), Arrival::kToSlot);
  EXPECT_EQ(s.FrameDone(1, absl::OkStatus()), Arrival::kStale);
  EXPECT_EQ(s.newest_delivered(), 2u);
}

TEST(StreamScheduleTest, AVanishedClientIsParkedAfterItsWrite) {
  StreamSchedule s = FirstFrameTaken(Pacing(0));
  EXPECT_EQ(s.FrameDone(1, absl::OkStatus()), Arrival::kToSlot);
  EXPECT_TRUE(s.Next(T(10)).write);
  s.ClientGone();
  StreamDecision d = s.Next(T(11));
  EXPECT_FALSE(d.finish);  // never with a write outstanding
  s.WriteDone(false);
  d = s.Next(T(12));
  ASSERT_TRUE(d.finish);
  EXPECT_EQ(d.finish->code(), absl::StatusCode::kCancelled);
  EXPECT_EQ(d.finish->message(), "client cancelled the stream");
  EXPECT_TRUE(d.park);
  EXPECT_TRUE(s.finished());
  EXPECT_TRUE(Quiet(s.Next(T(13))));  // decided once
}

TEST(StreamScheduleTest, NoParkingAfterAHalfCloseAStopOrWithoutAGracePeriod) {
  auto vanish = [](StreamSchedule& s) {
    s.ClientGone();
    StreamDecision d = s.Next(T(10));
    EXPECT_TRUE(d.finish.has_value());
    EXPECT_EQ(d.finish.value_or(absl::OkStatus()).code(), absl::StatusCode::kCancelled);
    return d.park;
  };
  StreamSchedule closed(milliseconds(0), true);
  closed.Open(T(0), Pacing(0));
  closed.ReadsDone();
  EXPECT_FALSE(vanish(closed));
  StreamSchedule stopping(milliseconds(0), true);
  stopping.Open(T(0), Pacing(0));
  stopping.Stop();
  EXPECT_FALSE(vanish(stopping));
  StreamSchedule no_grace(milliseconds(0), false);
  no_grace.Open(T(0), Pacing(0));
  EXPECT_FALSE(vanish(no_grace));
  StreamSchedule never_opened(milliseconds(0), true);
  EXPECT_FALSE(vanish(never_opened));
}

TEST(StreamScheduleTest, AHalfClosedStreamEndsOkOnceTheRestFrameIsOut) {
  StreamSchedule s(milliseconds(0), true);
  s.Open(T(0), Pacing(30, /*interactive=*/true, /*rest_ms=*/100));
  s.CameraMoved(T(0));
  s.Next(T(0));
  MustTake(s, T(0), FrameProfile::kInteractive);
  s.ReadsDone();  // also ends the 30 fps cadence
  StreamDecision d = DeliverAndWrite(s, 1, T(10));
  ASSERT_TRUE(d.enqueue_at);
  EXPECT_EQ(*d.enqueue_at, T(100));  // the rest frame, not the cadence's tick at 33 ms
  EXPECT_FALSE(s.Next(T(20)).finish);
  MustTake(s, T(100), FrameProfile::kFull);
  EXPECT_FALSE(s.Next(T(101)).finish);  // in flight
  DeliverAndWrite(s, 2, T(110));
  d = s.Next(T(120));
  ASSERT_TRUE(d.finish);
  EXPECT_TRUE(d.finish->ok());
  EXPECT_FALSE(d.enqueue_at);
}

TEST(StreamScheduleTest, AStoppingServerEndsTheStreamAfterItsFramesInFlight) {
  StreamSchedule s = FirstFrameTaken(Pacing(60));
  s.Stop();
  StreamDecision d = s.Next(T(1));
  EXPECT_FALSE(d.finish);
  EXPECT_FALSE(d.enqueue);
  EXPECT_FALSE(d.enqueue_at);                                     // no new frames
  EXPECT_EQ(s.FrameDone(1, absl::OkStatus()), Arrival::kToSlot);  // still written
  d = s.Next(T(10));
  EXPECT_TRUE(d.write);
  EXPECT_FALSE(d.finish);
  s.WriteDone(true);
  d = s.Next(T(20));
  ASSERT_TRUE(d.finish);
  EXPECT_EQ(d.finish->code(), absl::StatusCode::kUnavailable);
  EXPECT_EQ(d.finish->message(), "server is shutting down");
}

TEST(StreamScheduleTest, TheLoopDroppingTheSessionStopsIt) {
  StreamSchedule s(milliseconds(0), true);
  s.Open(T(0), Pacing(0));
  EXPECT_TRUE(s.Next(T(0)).enqueue);
  EXPECT_EQ(s.FrameDone(0, absl::UnavailableError("server is shutting down")), Arrival::kIgnored);
  StreamDecision d = s.Next(T(1));
  EXPECT_FALSE(d.enqueue);
  ASSERT_TRUE(d.finish);
  EXPECT_EQ(d.finish->code(), absl::StatusCode::kUnavailable);
}

TEST(StreamScheduleTest, ARenderErrorEndsTheStreamWithIt) {
  StreamSchedule s = FirstFrameTaken(Pacing(0));
  EXPECT_EQ(s.FrameDone(1, absl::InternalError("render: device lost")), Arrival::kIgnored);
  StreamDecision d = s.Next(T(1));
  ASSERT_TRUE(d.finish);
  EXPECT_EQ(*d.finish, absl::InternalError("render: device lost"));
  EXPECT_FALSE(d.park);
}

TEST(StreamScheduleTest, TheFirstErrorWinsAndStopsEvents) {
  StreamSchedule s(milliseconds(0), true);
  EXPECT_TRUE(s.TakesEvents());
  s.Open(T(0), Pacing(0));
  EXPECT_TRUE(s.TakesEvents());
  EXPECT_TRUE(s.Fail(absl::InvalidArgumentError("settings.width: 0")));
  EXPECT_FALSE(s.Fail(absl::NotFoundError("scene_id")));
  EXPECT_FALSE(s.TakesEvents());
  StreamDecision d = s.Next(T(1));
  EXPECT_FALSE(d.enqueue);  // the pending first frame is not rendered
  ASSERT_TRUE(d.finish);
  EXPECT_EQ(*d.finish, absl::InvalidArgumentError("settings.width: 0"));
}

TEST(StreamScheduleTest, HandingTheSessionOverAbortsThisStream) {
  StreamSchedule s(milliseconds(0), true);
  EXPECT_FALSE(s.CanHandOver());  // not open yet
  s.Open(T(0), Pacing(0));
  s.Next(T(0));
  MustTake(s, T(0), FrameProfile::kFull);
  EXPECT_EQ(s.FrameDone(1, absl::OkStatus()), Arrival::kToSlot);
  EXPECT_TRUE(s.CanHandOver());
  s.HandOver();
  EXPECT_FALSE(s.CanHandOver());
  EXPECT_FALSE(s.TakesEvents());
  EXPECT_FALSE(s.frame_waiting());  // the waiting frame went with the state
  StreamDecision d = s.Next(T(1));
  EXPECT_FALSE(d.write);
  EXPECT_FALSE(d.park);
  ASSERT_TRUE(d.finish);
  EXPECT_EQ(d.finish->code(), absl::StatusCode::kAborted);
}

TEST(StreamScheduleTest, AnEarlierWakeReplacesALaterTimer) {
  StreamSchedule s(milliseconds(0), true);
  s.Open(T(0), Pacing(1, /*interactive=*/true, /*rest_ms=*/250));  // a frame a second
  s.Next(T(0));
  MustTake(s, T(0), FrameProfile::kFull);
  StreamDecision d = DeliverAndWrite(s, 1, T(10));
  ASSERT_TRUE(d.enqueue_at);
  EXPECT_EQ(*d.enqueue_at, T(1000));
  s.CameraMoved(T(100));
  s.Changed(T(100));
  EXPECT_TRUE(s.Next(T(100)).enqueue);  // a change jumps the queue while a timer is armed
  MustTake(s, T(100), FrameProfile::kInteractive);
  d = DeliverAndWrite(s, 2, T(110));
  ASSERT_TRUE(d.enqueue_at);
  EXPECT_EQ(*d.enqueue_at, T(350));  // the rest frame, before the cadence's next tick
}

TEST(StreamScheduleTest, ARefusedStreamDecidesNothing) {
  StreamSchedule s(milliseconds(0), true);
  s.Refuse();
  EXPECT_TRUE(s.finished());
  EXPECT_TRUE(Quiet(s.Next(T(0))));
}

// TAA's settling: once nothing has changed for the rest time, full frames keep coming until
// settle_frames of them reflect the newest change, then nothing until the next change; a
// camera that keeps moving gets one frame per change.
TEST(StreamScheduleTest, SettleFramesFollowTheNewestChangeOnceItRests) {
  StreamPacing pacing = Pacing(0, /*interactive=*/false, /*rest_ms=*/250);
  pacing.settle_frames = 3;
  StreamSchedule s(milliseconds(0), true);
  s.Open(T(0), pacing);
  EXPECT_TRUE(s.Next(T(0)).enqueue);
  MustTake(s, T(0), FrameProfile::kFull);  // the open's frame, at once
  StreamDecision d = DeliverAndWrite(s, 1, T(5));
  ASSERT_TRUE(d.enqueue_at);
  EXPECT_EQ(*d.enqueue_at, T(250));  // settling waits for the rest time
  EXPECT_FALSE(s.Take(T(100)));
  MustTake(s, T(250), FrameProfile::kFull);
  EXPECT_TRUE(DeliverAndWrite(s, 2, T(255)).enqueue);  // then back to back
  MustTake(s, T(256), FrameProfile::kFull);
  DeliverAndWrite(s, 3, T(260));
  EXPECT_TRUE(Quiet(s.Next(T(270))));
  EXPECT_FALSE(s.Take(T(1000)));  // settled: nothing more

  // A camera that moves every 50 ms: one frame per change, no settling in between.
  uint64_t seq = 3;
  for (int t = 2000; t < 2200; t += 50) {
    s.Changed(T(t));
    s.Next(T(t));
    MustTake(s, T(t), FrameProfile::kFull);
    DeliverAndWrite(s, ++seq, T(t + 5));
    EXPECT_FALSE(s.Take(T(t + 10))) << "a settle frame while the camera moves, at " << t;
  }
  MustTake(s, T(2150 + 250), FrameProfile::kFull);  // at rest, settling resumes
}

TEST(StreamScheduleTest, SettleFramesWaitForTheCameraToRest) {
  StreamPacing pacing = Pacing(0, /*interactive=*/true, /*rest_ms=*/250);
  pacing.settle_frames = 2;
  StreamSchedule s(milliseconds(0), true);
  s.Open(T(0), pacing);
  s.Next(T(0));
  MustTake(s, T(0), FrameProfile::kFull);
  DeliverAndWrite(s, 1, T(5));
  MustTake(s, T(250), FrameProfile::kFull);  // the second settle frame, at rest
  DeliverAndWrite(s, 2, T(255));
  EXPECT_FALSE(s.Take(T(300)));

  s.CameraMoved(T(400));
  s.Changed(T(400));
  s.Next(T(400));
  MustTake(s, T(400), FrameProfile::kInteractive);
  const StreamDecision d = DeliverAndWrite(s, 3, T(410));
  ASSERT_TRUE(d.enqueue_at);
  EXPECT_EQ(*d.enqueue_at, T(650));  // nothing more while the camera moves
  EXPECT_FALSE(s.Take(T(500)));
  MustTake(s, T(650), FrameProfile::kFull);  // at rest: the rest frame, then one more
  DeliverAndWrite(s, 4, T(660));
  MustTake(s, T(661), FrameProfile::kFull);
  DeliverAndWrite(s, 5, T(670));
  EXPECT_FALSE(s.Take(T(2000)));
}

}  // namespace
}  // namespace tessera::server
