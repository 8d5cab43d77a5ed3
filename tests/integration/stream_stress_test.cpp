// Stress test: eight viewers stream from one in-process server for a minute (or
// TESSERA_STRESS_SECONDS) with mixed behaviour: continuous, event-driven, interactive profile,
// settings changes and resizes, a cancel + resume (twice) and a half-close + fresh session; half
// of them (one of each kind, and the resuming one) as H.264 video, every frame decoded.
// It checks invariants on every frame, progress, the server's cleanup after the last client,
// and that the process' resident memory stays bounded. It is bounded, not a timing test:
// every wait has a limit, and nothing asserts on frame rates or latencies.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/string_view.h"
#include "common/video.h"
#include "server/server.h"
#include "tessera/v1/render_service.grpc.pb.h"
#include "tests/integration/client_helpers.h"

namespace tessera {
namespace {

using server::Server;
using server::ServerOptions;
using server::ServerStats;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;
using namespace test_client;  // client_helpers.h

int StressSeconds() {
  const char* env = std::getenv("TESSERA_STRESS_SECONDS");
  const int s = env ? std::atoi(env) : 0;
  return s > 0 ? s : 60;
}

double SecondsSince(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

uint64_t RssBytes() {
  std::ifstream in("/proc/self/statm");
  uint64_t size = 0, resident = 0;
  in >> size >> resident;
  return resident * static_cast<uint64_t>(sysconf(_SC_PAGESIZE));
}

double Mib(uint64_t bytes) { return double(bytes) / (1024.0 * 1024.0); }

// Failures seen on client threads; the main thread asserts on them.
class ErrorList {
 public:
  void Add(std::string error) {
    std::lock_guard lock(mu_);
    ++count_;
    if (errors_.size() < kKept) errors_.push_back(std::move(error));
  }
  size_t count() const {
    std::lock_guard lock(mu_);
    return count_;
  }
  std::string Joined() const {
    std::lock_guard lock(mu_);
    std::string out = absl::StrJoin(errors_, "\n");
    if (count_ > errors_.size())
      absl::StrAppend(&out, "\n... and ", count_ - errors_.size(), " more");
    return out;
  }

 private:
  static constexpr size_t kKept = 100;
  mutable std::mutex mu_;
  std::vector<std::string> errors_;
  size_t count_ = 0;
};

struct Size {
  uint32_t w = 0;
  uint32_t h = 0;
  bool operator==(const Size&) const = default;
};

enum class Kind { kContinuous, kEventDriven, kInteractive };

const char* KindName(Kind k) {
  switch (k) {
    case Kind::kContinuous:
      return "continuous";
    case Kind::kEventDriven:
      return "event-driven";
    case Kind::kInteractive:
      return "interactive";
  }
  return "?";
}

struct ClientSpec {
  int index = 0;
  Kind kind = Kind::kEventDriven;
  Size size;                        // at open
  Size alt_size;                    // the resize settings change toggles between the two
  float target_fps = 0;             // continuous clients
  uint32_t seed = 0;                // std::mt19937 seed: the event schedule and settings values
  std::vector<double> resume_at;    // fractions of the run: cancel, then resume by token
  std::optional<double> reopen_at;  // fraction of the run: half-close, drain, open fresh
  bool h264 = false;                // video.codec H264: every frame is decoded in order
};

// The eight viewers: 2 continuous, 4 event-driven, 2 with the interactive profile. Client 2
// cancels and resumes twice; client 0 half-closes and opens a fresh session once.
ClientSpec MakeSpec(int i) {
  static constexpr Kind kKinds[8] = {Kind::kContinuous,  Kind::kContinuous,  Kind::kEventDriven,
                                     Kind::kEventDriven, Kind::kEventDriven, Kind::kEventDriven,
                                     Kind::kInteractive, Kind::kInteractive};
  static constexpr Size kSizes[8] = {{64, 48},  {80, 56},  {96, 64},   {112, 72},
                                     {128, 88}, {144, 96}, {160, 112}, {192, 128}};
  ClientSpec s;
  s.index = i;
  s.kind = kKinds[i];
  s.size = kSizes[i];
  s.alt_size = {kSizes[i].w + 16, kSizes[i].h + 8};
  s.target_fps = s.kind == Kind::kContinuous ? 20.0f + 10.0f * float(i) : 0.0f;
  s.seed = 7919u * uint32_t(i + 1);
  if (i == 2) s.resume_at = {1.0 / 3.0, 2.0 / 3.0};
  s.h264 = i == 1 || i == 2 || i == 4 || i == 7;
  if (i == 0) s.reopen_at = 0.5;
  return s;
}

struct StreamEnd {
  bool cancelled = false;  // by this client: CANCELLED expected; otherwise OK expected
  grpc::Status status;
};

// One viewer: a writer (Run, on the client's thread) and a reader thread per stream.
class StressClient {
 public:
  StressClient(ClientSpec spec, std::string address, Clock::time_point start, Clock::duration run,
               std::chrono::system_clock::time_point deadline, ErrorList* errors)
      : spec_(std::move(spec)),
        address_(std::move(address)),
        start_(start),
        run_(run),
        deadline_(deadline),
        errors_(errors),
        rng_(spec_.seed),
        size_(spec_.size),
        channel_(NewChannel(address_, {.own_connection = true})) {}

  ~StressClient() { Abandon(); }

  void Run() {
    const Clock::time_point end = start_ + run_;
    Open(/*resume=*/false, "");
    size_t resume_next = 0;
    bool reopened = !spec_.reopen_at.has_value();
    auto at = [&](double fraction) {
      return start_ + std::chrono::duration_cast<Clock::duration>(run_ * fraction);
    };
    Clock::time_point now = Clock::now();
    Clock::time_point next_settings = now + Ms(1500, 3500);
    Clock::time_point next_camera = now + FirstCameraDelay();
    bool in_burst = true;  // interactive: camera motion, then a rest longer than rest_ms
    Clock::time_point phase_end = now + Ms(400, 1500);
    size_t settings_step = size_t(spec_.index);  // each client starts elsewhere in the list

    while (true) {
      now = Clock::now();
      if (now >= end) break;
      if (!write_ok_ || ReaderDone()) {
        Error("the stream broke mid-run (its end status follows)");
        break;
      }
      if (resume_next < spec_.resume_at.size() && now >= at(spec_.resume_at[resume_next])) {
        ++resume_next;
        CancelAndResume();
        continue;
      }
      if (!reopened && now >= at(*spec_.reopen_at)) {
        reopened = true;
        HalfCloseAndReopen();
        continue;
      }
      if (spec_.kind == Kind::kInteractive && now >= phase_end) {
        in_burst = !in_burst;
        phase_end = now + (in_burst ? Ms(400, 1500) : Ms(300, 1000));
        next_camera = in_burst ? now : phase_end;
      }
      if (now >= next_settings) {
        SendSettings(settings_step++);
        next_settings = now + Ms(2000, 4000);
      }
      if (now >= next_camera) {
        SendCamera();
        switch (spec_.kind) {
          case Kind::kContinuous:
            next_camera = now + Ms(500, 2000);
            break;
          case Kind::kEventDriven:
            next_camera = now + Ms(17, 50);  // 20..60 Hz
            break;
          case Kind::kInteractive:
            next_camera = in_burst ? now + 33ms : phase_end;
            break;
        }
      }
      Clock::time_point wake = std::min({next_settings, next_camera, end});
      if (spec_.kind == Kind::kInteractive) wake = std::min(wake, phase_end);
      if (resume_next < spec_.resume_at.size())
        wake = std::min(wake, at(spec_.resume_at[resume_next]));
      if (!reopened) wake = std::min(wake, at(*spec_.reopen_at));
      std::this_thread::sleep_until(wake);
    }
    Close(/*cancel=*/false);
  }

  // Results, read by the main thread after Run returned.
  const ClientSpec& spec() const { return spec_; }
  uint64_t frames() const { return total_frames_; }
  uint64_t video_frames() const { return video_frames_; }
  uint64_t interactive_frames() const { return interactive_frames_; }
  uint64_t full_frames() const { return total_frames_ - interactive_frames_; }
  uint64_t events_sent() const { return events_sent_; }
  int resumes_ok() const { return resumes_ok_; }
  int reopens_ok() const { return reopens_ok_; }
  const std::vector<StreamEnd>& ends() const { return ends_; }

 private:
  struct Call {
    std::unique_ptr<v1::RenderService::Stub> stub;
    std::unique_ptr<grpc::ClientContext> ctx;
    std::unique_ptr<StreamRW> rw;
    std::thread reader;
  };

  Clock::duration Ms(int lo, int hi) {
    return std::chrono::milliseconds(std::uniform_int_distribution<int>(lo, hi)(rng_));
  }
  Clock::duration FirstCameraDelay() {
    switch (spec_.kind) {
      case Kind::kContinuous:
        return Ms(500, 2000);
      case Kind::kEventDriven:
        return Ms(17, 50);
      case Kind::kInteractive:
        return 0ms;
    }
    return 0ms;
  }

  void Error(absl::string_view what) {
    errors_->Add(absl::StrCat("client ", spec_.index, " (", KindName(spec_.kind), "): ", what));
  }

  bool ReaderDone() {
    std::lock_guard lock(mu_);
    return reader_done_;
  }

  // Starts a stream: a fresh session (OpenSession with the current size) or a resume.
  void Open(bool resume, const std::string& token) {
    call_ = Call{};
    call_.stub = v1::RenderService::NewStub(channel_);
    call_.ctx = std::make_unique<grpc::ClientContext>();
    call_.ctx->set_deadline(deadline_);  // bounds every Read, Write and Finish of the stream
    // A viewer waits for the connection rather than giving up on its first failure: one of the
    // eight clients once ended before its first frame with "failed to connect to all addresses"
    // while the server was up, on a machine loaded by a parallel ctest (bounded by the deadline).
    call_.ctx->set_wait_for_ready(true);
    call_.rw = call_.stub->Stream(call_.ctx.get());
    write_ok_ = true;
    v1::ClientEvent open;
    {
      std::lock_guard lock(mu_);
      ++stream_no_;
      stream_frames_ = 0;
      reader_done_ = false;
      resumed_stream_ = resume;
      decoder_.reset();  // a new stream: its first frame must be a keyframe
      if (resume) {
        // Everything else in OpenSession is ignored; the event id is not applied either.
        open.mutable_open()->set_resume_token(token);
        open.set_event_id(newest_sent_);
      } else {
        previous_token_ = token_;
        token_.clear();
        last_seq_ = 0;
        last_event_ = 0;
        size_at_.clear();
        open.set_event_id(++newest_sent_);
        size_at_[newest_sent_] = size_;
        v1::OpenSession* o = open.mutable_open();
        o->set_scene_id("demo");
        o->mutable_settings()->set_width(size_.w);
        o->mutable_settings()->set_height(size_.h);
        o->set_target_fps(spec_.target_fps);
        OrbitEye(Orbit(), o->mutable_camera());
        if (spec_.h264) o->mutable_video()->set_codec(v1::VIDEO_CODEC_H264);
        if (spec_.kind == Kind::kInteractive) {
          o->mutable_interactive()->set_enabled(true);
          o->mutable_interactive()->set_render_scale(0.5f);
          o->mutable_interactive()->set_rest_ms(150);
        }
      }
    }
    call_.reader = std::thread([this, rw = call_.rw.get()] { ReadLoop(rw); });
    if (!call_.rw->Write(open)) write_ok_ = false;
  }

  // Ends the current stream: cancel (no half-close), or half-close and drain. Returns the
  // status; one other than CANCELLED / OK is an error.
  grpc::Status Close(bool cancel) {
    if (!call_.rw) return grpc::Status::OK;
    if (cancel)
      call_.ctx->TryCancel();
    else
      call_.rw->WritesDone();
    if (call_.reader.joinable()) call_.reader.join();  // reads until the stream ends
    grpc::Status st = call_.rw->Finish();
    const grpc::StatusCode want = cancel ? grpc::StatusCode::CANCELLED : grpc::StatusCode::OK;
    if (st.error_code() != want)
      Error(absl::StrCat("stream ", stream_no_, " ended with ", int(st.error_code()), " \"",
                         st.error_message(), "\", expected ", cancel ? "CANCELLED" : "OK"));
    ends_.push_back({cancel, st});
    call_.rw.reset();
    call_.ctx.reset();
    return st;
  }

  // Only for the destructor of a client whose Run never finished (a failed test).
  void Abandon() {
    if (!call_.rw) return;
    call_.ctx->TryCancel();
    if (call_.reader.joinable()) call_.reader.join();
    call_.rw->Finish();
  }

  void CancelAndResume() {
    std::string token;
    {
      std::lock_guard lock(mu_);
      token = token_;
    }
    if (token.empty()) {
      Error("no session_token seen before the planned resume; not resuming");
      return;
    }
    Close(/*cancel=*/true);
    channel_ = NewChannel(address_, {.own_connection = true});  // a reconnecting client
    Open(/*resume=*/true, token);
    // The resumed session sends its frame without any further event from us.
    std::unique_lock lock(mu_);
    const bool ended = cv_.wait_for(lock, 10s, [&] { return stream_frames_ > 0 || reader_done_; });
    if (stream_frames_ > 0) {
      ++resumes_ok_;
      size_ = size_at_.rbegin()->second;  // the reader dropped events the server never got
      return;
    }
    lock.unlock();
    Error(ended ? "the resumed stream ended before its first frame"
                : "no frame within 10 s of resuming (without sending an event)");
    Close(/*cancel=*/!ended);
    Open(/*resume=*/false, "");  // carry on with a fresh session
  }

  void HalfCloseAndReopen() {
    const grpc::Status st = Close(/*cancel=*/false);
    Open(/*resume=*/false, "");
    if (st.ok()) ++reopens_ok_;
  }

  uint64_t Orbit() { return uint64_t(spec_.index) * 1000 + orbit_++; }

  // Assigns the next event id (recording the size in force from it on) and writes.
  void Send(v1::ClientEvent e, std::optional<Size> resize = std::nullopt) {
    {
      std::lock_guard lock(mu_);
      e.set_event_id(++newest_sent_);
      if (resize) size_at_[newest_sent_] = *resize;
    }
    if (!write_ok_) return;
    if (!call_.rw->Write(e)) {
      write_ok_ = false;
      return;
    }
    ++events_sent_;
  }

  void SendCamera() {
    v1::ClientEvent e;
    OrbitEye(Orbit(), e.mutable_camera());
    Send(std::move(e));
  }

  // The settings changes, in a cycle: all accepted by the server.
  void SendSettings(size_t step) {
    v1::ClientEvent e;
    v1::RenderSettings* s = e.mutable_settings();
    std::optional<Size> resize;
    auto toggle_size = [&] {
      size_ = size_ == spec_.size ? spec_.alt_size : spec_.size;
      s->set_width(size_.w);
      s->set_height(size_.h);
      resize = size_;
    };
    switch (step % 8) {
      case 0:
        s->set_aa(v1::AA_FXAA);
        break;
      case 1:
        s->set_synthetic_lights(64);
        break;
      case 2:
        toggle_size();
        break;
      case 3:
        s->set_aa(v1::AA_MSAA);
        s->set_samples(4);
        break;
      case 4:
        s->set_jpeg_quality(std::uniform_int_distribution<uint32_t>(50, 90)(rng_));
        break;
      case 5:
        s->set_aa(v1::AA_TAA);
        break;
      case 6:
        s->set_synthetic_lights(0);
        break;
      case 7:
        s->set_aa(v1::AA_NONE);
        toggle_size();
        break;
    }
    Send(std::move(e), resize);
  }

  void ReadLoop(StreamRW* rw) {
    v1::Frame f;
    while (rw->Read(&f)) {
      std::lock_guard lock(mu_);
      CheckFrameLocked(f);
      cv_.notify_all();
    }
    std::lock_guard lock(mu_);
    reader_done_ = true;
    cv_.notify_all();
  }

  void CheckFrameLocked(const v1::Frame& f) {
    auto fail = [&](absl::string_view what) {
      Error(absl::StrCat("stream ", stream_no_, " frame seq=", f.sequence(),
                         " event=", f.event_id(), " ", f.width(), "x", f.height(), " profile=\"",
                         f.profile(), "\": ", what));
    };
    const bool first = stream_frames_++ == 0;
    ++total_frames_;
    if (f.profile() == "interactive") ++interactive_frames_;
    if (first && resumed_stream_) {
      if (f.session_token() != token_) fail("the resumed session has another session_token");
      if (f.profile() != "full") fail("a resumed session's first frame should be full");
      // Events written before the cancel that the server never read are lost: forget the sizes
      // they set (the newest event the session applied is this frame's).
      size_at_.erase(size_at_.upper_bound(f.event_id()), size_at_.end());
    } else if (first) {
      if (f.session_token().empty()) fail("empty session_token");
      if (!previous_token_.empty() && f.session_token() == previous_token_)
        fail("a fresh session has the previous session's token");
      token_ = f.session_token();
    } else if (f.session_token() != token_) {
      fail(absl::StrCat("session_token changed from ", token_));
    }
    if (f.sequence() <= last_seq_)
      fail(absl::StrCat(first && resumed_stream_ ? "the resumed sequence does not continue"
                                                 : "sequence not increasing",
                        " (previous ", last_seq_, ")"));
    if (f.event_id() < last_event_)
      fail(absl::StrCat("event_id went back (previous ", last_event_, ")"));
    if (f.event_id() > newest_sent_)
      fail(absl::StrCat("event_id beyond the newest sent (", newest_sent_, ")"));
    auto it = size_at_.upper_bound(f.event_id());
    if (it == size_at_.begin()) {
      fail("no size known for its event");
    } else {
      const Size want = std::prev(it)->second;
      if (f.width() != want.w || f.height() != want.h)
        fail(absl::StrCat("size should be ", want.w, "x", want.h, " (in force at event ",
                          std::prev(it)->first, ")"));
    }
    if (f.profile() != "full" && f.profile() != "interactive") fail("unknown profile");
    if (spec_.kind != Kind::kInteractive && f.profile() != "full")
      fail("interactive frame without the interactive profile");
    if (f.data().empty()) fail("no image data");
    if (spec_.h264) {
      if (f.encoding() != v1::VIDEO_H264) fail("not an H.264 frame");
      // A new stream, or a new size, starts a new video.
      const bool must_be_key = !decoder_ || f.width() != decoded_w_ || f.height() != decoded_h_;
      if (must_be_key && !f.keyframe()) fail("a new stream or size without a keyframe");
      if (!decoder_) {
        absl::StatusOr<std::unique_ptr<video::Decoder>> d = video::Decoder::Create();
        if (!d.ok()) return fail(d.status().ToString());
        decoder_ = *std::move(d);
      }
      absl::StatusOr<video::DecodedFrame> pic = decoder_->Decode(
          reinterpret_cast<const uint8_t*>(f.data().data()), f.data().size());
      if (!pic.ok()) {
        fail(absl::StrCat("does not decode: ", pic.status().ToString()));
      } else if (pic->width != f.width() || pic->height != f.height()) {
        fail(absl::StrCat("decodes to ", pic->width, "x", pic->height));
      }
      decoded_w_ = f.width();
      decoded_h_ = f.height();
      ++video_frames_;
    } else if (f.encoding() != v1::IMAGE_JPEG) {
      fail("not a JPEG frame");
    }
    last_seq_ = f.sequence();
    last_event_ = f.event_id();
  }

  const ClientSpec spec_;
  const std::string address_;
  const Clock::time_point start_;
  const Clock::duration run_;
  const std::chrono::system_clock::time_point deadline_;
  ErrorList* const errors_;

  // Writer (Run's thread) only.
  std::mt19937 rng_;
  Size size_;  // the size asked for now
  std::shared_ptr<grpc::Channel> channel_;
  Call call_;
  bool write_ok_ = true;
  uint64_t orbit_ = 0;
  uint64_t events_sent_ = 0;
  int resumes_ok_ = 0;
  int reopens_ok_ = 0;
  std::vector<StreamEnd> ends_;

  // Shared by the writer and the reader.
  std::mutex mu_;
  std::condition_variable cv_;
  std::map<uint64_t, Size> size_at_;  // event id -> the size asked for from that event on
  uint64_t newest_sent_ = 0;          // event ids are assigned before the write
  uint64_t last_seq_ = 0;             // per session (continues across a resume)
  uint64_t last_event_ = 0;
  std::string token_;
  std::string previous_token_;  // of the session before a fresh reopen
  std::unique_ptr<video::Decoder> decoder_;  // h264: this stream's, from its first keyframe
  uint32_t decoded_w_ = 0, decoded_h_ = 0;
  uint64_t video_frames_ = 0;
  int stream_no_ = 0;
  bool resumed_stream_ = false;
  uint64_t stream_frames_ = 0;
  bool reader_done_ = false;
  uint64_t total_frames_ = 0;
  uint64_t interactive_frames_ = 0;
};

std::string StatsLine(const ServerStats& s) {
  return absl::StrCat(
      "{\"sessions\": ", s.sessions, ", \"parked_sessions\": ", s.parked_sessions,
      ", \"pending_frame_bytes\": ", s.pending_frame_bytes,
      ", \"frames_in_flight\": ", s.frames_in_flight, ", \"queue_depth\": ", s.queue_depth,
      ", \"frames_rendered\": ", s.frames_rendered, ", \"frames_dropped\": ", s.frames_dropped,
      ", \"validation_messages\": ", s.validation_messages, "}");
}

struct RssSample {
  double t_s;
  uint64_t bytes;
  const char* phase;
};

TEST(StreamStress, EightViewersForAMinute) {
  ServerOptions o;
  o.listen = "127.0.0.1:0";
  o.validation = std::getenv("TESSERA_VALIDATION") != nullptr;
  o.max_sessions = 16;
  o.resume_grace_s = 5;
  absl::StatusOr<std::unique_ptr<Server>> started = Server::Start(o);
  ASSERT_TRUE(started.ok()) << started.status();
  std::unique_ptr<Server> server = *std::move(started);

  const int seconds = StressSeconds();
  const uint64_t min_frames = std::max<uint64_t>(10, uint64_t(seconds) / 3);
  const double warm_s = std::max(5.0, 0.15 * seconds);
  std::cout << "{\"stress\": {\"seconds\": " << seconds
            << ", \"clients\": 8, \"min_frames\": " << min_frames << ", \"warmup_s\": " << warm_s
            << "}}" << std::endl;

  ErrorList errors;
  const Clock::time_point start = Clock::now();
  const Clock::duration run = std::chrono::seconds(seconds);
  // Every stream's deadline: a hung read, write or finish ends there instead of hanging.
  const std::chrono::system_clock::time_point deadline =
      std::chrono::system_clock::now() + run + 90s;
  std::vector<std::unique_ptr<StressClient>> clients;
  for (int i = 0; i < 8; ++i)
    clients.push_back(std::make_unique<StressClient>(MakeSpec(i), server->address(), start, run,
                                                     deadline, &errors));
  std::vector<std::thread> threads;
  for (auto& c : clients) threads.emplace_back([c = c.get()] { c->Run(); });

  // RSS every 2 s while the clients run.
  std::vector<RssSample> series;
  auto sample = [&](const char* phase) {
    series.push_back({SecondsSince(start), RssBytes(), phase});
    const RssSample& s = series.back();
    std::cout << "{\"rss_sample\": {\"t_s\": " << s.t_s << ", \"rss_mib\": " << Mib(s.bytes)
              << ", \"phase\": \"" << s.phase << "\"}}" << std::endl;
  };
  for (int k = 0; start + std::chrono::seconds(2 * k) <= start + run; ++k) {
    std::this_thread::sleep_until(start + std::chrono::seconds(2 * k));
    sample(SecondsSince(start) <= warm_s ? "warmup" : "run");
  }
  for (std::thread& t : threads) t.join();  // bounded: every stream has the deadline above

  // Per-client results, then the clients (and their channels) go.
  for (const auto& c : clients) {
    const ClientSpec& s = c->spec();
    std::vector<std::string> ends;
    for (const StreamEnd& e : c->ends())
      ends.push_back(absl::StrCat(e.cancelled ? "cancel:" : "close:", int(e.status.error_code())));
    std::cout << "{\"client\": " << s.index << ", \"kind\": \"" << KindName(s.kind)
              << "\", \"size\": \"" << s.size.w << "x" << s.size.h
              << "\", \"codec\": \"" << (s.h264 ? "h264" : "jpeg")
              << "\", \"frames\": " << c->frames()
              << ", \"interactive_frames\": " << c->interactive_frames()
              << ", \"events_sent\": " << c->events_sent() << ", \"resumes\": " << c->resumes_ok()
              << ", \"reopens\": " << c->reopens_ok() << ", \"stream_ends\": \""
              << absl::StrJoin(ends, ",") << "\"}" << std::endl;
    EXPECT_GE(c->frames(), min_frames) << "client " << s.index << " (" << KindName(s.kind) << ")";
    EXPECT_EQ(c->resumes_ok(), int(s.resume_at.size())) << "client " << s.index;
    EXPECT_EQ(c->video_frames(), s.h264 ? c->frames() : 0u) << "client " << s.index;
    EXPECT_EQ(c->reopens_ok(), s.reopen_at ? 1 : 0) << "client " << s.index;
    if (s.kind == Kind::kInteractive) {
      EXPECT_GT(c->interactive_frames(), 0u) << "client " << s.index << ": no interactive frame";
      EXPECT_GT(c->full_frames(), 0u) << "client " << s.index << ": no full frame after a rest";
    }
  }
  clients.clear();
  EXPECT_EQ(errors.count(), 0u) << errors.Joined();

  // The server lets go of everything once the last stream is closed.
  const bool drained = WaitFor(
      *server,
      [](const ServerStats& s) {
        return s.sessions == 0 && s.pending_frame_bytes == 0 && s.frames_in_flight == 0;
      },
      /*ms=*/10000, /*poll_ms=*/20);
  EXPECT_TRUE(drained) << StatsLine(server->stats());
  const bool unparked = WaitFor(
      *server, [](const ServerStats& s) { return s.parked_sessions == 0; }, /*ms=*/10000,
      /*poll_ms=*/20);
  EXPECT_TRUE(unparked) << StatsLine(server->stats());
  const ServerStats after = server->stats();
  std::cout << "{\"server_stats\": " << StatsLine(after) << "}" << std::endl;

  // Memory: the end (every client closed) against the warm-up peak.
  sample("end");
  uint64_t baseline = 0;
  for (const RssSample& s : series)
    if (s.phase == std::string_view("warmup")) baseline = std::max(baseline, s.bytes);
  const uint64_t rss_end = series.back().bytes;
  const double limit = double(baseline) * 1.15 + 48.0 * 1024 * 1024;
  const bool rss_ok = double(rss_end) <= limit;
  uint64_t peak = 0;
  for (const RssSample& s : series) peak = std::max(peak, s.bytes);
  std::cout << "{\"rss_verdict\": {\"baseline_mib\": " << Mib(baseline)
            << ", \"peak_mib\": " << Mib(peak) << ", \"end_mib\": " << Mib(rss_end)
            << ", \"limit_mib\": " << limit / (1024.0 * 1024.0)
            << ", \"ok\": " << (rss_ok ? "true" : "false") << "}}" << std::endl;
  EXPECT_GT(baseline, 0u);
  EXPECT_TRUE(rss_ok) << "RSS at the end " << Mib(rss_end) << " MiB > warm-up peak "
                      << Mib(baseline) << " MiB * 1.15 + 48 MiB";

  server->Shutdown();
  EXPECT_EQ(server->stats().validation_messages, 0u);
}

}  // namespace
}  // namespace tessera
