// Integration tests of the streaming service: resumable sessions, idle refinement, priorities
// and deadlines, scene eviction, the Prometheus endpoint, dying client processes, bearer
// tokens (with SIGHUP reload through the tesserad binary), TLS and mTLS. A real tesserad
// (in-process Server on port 0, or the binary) over real gRPC.
#include <arpa/inet.h>
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <thread>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "renderer/image_io.h"
#include "server/server.h"
#include "tessera/v1/render_service.grpc.pb.h"
#include "tests/integration/client_helpers.h"
#include "tests/integration/test_certs.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;
using server::Server;
using server::ServerOptions;
using server::ServerStats;
using Clock = std::chrono::steady_clock;
using namespace test_client;  // client_helpers.h

v1::ClientEvent ResumeEvent(const std::string& token) {
  v1::ClientEvent e;
  e.mutable_open()->set_resume_token(token);
  return e;
}

// GET http://127.0.0.1:port/path over a plain socket (HTTP/1.0: the server closes).
std::string HttpGet(int port, const std::string& path) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return "";
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  std::string out;
  if (connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0) {
    const std::string req = absl::StrCat("GET ", path, " HTTP/1.0\r\nHost: localhost\r\n\r\n");
    if (write(fd, req.data(), req.size()) == static_cast<ssize_t>(req.size())) {
      char buf[4096];
      for (ssize_t n; (n = read(fd, buf, sizeof buf)) > 0;) out.append(buf, n);
    }
  }
  close(fd);
  return out;
}

// --- one server for the session tests: resume grace 2 s, metrics on, one uploaded scene max --

class ServiceTest : public SharedServerTest<ServiceTest> {
 protected:
  static void SetUpTestSuite() {
    ServerOptions o = BaseOptions();
    o.resume_grace_s = 2;
    o.max_scenes = 1;
    o.max_session_fps = 1000;
    o.metrics_listen = "127.0.0.1:0";
    server_ = StartServer(o).release();
  }
  void TearDown() override {
    grpc::ClientContext ctx;
    v1::Frame f;
    EXPECT_TRUE(stub_->Render(&ctx, DemoRequest(32, 24), &f).ok()) << "server still serves";
    EXPECT_EQ(server_->stats().validation_messages, 0u);
  }
};

// A stream that breaks (the client vanishes without closing) leaves its session parked; a new
// stream with the token gets it back, scene, settings, camera and sequence, and a full frame
// without sending anything.
TEST_F(ServiceTest, ResumeAfterABrokenStreamRestoresTheSessionWithAFullFrameAtOnce) {
  std::string token;
  uint64_t last_seq = 0;
  {
    grpc::ClientContext ctx;
    auto rw = stub_->Stream(&ctx);
    v1::ClientEvent open = OpenEvent("demo", 80, 60);
    open.mutable_open()->mutable_settings()->set_aa(v1::AA_FXAA);
    open.mutable_open()->mutable_settings()->set_jpeg_quality(77);
    ASSERT_TRUE(rw->Write(open));
    ASSERT_TRUE(rw->Write(CameraEvent(3)));
    v1::Frame f;
    ASSERT_TRUE(ReadUntilEvent(rw.get(), 3, &f));
    token = f.session_token();
    last_seq = f.sequence();
    EXPECT_EQ(token.size(), 32u);
    ctx.TryCancel();  // as a dropped connection looks to the server
    rw->Finish();
  }
  ASSERT_TRUE(WaitFor(*server_, [](const ServerStats& s) {
    return s.sessions == 0 && s.parked_sessions == 1 && s.pending_frame_bytes == 0;
  }));
  grpc::ClientContext ctx;
  auto rw = stub_->Stream(&ctx);
  ASSERT_TRUE(rw->Write(ResumeEvent(token)));
  v1::Frame f;
  ASSERT_TRUE(rw->Read(&f)) << "a resumed session gets a frame without asking";
  EXPECT_EQ(f.session_token(), token);
  EXPECT_GT(f.sequence(), last_seq);
  EXPECT_EQ(f.event_id(), 3u);
  EXPECT_EQ(f.profile(), "full");
  EXPECT_EQ(f.width(), 80u);
  EXPECT_EQ(f.settings().aa(), v1::AA_FXAA);
  EXPECT_EQ(f.settings().jpeg_quality(), 77u);
  EXPECT_NEAR(f.camera().eye().x(), EyeX(3), 1e-4);
  EXPECT_EQ(server_->stats().parked_sessions, 0u);
  // It is a live session again.
  ASSERT_TRUE(rw->Write(CameraEvent(4)));
  ASSERT_TRUE(ReadUntilEvent(rw.get(), 4, &f));
  EXPECT_NEAR(f.camera().eye().x(), EyeX(4), 1e-4);
  EXPECT_TRUE(CloseStream(rw.get()).ok());
  // A session that ended cleanly cannot be resumed.
  grpc::ClientContext ctx2;
  auto again = stub_->Stream(&ctx2);
  ASSERT_TRUE(again->Write(ResumeEvent(token)));
  EXPECT_CODE(CloseStream(again.get()), NOT_FOUND, "resume_token");
}

// The client reconnects before the server noticed the old connection was gone: the resume
// takes the session from the open stream, which ends with ABORTED.
TEST_F(ServiceTest, ResumingAnOpenSessionMovesItAndAbortsTheOldStream) {
  grpc::ClientContext old_ctx;
  auto old_rw = stub_->Stream(&old_ctx);
  ASSERT_TRUE(old_rw->Write(OpenEvent("demo", 64, 48)));
  ASSERT_TRUE(old_rw->Write(CameraEvent(5)));
  v1::Frame f;
  ASSERT_TRUE(ReadUntilEvent(old_rw.get(), 5, &f));
  const std::string token = f.session_token();
  grpc::ClientContext ctx;
  auto rw = stub_->Stream(&ctx);
  ASSERT_TRUE(rw->Write(ResumeEvent(token)));
  ASSERT_TRUE(rw->Read(&f));
  EXPECT_EQ(f.session_token(), token);
  EXPECT_EQ(f.event_id(), 5u);
  while (old_rw->Read(&f)) {
  }
  EXPECT_CODE(old_rw->Finish(), ABORTED, "resumed");
  EXPECT_TRUE(CloseStream(rw.get()).ok());
  EXPECT_TRUE(WaitFor(*server_, [](const ServerStats& s) { return s.sessions == 0; }));
}

TEST_F(ServiceTest, UnknownAndExpiredTokensAreNotFound) {
  {
    grpc::ClientContext ctx;
    auto rw = stub_->Stream(&ctx);
    ASSERT_TRUE(rw->Write(ResumeEvent("0123456789abcdef0123456789abcdef")));
    EXPECT_CODE(CloseStream(rw.get()), NOT_FOUND, "resume_token");
  }
  std::string token;
  {
    grpc::ClientContext ctx;
    auto rw = stub_->Stream(&ctx);
    ASSERT_TRUE(rw->Write(OpenEvent("demo", 32, 32)));
    v1::Frame f;
    ASSERT_TRUE(rw->Read(&f));
    token = f.session_token();
    ctx.TryCancel();
    rw->Finish();
  }
  ASSERT_TRUE(WaitFor(*server_, [](const ServerStats& s) { return s.parked_sessions == 1; }));
  // The grace period is 2 s: the sweeper drops it, and with it its scene lease.
  ASSERT_TRUE(WaitFor(*server_, [](const ServerStats& s) { return s.parked_sessions == 0; }));
  grpc::ClientContext ctx;
  auto rw = stub_->Stream(&ctx);
  ASSERT_TRUE(rw->Write(ResumeEvent(token)));
  EXPECT_CODE(CloseStream(rw.get()), NOT_FOUND, "grace period");
}

// While the camera moves, frames are rendered at half size and upscaled to the session's
// size; once it rests, one full-quality frame follows without any client event.
TEST_F(ServiceTest, InteractiveFramesWhileMovingThenOneFullFrameAtRest) {
  grpc::ClientContext ctx;
  auto rw = stub_->Stream(&ctx);
  v1::ClientEvent open = OpenEvent("demo", 128, 96);
  open.mutable_open()->mutable_interactive()->set_enabled(true);
  open.mutable_open()->mutable_interactive()->set_render_scale(0.5f);
  open.mutable_open()->mutable_interactive()->set_jpeg_quality(50);
  open.mutable_open()->mutable_interactive()->set_rest_ms(400);
  ASSERT_TRUE(rw->Write(open));
  v1::Frame f;
  ASSERT_TRUE(rw->Read(&f));
  EXPECT_EQ(f.profile(), "full") << "the first frame: nothing moved yet";
  constexpr uint64_t kMoves = 6;
  std::vector<v1::Frame> frames;
  for (uint64_t k = 1; k <= kMoves; ++k) {
    ASSERT_TRUE(rw->Write(CameraEvent(k)));
    ASSERT_TRUE(ReadUntilEvent(rw.get(), k, &f));  // one frame per move, within the rest time
    frames.push_back(f);
  }
  int interactive = 0;
  for (const v1::Frame& g : frames) {
    if (g.profile() != "interactive") continue;
    ++interactive;
    EXPECT_EQ(g.width(), 128u);
    EXPECT_EQ(g.height(), 96u);
    EXPECT_EQ(g.render_width(), 64u);
    EXPECT_EQ(g.render_height(), 48u);
    EXPECT_EQ(g.settings().width(), 64u) << "the settings the renderer used";
    EXPECT_EQ(g.settings().jpeg_quality(), 50u);
    absl::StatusOr<RgbaImage> img = DecodeJpeg(
        std::span(reinterpret_cast<const uint8_t*>(g.data().data()), g.data().size()));
    ASSERT_TRUE(img.ok()) << img.status();
    EXPECT_EQ(img->width, 128u);
  }
  EXPECT_GE(interactive, int(kMoves) - 1) << "frames while the camera moves are interactive";
  // Rest: the next frame comes by itself, full quality, reflecting the last move.
  const auto t0 = Clock::now();
  ASSERT_TRUE(rw->Read(&f));
  const double waited_ms =
      std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  EXPECT_EQ(f.profile(), "full");
  EXPECT_EQ(f.event_id(), kMoves);
  EXPECT_EQ(f.render_width(), 128u);
  EXPECT_EQ(f.settings().jpeg_quality(), 90u);
  EXPECT_GE(waited_ms, 150.0) << "it waited for the camera to rest (400 ms after the last move)";
  // Exactly one: nothing more until something changes.
  ASSERT_TRUE(rw->Write(CameraEvent(kMoves + 1)));
  ASSERT_TRUE(rw->Read(&f));
  EXPECT_EQ(f.event_id(), kMoves + 1) << "no second full frame was sent in between";
  EXPECT_TRUE(CloseStream(rw.get()).ok());
}

// A client that half-closes right after moving still gets the full-quality frame last.
TEST_F(ServiceTest, HalfCloseAfterMovingStillEndsWithTheFullFrame) {
  grpc::ClientContext ctx;
  auto rw = stub_->Stream(&ctx);
  v1::ClientEvent open = OpenEvent("demo", 96, 64);
  open.mutable_open()->mutable_interactive()->set_enabled(true);
  open.mutable_open()->mutable_interactive()->set_rest_ms(100);
  ASSERT_TRUE(rw->Write(open));
  v1::Frame f;
  ASSERT_TRUE(rw->Read(&f));
  ASSERT_TRUE(rw->Write(CameraEvent(1)));
  ASSERT_TRUE(ReadUntilEvent(rw.get(), 1, &f));
  EXPECT_EQ(f.profile(), "interactive");
  rw->WritesDone();
  v1::Frame last = f;
  while (rw->Read(&f)) last = f;
  EXPECT_TRUE(rw->Finish().ok());
  EXPECT_EQ(last.profile(), "full");
  EXPECT_EQ(last.event_id(), 1u);
  EXPECT_EQ(last.render_width(), 96u);
}

// Background renders run only when no normal work waits: a normal render queued behind six
// background ones is served next.
TEST_F(ServiceTest, BackgroundRendersWaitForNormalOnes) {
  std::mutex mu;
  std::vector<std::string> order;
  std::vector<std::thread> threads;
  auto render = [&](bool background, const std::string& name) {
    v1::RenderRequest req = DemoRequest(960, 540);  // slow enough for a queue to build
    req.set_background(background);
    grpc::ClientContext ctx;
    v1::Frame f;
    grpc::Status st = stub_->Render(&ctx, req, &f);
    EXPECT_TRUE(st.ok()) << st.error_message();
    std::lock_guard lock(mu);
    order.push_back(name);
  };
  for (int i = 0; i < 6; ++i)
    threads.emplace_back(render, true, absl::StrCat("background", i));
  ASSERT_TRUE(WaitFor(*server_, [](const ServerStats& s) { return s.queue_depth >= 4; }));
  threads.emplace_back(render, false, "normal");
  for (std::thread& t : threads) t.join();
  const size_t pos = std::find(order.begin(), order.end(), "normal") - order.begin();
  // At most the background frames already taken by the render thread (one rendering, and
  // the one it took just before the normal request arrived) finish first.
  EXPECT_LE(pos, 2u) << "the normal render finished at position " << pos;
}

// A render whose deadline passes while it waits in the queue is not rendered at all.
TEST_F(ServiceTest, RenderPastItsDeadlineIsNotRendered) {
  std::vector<std::thread> threads;
  for (int i = 0; i < 4; ++i)
    threads.emplace_back([&] {
      grpc::ClientContext ctx;
      v1::Frame f;
      EXPECT_TRUE(stub_->Render(&ctx, DemoRequest(960, 540), &f).ok());
    });
  ASSERT_TRUE(WaitFor(*server_, [](const ServerStats& s) { return s.queue_depth >= 2; }));
  const uint64_t before = server_->stats().frames_rendered;
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(5));
  v1::Frame f;
  EXPECT_EQ(stub_->Render(&ctx, DemoRequest(320, 240), &f).error_code(),
            grpc::StatusCode::DEADLINE_EXCEEDED);
  for (std::thread& t : threads) t.join();
  ASSERT_TRUE(WaitFor(*server_, [](const ServerStats& s) { return s.queue_depth == 0; }));
  const uint64_t rendered = server_->stats().frames_rendered - before;
  EXPECT_LE(rendered, 4u) << "the expired render was skipped, not rendered";
}

// max_scenes is 1 here: a second upload evicts the first (no session uses it), HasScene says
// so, and the eviction is counted in the metrics.
TEST_F(ServiceTest, LeastRecentlyUsedUnusedSceneIsEvicted) {
  v1::SceneInfo box, boxt;
  grpc::Status st = UploadFromDisk(stub_.get(), AssetsDir() + "/Box/glTF/Box.gltf", &box);
  ASSERT_TRUE(st.ok()) << st.error_message();
  const uint64_t evicted_before = server_->stats().scenes_evicted;
  st = UploadFromDisk(stub_.get(), AssetsDir() + "/BoxTextured/glTF/BoxTextured.gltf", &boxt);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(server_->stats().scenes_evicted, evicted_before + 1);
  grpc::ClientContext ctx;
  v1::HasSceneRequest has;
  has.set_scene_id(box.scene_id());
  v1::HasSceneResponse r;
  ASSERT_TRUE(stub_->HasScene(&ctx, has, &r).ok());
  EXPECT_FALSE(r.present());
  const std::map<std::string, double> m = ParseMetrics(server_->MetricsText());
  EXPECT_GE(m.at("tessera_scenes_evicted_total"), 1.0);
  grpc::ClientContext ctx2;
  v1::ServerInfo info;
  ASSERT_TRUE(stub_->GetServerInfo(&ctx2, v1::GetServerInfoRequest(), &info).ok());
  EXPECT_GT(info.scene_device_bytes(), boxt.device_bytes());
}

TEST_F(ServiceTest, MetricsEndpointIsScrapedAndParsed) {
  ASSERT_GT(server_->metrics_port(), 0);
  {
    grpc::ClientContext ctx;
    v1::Frame f;
    ASSERT_TRUE(stub_->Render(&ctx, DemoRequest(48, 32), &f).ok());
    grpc::ClientContext bad;
    v1::RenderRequest req = DemoRequest(48, 32);
    req.set_scene_id("no-such-scene");
    EXPECT_EQ(stub_->Render(&bad, req, &f).error_code(), grpc::StatusCode::NOT_FOUND);
  }
  const std::string response = HttpGet(server_->metrics_port(), "/metrics");
  ASSERT_NE(response.find("200 OK"), std::string::npos) << response.substr(0, 200);
  const std::string body = response.substr(response.find("\r\n\r\n") + 4);
  const std::map<std::string, double> m = ParseMetrics(body);
  EXPECT_GE(m.at("tessera_frames_total{kind=\"render\",profile=\"full\"}"), 1.0);
  EXPECT_GE(m.at("tessera_pass_gpu_milliseconds_count{pass=\"forward\"}"), 1.0);
  EXPECT_GT(m.at("tessera_pass_gpu_milliseconds_sum{pass=\"forward\"}"), 0.0);
  EXPECT_GE(m.at("tessera_encode_milliseconds_count"), 1.0);
  EXPECT_GE(m.at("tessera_rpcs_total{code=\"OK\",method=\"Render\"}"), 1.0);
  EXPECT_GE(m.at("tessera_rpcs_total{code=\"NOT_FOUND\",method=\"Render\"}"), 1.0);
  EXPECT_EQ(m.at("tessera_sessions"), 0.0);
  EXPECT_GT(m.at("tessera_scene_device_bytes"), 0.0);
  EXPECT_TRUE(m.count("tessera_queue_depth"));
  EXPECT_TRUE(m.count("tessera_uploads_in_progress"));
  EXPECT_TRUE(m.count("tessera_frame_total_milliseconds_bucket{kind=\"render\",le=\"+Inf\"}"));
}

// Client processes killed (SIGKILL) mid-stream and mid-upload: their session and upload
// buffers are freed; the stream's session is parked, then dropped after the grace period.
TEST_F(ServiceTest, KilledClientsFreeTheirSessionsAndUploads) {
  for (const char* mode : {"stream", "upload"}) {
    SCOPED_TRACE(mode);
    int out[2];
    ASSERT_EQ(pipe(out), 0);
    const pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      dup2(out[1], STDOUT_FILENO);
      close(out[0]);
      execl(DYING_CLIENT_PATH, DYING_CLIENT_PATH, server_->address().c_str(), mode,
            (char*)nullptr);
      _exit(127);
    }
    close(out[1]);
    char buf[128] = {};
    const ssize_t n = read(out[0], buf, sizeof buf - 1);  // "ready ..." once mid-call
    close(out[0]);
    ASSERT_GT(n, 0) << "the client did not get going";
    EXPECT_EQ(std::string(buf, 5), "ready");
    // The client's writes may still be on their way: wait until the server holds the call.
    if (std::string(mode) == "stream")
      EXPECT_TRUE(WaitFor(*server_, [](const ServerStats& s) { return s.sessions == 1; }));
    else
      EXPECT_TRUE(
          WaitFor(*server_, [](const ServerStats& s) { return s.uploads_in_progress == 1; }));
    kill(pid, SIGKILL);
    waitpid(pid, nullptr, 0);
    EXPECT_TRUE(WaitFor(*server_, [](const ServerStats& s) {
      return s.sessions == 0 && s.uploads_in_progress == 0 && s.pending_frame_bytes == 0 &&
             s.frames_in_flight == 0;
    }));
  }
  EXPECT_TRUE(WaitFor(*server_, [](const ServerStats& s) { return s.parked_sessions == 0; }));
}

// --- the per-session fps cap ---------------------------------------------------------------

TEST(FpsCap, TargetFpsAboveTheCapIsLoweredAndNoted) {
  ServerOptions o = BaseOptions();
  o.max_session_fps = 10;
  std::unique_ptr<Server> server = StartServer(o);
  ASSERT_NE(server, nullptr);
  auto stub = Connect(server->address());
  grpc::ClientContext ctx;
  auto rw = stub->Stream(&ctx);
  ASSERT_TRUE(rw->Write(OpenEvent("demo", 32, 24, /*fps=*/120)));
  v1::Frame f;
  ASSERT_TRUE(rw->Read(&f));
  bool noted = false;
  for (const v1::SettingNote& n : f.notes())
    noted |= n.field() == "target_fps" && n.message().find("max_session_fps") != std::string::npos;
  EXPECT_TRUE(noted);
  // An upper bound only: 10 fps for 1.5 s is 15 frames (+2 for the edges), never 120 fps.
  const auto t0 = Clock::now();
  int frames = 0;
  while (Clock::now() - t0 < std::chrono::milliseconds(1500) && rw->Read(&f)) ++frames;
  EXPECT_LE(frames, 17);
  EXPECT_GE(frames, 1);
  ctx.TryCancel();
  rw->Finish();
  grpc::ClientContext info_ctx;
  v1::ServerInfo info;
  ASSERT_TRUE(stub->GetServerInfo(&info_ctx, v1::GetServerInfoRequest(), &info).ok());
  EXPECT_EQ(info.limits().max_session_fps(), 10.0f);
  server->Shutdown();
}

// --- bearer tokens -------------------------------------------------------------------------

class BearerAuth final : public grpc::MetadataCredentialsPlugin {
 public:
  explicit BearerAuth(std::string token) : token_(std::move(token)) {}
  grpc::Status GetMetadata(grpc::string_ref, grpc::string_ref, const grpc::AuthContext&,
                           std::multimap<grpc::string, grpc::string>* md) override {
    md->insert({"authorization", "Bearer " + token_});
    return grpc::Status::OK;
  }
  bool IsBlocking() const override { return false; }

 private:
  std::string token_;
};

void WithToken(grpc::ClientContext* ctx, const std::string& token) {
  ctx->AddMetadata("authorization", "Bearer " + token);
}

std::string TempPath(const std::string& name) {
  return (fs::temp_directory_path() / absl::StrCat("tessera_", getpid(), "_", name)).string();
}

void WriteFile(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
}

// Health means something: a frame stuck on the device turns it NOT_SERVING (and back when the
// frame ends), a lost device for good; GetServerInfo and the metrics say why, renders fail with
// UNAVAILABLE naming the lost device, and the server's device-lost callback runs once.
TEST(Health, AStalledRenderAndALostDeviceTurnHealthNotServing) {
  ServerOptions o = BaseOptions();
  o.render_stall_s = 0.5;
  std::atomic<int> lost_calls{0};
  o.on_device_lost = [&] { lost_calls++; };
  std::unique_ptr<Server> server = StartServer(o);
  ASSERT_NE(server, nullptr);
  auto stub = Connect(server->address());
  auto info = [&] {
    grpc::ClientContext ctx;
    v1::ServerInfo i;
    EXPECT_TRUE(stub->GetServerInfo(&ctx, {}, &i).ok());
    return i;
  };
  EXPECT_TRUE(HealthServing(server->address()));
  EXPECT_TRUE(info().serving());
  EXPECT_EQ(ParseMetrics(server->MetricsText()).at("tessera_serving"), 1.0);

  // A frame that blocks for 3 s: NOT_SERVING within a second, SERVING again after it.
  server->StallNextRenderForTesting(3000);
  std::thread slow([&] {
    grpc::ClientContext ctx;
    v1::Frame f;
    EXPECT_TRUE(stub->Render(&ctx, DemoRequest(16, 16), &f).ok());
  });
  const auto t0 = std::chrono::steady_clock::now();
  bool went_down = false;
  while (std::chrono::steady_clock::now() - t0 < std::chrono::seconds(2) && !went_down) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    went_down = !HealthServing(server->address());
  }
  EXPECT_TRUE(went_down) << "health stayed SERVING while a frame was stuck";
  const v1::ServerInfo stalled = info();
  EXPECT_FALSE(stalled.serving());
  EXPECT_NE(stalled.unhealthy_reason().find("render thread"), std::string::npos)
      << stalled.unhealthy_reason();
  std::map<std::string, double> m = ParseMetrics(server->MetricsText());
  EXPECT_EQ(m.at("tessera_serving"), 0.0);
  EXPECT_GT(m.at("tessera_render_busy_seconds"), 0.5);
  slow.join();
  server->CheckHealth();
  EXPECT_TRUE(HealthServing(server->address()));
  EXPECT_TRUE(info().serving());
  EXPECT_EQ(ParseMetrics(server->MetricsText()).at("tessera_render_stalls"), 1.0);

  // The device is lost: that frame and every later one fail with UNAVAILABLE, for good.
  server->SimulateDeviceLossForTesting();
  for (int i = 0; i < 2; ++i) {
    grpc::ClientContext ctx;
    v1::Frame f;
    EXPECT_CODE(stub->Render(&ctx, DemoRequest(16, 16), &f), UNAVAILABLE, "device was lost");
  }
  server->CheckHealth();
  EXPECT_FALSE(HealthServing(server->address()));
  const v1::ServerInfo lost = info();
  EXPECT_FALSE(lost.serving());
  EXPECT_NE(lost.unhealthy_reason().find("device was lost"), std::string::npos)
      << lost.unhealthy_reason();
  m = ParseMetrics(server->MetricsText());
  EXPECT_EQ(m.at("tessera_device_lost"), 1.0);
  EXPECT_EQ(m.at("tessera_serving"), 0.0);
  EXPECT_EQ(lost_calls.load(), 1);
}

constexpr char kOpsToken[] = "ops-token-0123456789abcdef";
constexpr char kViewerToken[] = "viewer-token-abcdefghijklmn";

TEST(Security, TokensAreRequiredHealthStaysOpenLimitsHoldAndReloadWorks) {
  const std::string tokens = TempPath("tokens.txt");
  WriteFile(tokens, absl::StrCat("# test tokens\n", kOpsToken, " ops\n", kViewerToken,
                                 " viewer max_sessions=1 max_uploads=0\n"));
  ServerOptions o = BaseOptions();
  o.token_file = tokens;
  std::unique_ptr<Server> server = StartServer(o);
  ASSERT_NE(server, nullptr);
  auto stub = Connect(server->address());
  v1::Frame f;
  {  // no token, a wrong token, another scheme
    grpc::ClientContext none, wrong, basic, info_ctx;
    EXPECT_CODE(stub->Render(&none, DemoRequest(16, 16), &f), UNAUTHENTICATED, "bearer token");
    WithToken(&wrong, "not-a-valid-token-at-all-000");
    EXPECT_CODE(stub->Render(&wrong, DemoRequest(16, 16), &f), UNAUTHENTICATED, "invalid");
    basic.AddMetadata("authorization", absl::StrCat("Basic ", kOpsToken));
    EXPECT_CODE(stub->Render(&basic, DemoRequest(16, 16), &f), UNAUTHENTICATED, "invalid");
    v1::ServerInfo info;
    EXPECT_EQ(stub->GetServerInfo(&info_ctx, {}, &info).error_code(),
              grpc::StatusCode::UNAUTHENTICATED);
    grpc::ClientContext list_ctx;
    v1::ListScenesResponse list;
    EXPECT_EQ(stub->ListScenes(&list_ctx, {}, &list).error_code(),
              grpc::StatusCode::UNAUTHENTICATED);
    grpc::ClientContext stream_ctx;
    auto rw = stub->Stream(&stream_ctx);
    rw->Write(OpenEvent("demo", 16, 16));
    EXPECT_CODE(CloseStream(rw.get()), UNAUTHENTICATED, "bearer token");
    v1::SceneInfo scene;
    grpc::ClientContext up_ctx;
    EXPECT_EQ(UploadFromDisk(stub.get(), AssetsDir() + "/Box/glTF/Box.gltf", &scene, &up_ctx)
                  .error_code(),
              grpc::StatusCode::UNAUTHENTICATED);
  }
  EXPECT_TRUE(HealthServing(server->address())) << "health needs no token";
  {  // the right token, as call credentials would send it
    grpc::ClientContext ctx;
    WithToken(&ctx, kOpsToken);
    EXPECT_TRUE(stub->Render(&ctx, DemoRequest(16, 16), &f).ok());
    grpc::ClientContext info_ctx;
    WithToken(&info_ctx, kOpsToken);
    v1::ServerInfo info;
    ASSERT_TRUE(stub->GetServerInfo(&info_ctx, {}, &info).ok());
    EXPECT_TRUE(info.auth_required());
    EXPECT_FALSE(info.tls());
  }
  {  // per-token limits: viewer may hold one stream and upload nothing
    grpc::ClientContext a;
    WithToken(&a, kViewerToken);
    auto first = stub->Stream(&a);
    ASSERT_TRUE(first->Write(OpenEvent("demo", 16, 16)));
    ASSERT_TRUE(first->Read(&f));
    grpc::ClientContext b;
    WithToken(&b, kViewerToken);
    auto second = stub->Stream(&b);
    second->Write(OpenEvent("demo", 16, 16));
    EXPECT_CODE(CloseStream(second.get()), RESOURCE_EXHAUSTED, "max_sessions");
    grpc::ClientContext c;  // another token is not limited by viewer's count
    WithToken(&c, kOpsToken);
    auto third = stub->Stream(&c);
    ASSERT_TRUE(third->Write(OpenEvent("demo", 16, 16)));
    EXPECT_TRUE(third->Read(&f));
    EXPECT_TRUE(CloseStream(third.get()).ok());
    // A stream that breaks gives its slot back (its session is parked, not open).
    a.TryCancel();
    first->Finish();
    ASSERT_TRUE(WaitFor(*server, [](const ServerStats& s) { return s.sessions == 0; }));
    grpc::ClientContext d;
    WithToken(&d, kViewerToken);
    auto fourth = stub->Stream(&d);
    ASSERT_TRUE(fourth->Write(OpenEvent("demo", 16, 16)));
    EXPECT_TRUE(fourth->Read(&f)) << "the token's max_sessions was given back";
    EXPECT_TRUE(CloseStream(fourth.get()).ok());
    v1::SceneInfo scene;
    grpc::ClientContext up;
    WithToken(&up, kViewerToken);
    grpc::Status st = UploadFromDisk(stub.get(), AssetsDir() + "/Box/glTF/Box.gltf", &scene, &up);
    EXPECT_CODE(st, RESOURCE_EXHAUSTED, "max_uploads");
    EXPECT_EQ(st.error_message().find(kViewerToken), std::string::npos) << "no secret in errors";
  }
  // Reload: the viewer token is replaced; a broken file keeps the current table.
  const std::string new_token = "fresh-viewer-token-zyxwvutsrq";
  WriteFile(tokens, absl::StrCat(kOpsToken, " ops\n", new_token, " viewer\n"));
  ASSERT_TRUE(server->ReloadTokens().ok());
  {
    grpc::ClientContext old_ctx, new_ctx;
    WithToken(&old_ctx, kViewerToken);
    EXPECT_EQ(stub->Render(&old_ctx, DemoRequest(16, 16), &f).error_code(),
              grpc::StatusCode::UNAUTHENTICATED);
    WithToken(&new_ctx, new_token);
    EXPECT_TRUE(stub->Render(&new_ctx, DemoRequest(16, 16), &f).ok());
  }
  WriteFile(tokens, "this line is not a token file\n");
  EXPECT_FALSE(server->ReloadTokens().ok());
  {
    grpc::ClientContext ctx;
    WithToken(&ctx, new_token);
    EXPECT_TRUE(stub->Render(&ctx, DemoRequest(16, 16), &f).ok()) << "the old table stays";
  }
  // Resume tokens are bound to who opened the session.
  {
    grpc::ClientContext ctx;
    WithToken(&ctx, kOpsToken);
    auto rw = stub->Stream(&ctx);
    ASSERT_TRUE(rw->Write(OpenEvent("demo", 16, 16)));
    ASSERT_TRUE(rw->Read(&f));
    const std::string session = f.session_token();
    grpc::ClientContext thief;
    WithToken(&thief, new_token);
    auto other = stub->Stream(&thief);
    other->Write(ResumeEvent(session));
    EXPECT_CODE(CloseStream(other.get()), NOT_FOUND, "resume_token");
    EXPECT_TRUE(CloseStream(rw.get()).ok()) << "the owner's stream was not touched";
  }
  server->Shutdown();
  fs::remove(tokens);
}

// --- TLS and mTLS --------------------------------------------------------------------------

TEST(Security, TlsAndMutualTls) {
  const tessera::testing::TestPki pki = tessera::testing::MakeTestPki();
  const std::string cert = TempPath("server.pem"), key = TempPath("server.key"),
                    ca = TempPath("ca.pem");
  WriteFile(cert, pki.server_cert_pem);
  WriteFile(key, pki.server_key_pem);
  WriteFile(ca, pki.ca_cert_pem);
  auto tls_client = [&](const std::string& roots, bool with_cert) {
    grpc::SslCredentialsOptions ssl;
    ssl.pem_root_certs = roots;
    if (with_cert) {
      ssl.pem_cert_chain = pki.client_cert_pem;
      ssl.pem_private_key = pki.client_key_pem;
    }
    return grpc::SslCredentials(ssl);
  };
  auto render = [](const std::string& address, std::shared_ptr<grpc::ChannelCredentials> c) {
    auto stub = Connect(address, {.creds = c});
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(20));
    v1::Frame f;
    return stub->Render(&ctx, DemoRequest(16, 16), &f);
  };
  {
    ServerOptions o = BaseOptions();
    o.tls_cert_file = cert;
    o.tls_key_file = key;
    o.health_listen = "127.0.0.1:0";  // plaintext health for the probes, nothing else
    std::unique_ptr<Server> server = StartServer(o);
    ASSERT_NE(server, nullptr);
    ASSERT_GT(server->health_port(), 0);
    const std::string health = absl::StrCat("127.0.0.1:", server->health_port());
    EXPECT_TRUE(HealthServing(health));
    EXPECT_EQ(render(health, grpc::InsecureChannelCredentials()).error_code(),
              grpc::StatusCode::UNIMPLEMENTED)
        << "the plaintext health port serves nothing but health";
    EXPECT_TRUE(render(server->address(), tls_client(pki.ca_cert_pem, false)).ok());
    EXPECT_EQ(render(server->address(), tls_client(pki.other_ca_cert_pem, false)).error_code(),
              grpc::StatusCode::UNAVAILABLE)
        << "a certificate from an untrusted CA is refused";
    EXPECT_EQ(render(server->address(), grpc::InsecureChannelCredentials()).error_code(),
              grpc::StatusCode::UNAVAILABLE)
        << "plaintext does not reach a TLS server";
    EXPECT_TRUE(HealthServing(server->address(), tls_client(pki.ca_cert_pem, false)));
    server->Shutdown();
  }
  {
    ServerOptions o = BaseOptions();
    o.tls_cert_file = cert;
    o.tls_key_file = key;
    o.tls_client_ca_file = ca;
    std::unique_ptr<Server> server = StartServer(o);
    ASSERT_NE(server, nullptr);
    EXPECT_TRUE(render(server->address(), tls_client(pki.ca_cert_pem, true)).ok());
    EXPECT_EQ(render(server->address(), tls_client(pki.ca_cert_pem, false)).error_code(),
              grpc::StatusCode::UNAVAILABLE)
        << "mTLS: no client certificate, no call";
    server->Shutdown();
  }
  {  // bad files are named
    ServerOptions o = BaseOptions();
    o.tls_cert_file = cert;
    o.tls_key_file = TempPath("missing.key");
    absl::StatusOr<std::unique_ptr<Server>> s = Server::Start(o);
    ASSERT_FALSE(s.ok());
    EXPECT_NE(s.status().message().find("tls_key"), std::string::npos) << s.status();
    o.tls_key_file = "";
    s = Server::Start(o);
    ASSERT_FALSE(s.ok());
    EXPECT_NE(s.status().message().find("tls_cert / tls_key"), std::string::npos) << s.status();
  }
  for (const std::string& p : {cert, key, ca}) fs::remove(p);
}

// --- the tesserad binary: SIGHUP reloads the token file ------------------------------------

TEST(TesseradProcess, SighupReloadsTheTokenFile) {
  const std::string tokens = TempPath("sighup_tokens.txt");
  const std::string port_file = TempPath("sighup_port");
  WriteFile(tokens, absl::StrCat(kOpsToken, " ops\n"));
  const auto [pid, port] = SpawnTesserad(port_file, {"--token_file=" + tokens});
  ASSERT_GT(pid, 0);
  ASSERT_GT(port, 0) << "tesserad did not start";
  auto stub = Connect(absl::StrCat("127.0.0.1:", port));
  auto render_with = [&](const std::string& token) {
    grpc::ClientContext ctx;
    WithToken(&ctx, token);
    v1::Frame f;
    return stub->Render(&ctx, DemoRequest(16, 16), &f).error_code();
  };
  EXPECT_EQ(render_with(kOpsToken), grpc::StatusCode::OK);
  const std::string added = "added-by-sighup-0123456789";
  WriteFile(tokens, absl::StrCat(kOpsToken, " ops\n", added, " added\n"));
  EXPECT_EQ(render_with(added), grpc::StatusCode::UNAUTHENTICATED) << "not before the signal";
  ASSERT_EQ(kill(pid, SIGHUP), 0);
  grpc::StatusCode code = grpc::StatusCode::UNAUTHENTICATED;
  for (int i = 0; i < 100 && code != grpc::StatusCode::OK; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    code = render_with(added);
  }
  EXPECT_EQ(code, grpc::StatusCode::OK);
  kill(pid, SIGTERM);
  int status = 0;
  waitpid(pid, &status, 0);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  fs::remove(tokens);
  fs::remove(port_file);
}

// A lost device ends the process with status 75 after a graceful shutdown, so that its
// supervisor starts a fresh one (TESSERA_TEST_DEVICE_LOST_AFTER_FRAMES=1: the second frame meets
// the lost device).
TEST(TesseradProcess, ALostDeviceExitsWithStatus75) {
  const std::string port_file = TempPath("lost_port");
  const auto [pid, port] =
      SpawnTesserad(port_file, {}, {"TESSERA_TEST_DEVICE_LOST_AFTER_FRAMES=1"});
  ASSERT_GT(pid, 0);
  ASSERT_GT(port, 0) << "tesserad did not start";
  auto stub = Connect(absl::StrCat("127.0.0.1:", port));
  {
    grpc::ClientContext ctx;
    v1::Frame f;
    EXPECT_TRUE(stub->Render(&ctx, DemoRequest(16, 16), &f).ok());
  }
  {
    grpc::ClientContext ctx;
    v1::Frame f;
    EXPECT_CODE(stub->Render(&ctx, DemoRequest(16, 16), &f), UNAVAILABLE, "device was lost");
  }
  int status = 0;
  pid_t done = 0;
  for (int i = 0; i < 200 && done == 0; ++i) {  // 20 s at most
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    done = waitpid(pid, &status, WNOHANG);
  }
  if (done == 0) {
    kill(pid, SIGKILL);
    waitpid(pid, &status, 0);
    ADD_FAILURE() << "tesserad did not exit after losing its device";
  } else {
    EXPECT_TRUE(WIFEXITED(status)) << "killed by a signal instead of exiting: " << status;
    EXPECT_EQ(WEXITSTATUS(status), 75);
  }
  fs::remove(port_file);
}

}  // namespace
}  // namespace tessera
