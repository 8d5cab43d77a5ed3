// The Prometheus metrics: counters, histograms and scrape-time gauges in the exposition text,
// the HTTP endpoint (GET /metrics over a plain socket, parsed as the text format), its errors
// (address in use, bad address, second Serve) and recording from several threads at once.
#include "server/metrics.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <thread>
#include <utility>
#include <vector>

#include "absl/status/status.h"

namespace tessera::server {
namespace {

// The value of the sample line `series` (the name with its labels exactly as serialized, e.g.
// `tessera_frames_total{kind="stream",profile="full"}`), or nullopt when there is none.
std::optional<double> Sample(const std::string& text, std::string_view series) {
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    if (line.size() > series.size() && line.compare(0, series.size(), series) == 0 &&
        line[series.size()] == ' ') {
      const std::string value = line.substr(series.size() + 1);
      if (value == "+Inf") return std::numeric_limits<double>::infinity();
      if (value == "-Inf") return -std::numeric_limits<double>::infinity();
      if (value == "NaN" || value == "Nan") return std::numeric_limits<double>::quiet_NaN();
      char* end = nullptr;
      const double v = std::strtod(value.c_str(), &end);
      if (end != value.c_str() + value.size()) return std::nullopt;
      return v;
    }
  }
  return std::nullopt;
}

bool IsNameStart(char c) {
  return std::isalpha(static_cast<unsigned char>(c)) || c == '_' || c == ':';
}
bool IsNameChar(char c) { return IsNameStart(c) || std::isdigit(static_cast<unsigned char>(c)); }

// A sample value of the text format: a finite decimal number, +Inf, -Inf or NaN (prometheus-cpp
// writes "Nan", which Prometheus's case-insensitive float parser accepts too).
bool IsSampleValue(std::string_view v) {
  if (v == "+Inf" || v == "-Inf" || v == "NaN" || v == "Nan") return true;
  if (v.empty()) return false;
  const std::string s(v);
  char* end = nullptr;
  const double d = std::strtod(s.c_str(), &end);
  return end == s.c_str() + s.size() && std::isfinite(d);
}

// One line of the text exposition format: "# HELP name text", "# TYPE name type", another
// comment, or a sample `name{label="value",...} value [timestamp]` / `name value [timestamp]`.
::testing::AssertionResult IsExpositionLine(std::string_view line) {
  auto fail = [&](std::string_view why) {
    return ::testing::AssertionFailure() << why << " in line \"" << line << "\"";
  };
  if (line.empty()) return fail("empty line");
  if (line[0] == '#') {
    for (std::string_view kind : {"# HELP ", "# TYPE "}) {
      if (line.substr(0, kind.size()) != kind) continue;
      std::string_view rest = line.substr(kind.size());
      size_t n = 0;
      if (rest.empty() || !IsNameStart(rest[0])) return fail("bad metric name");
      while (n < rest.size() && IsNameChar(rest[n])) ++n;
      if (kind == "# TYPE ") {
        const std::string_view type = rest.substr(n);
        if (type != " counter" && type != " gauge" && type != " histogram" && type != " summary" &&
            type != " untyped")
          return fail("bad type");
      } else if (n < rest.size() && rest[n] != ' ') {
        return fail("bad HELP");
      }
    }
    return ::testing::AssertionSuccess();
  }
  size_t i = 0;
  if (!IsNameStart(line[0])) return fail("bad metric name");
  while (i < line.size() && IsNameChar(line[i])) ++i;
  if (i < line.size() && line[i] == '{') {
    ++i;
    while (i < line.size() && line[i] != '}') {
      if (!IsNameStart(line[i]) || line[i] == ':') return fail("bad label name");
      while (i < line.size() && IsNameChar(line[i]) && line[i] != ':') ++i;
      if (line.substr(i, 2) != "=\"") return fail("label without =\"");
      i += 2;
      while (i < line.size() && line[i] != '"') {
        if (line[i] == '\\') {
          if (i + 1 >= line.size() ||
              (line[i + 1] != '\\' && line[i + 1] != '"' && line[i + 1] != 'n'))
            return fail("bad escape in label value");
          ++i;
        }
        ++i;
      }
      if (i >= line.size()) return fail("unterminated label value");
      ++i;  // closing quote
      if (i < line.size() && line[i] == ',')
        ++i;
      else if (i < line.size() && line[i] != '}')
        return fail("labels not separated by ,");
    }
    if (i >= line.size()) return fail("unterminated labels");
    ++i;  // }
  }
  if (i >= line.size() || line[i] != ' ') return fail("no space before the value");
  std::string_view rest = line.substr(i + 1);
  const size_t space = rest.find(' ');
  if (!IsSampleValue(rest.substr(0, space))) return fail("bad value");
  if (space != std::string_view::npos) {
    const std::string_view ts = rest.substr(space + 1);
    if (ts.empty()) return fail("empty timestamp");
    for (size_t k = 0; k < ts.size(); ++k) {
      if (!std::isdigit(static_cast<unsigned char>(ts[k])) && !(k == 0 && ts[k] == '-'))
        return fail("bad timestamp");
    }
  }
  return ::testing::AssertionSuccess();
}

// A whole exposition body: newline-terminated lines, each valid.
::testing::AssertionResult IsExpositionText(const std::string& body) {
  if (body.empty() || body.back() != '\n')
    return ::testing::AssertionFailure() << "body does not end with a newline";
  std::istringstream in(body);
  std::string line;
  while (std::getline(in, line)) {
    ::testing::AssertionResult ok = IsExpositionLine(line);
    if (!ok) return ok;
  }
  return ::testing::AssertionSuccess();
}

// GET `path` from 127.0.0.1:`port` over HTTP/1.0 (the server closes when done): the whole
// response, or an empty string when the connection fails. Reads time out after 10 s.
std::string HttpGet(int port, std::string_view path) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return "";
  timeval timeout{10, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof(timeout));
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof(timeout));
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  std::string response;
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) == 0) {
    const std::string request = "GET " + std::string(path) + " HTTP/1.0\r\nHost: x\r\n\r\n";
    size_t sent = 0;
    while (sent < request.size()) {
      const ssize_t n = ::send(fd, request.data() + sent, request.size() - sent, MSG_NOSIGNAL);
      if (n <= 0) break;
      sent += static_cast<size_t>(n);
    }
    char buffer[4096];
    ssize_t n;
    while ((n = ::recv(fd, buffer, sizeof(buffer), 0)) > 0) response.append(buffer, n);
  }
  ::close(fd);
  return response;
}

// Gauge values the test changes; the callback reads them under a lock, as the Server would.
struct FakeGauges {
  std::mutex mu;
  MetricsGauges values;
  std::function<MetricsGauges()> Callback() {
    return [this] {
      std::lock_guard lock(mu);
      return values;
    };
  }
  void Set(const MetricsGauges& g) {
    std::lock_guard lock(mu);
    values = g;
  }
};

using Passes = std::vector<std::pair<std::string, double>>;

// The format checker itself, so that "parses as the text format" below means something.
TEST(MetricsTest, ExpositionCheckerRejectsMalformedLines) {
  EXPECT_TRUE(IsExpositionLine("# HELP a_b Some help."));
  EXPECT_TRUE(IsExpositionLine("# TYPE a_b histogram"));
  EXPECT_TRUE(IsExpositionLine("a_b 1"));
  EXPECT_TRUE(IsExpositionLine(R"(a_b{x="1",le="+Inf"} 2.5e-3)"));
  EXPECT_TRUE(IsExpositionLine(R"(a_b{x="q\"uote"} +Inf 1700000000000)"));
  EXPECT_TRUE(IsExpositionLine("a_b NaN"));
  EXPECT_FALSE(IsExpositionLine("# TYPE a_b gaugey"));
  EXPECT_FALSE(IsExpositionLine("1ab 1"));
  EXPECT_FALSE(IsExpositionLine("a_b"));
  EXPECT_FALSE(IsExpositionLine("a_b  1"));
  EXPECT_FALSE(IsExpositionLine("a_b one"));
  EXPECT_FALSE(IsExpositionLine("a_b inf"));
  EXPECT_FALSE(IsExpositionLine(R"(a_b{x=1} 1)"));
  EXPECT_FALSE(IsExpositionLine(R"(a_b{x="1" 1)"));
  EXPECT_FALSE(IsExpositionLine(R"(a_b{x="1"y="2"} 1)"));
  EXPECT_FALSE(IsExpositionLine("a_b 1 soon"));
  EXPECT_FALSE(IsExpositionText("a_b 1"));  // no final newline
}

TEST(MetricsTest, GrpcCodeNamesAreTheCanonicalNames) {
  for (int code = 0; code <= 16; ++code) {
    EXPECT_EQ(GrpcCodeName(code), absl::StatusCodeToString(static_cast<absl::StatusCode>(code)))
        << code;
  }
  EXPECT_EQ(GrpcCodeName(0), "OK");
  EXPECT_EQ(GrpcCodeName(3), "INVALID_ARGUMENT");
  EXPECT_EQ(GrpcCodeName(16), "UNAUTHENTICATED");
  EXPECT_EQ(GrpcCodeName(17), "UNKNOWN");
  EXPECT_EQ(GrpcCodeName(-1), "UNKNOWN");
}

TEST(MetricsTest, EveryMetricHasHelpAndType) {
  Metrics metrics(nullptr);  // no callback: the gauges read 0
  metrics.FrameDone("stream", "full", {{"gbuffer", 1.0}}, 1.0, 1.0, 2.0);
  const std::string text = metrics.Text();
  EXPECT_TRUE(IsExpositionText(text)) << text;
  const std::pair<const char*, const char*> expected[] = {
      {"tessera_frames_total", "counter"},
      {"tessera_frames_dropped_total", "counter"},
      {"tessera_uploads_total", "counter"},
      {"tessera_upload_bytes_total", "counter"},
      {"tessera_rpcs_total", "counter"},  // no RPC yet: may be absent, checked below
      {"tessera_sessions_opened_total", "counter"},
      {"tessera_scenes_evicted_total", "counter"},
      {"tessera_pass_gpu_milliseconds", "histogram"},
      {"tessera_frame_gpu_milliseconds", "histogram"},
      {"tessera_encode_milliseconds", "histogram"},
      {"tessera_frame_total_milliseconds", "histogram"},
      {"tessera_video_encode_milliseconds", "histogram"},
      {"tessera_video_bytes_total", "counter"},
      {"tessera_video_frames_total", "counter"},
      {"tessera_sessions", "gauge"},
      {"tessera_parked_sessions", "gauge"},
      {"tessera_queue_depth", "gauge"},
      {"tessera_frames_in_flight", "gauge"},
      {"tessera_uploads_in_progress", "gauge"},
      {"tessera_scenes", "gauge"},
      {"tessera_scene_device_bytes", "gauge"},
      {"tessera_scene_memory_budget_bytes", "gauge"},
      {"tessera_pending_frame_bytes", "gauge"},
      {"tessera_jobs_active", "gauge"},
  };
  metrics.RpcFinished("Render", 0);
  const std::string after_rpc = metrics.Text();
  for (const auto& [name, type] : expected) {
    EXPECT_NE(after_rpc.find(std::string("# HELP ") + name + " "), std::string::npos) << name;
    EXPECT_NE(after_rpc.find(std::string("# TYPE ") + name + " " + type + "\n"), std::string::npos)
        << name;
  }
  // Known series exist before their first increment, at 0.
  EXPECT_EQ(Sample(text, R"(tessera_frames_total{kind="background",profile="interactive"})"), 0);
  EXPECT_EQ(Sample(text, R"(tessera_uploads_total{result="error"})"), 0);
  EXPECT_EQ(Sample(text, R"(tessera_sessions_opened_total{resumed="true"})"), 0);
  EXPECT_EQ(Sample(text, "tessera_frames_dropped_total"), 0);
  EXPECT_EQ(Sample(text, "tessera_scenes"), 0);
}

TEST(MetricsTest, CountersCount) {
  Metrics metrics(nullptr);
  metrics.FrameDone("stream", "full", {}, 1, 1, 1);
  metrics.FrameDone("stream", "full", {}, 1, 1, 1);
  metrics.FrameDone("render", "interactive", {}, 1, 1, 1);
  metrics.FrameDropped();
  metrics.FrameDropped();
  metrics.UploadFinished("loaded", 1000);
  metrics.UploadFinished("loaded", 500);
  metrics.UploadFinished("error", 7);
  metrics.RpcFinished("Render", 0);
  metrics.RpcFinished("Render", 0);
  metrics.RpcFinished("UploadScene", 3);
  metrics.RpcFinished("Stream", 16);
  metrics.RpcFinished("Stream", 99);  // not a code: UNKNOWN
  metrics.SessionOpened(false);
  metrics.SessionOpened(false);
  metrics.SessionOpened(true);
  metrics.SceneEvicted();
  metrics.VideoFrameEncoded(3.0, 1000, true);
  metrics.VideoFrameEncoded(1.0, 200, false);
  metrics.VideoFrameEncoded(1.5, 300, false);
  const std::string text = metrics.Text();
  EXPECT_EQ(Sample(text, R"(tessera_frames_total{kind="stream",profile="full"})"), 2) << text;
  EXPECT_EQ(Sample(text, "tessera_video_bytes_total"), 1500);
  EXPECT_EQ(Sample(text, R"(tessera_video_frames_total{keyframe="true"})"), 1);
  EXPECT_EQ(Sample(text, R"(tessera_video_frames_total{keyframe="false"})"), 2);
  EXPECT_EQ(Sample(text, "tessera_video_encode_milliseconds_count"), 3);
  EXPECT_EQ(Sample(text, R"(tessera_frames_total{kind="render",profile="interactive"})"), 1);
  EXPECT_EQ(Sample(text, R"(tessera_frames_total{kind="render",profile="full"})"), 0);
  EXPECT_EQ(Sample(text, "tessera_frames_dropped_total"), 2);
  EXPECT_EQ(Sample(text, R"(tessera_uploads_total{result="loaded"})"), 2);
  EXPECT_EQ(Sample(text, R"(tessera_uploads_total{result="cached"})"), 0);
  EXPECT_EQ(Sample(text, R"(tessera_uploads_total{result="error"})"), 1);
  EXPECT_EQ(Sample(text, "tessera_upload_bytes_total"), 1507);
  EXPECT_EQ(Sample(text, R"(tessera_rpcs_total{code="OK",method="Render"})"), 2);
  EXPECT_EQ(Sample(text, R"(tessera_rpcs_total{code="INVALID_ARGUMENT",method="UploadScene"})"), 1);
  EXPECT_EQ(Sample(text, R"(tessera_rpcs_total{code="UNAUTHENTICATED",method="Stream"})"), 1);
  EXPECT_EQ(Sample(text, R"(tessera_rpcs_total{code="UNKNOWN",method="Stream"})"), 1);
  EXPECT_EQ(Sample(text, R"(tessera_sessions_opened_total{resumed="false"})"), 2);
  EXPECT_EQ(Sample(text, R"(tessera_sessions_opened_total{resumed="true"})"), 1);
  EXPECT_EQ(Sample(text, "tessera_scenes_evicted_total"), 1);
  EXPECT_TRUE(IsExpositionText(text)) << text;
}

TEST(MetricsTest, HistogramsObserveMilliseconds) {
  Metrics metrics(nullptr);
  metrics.FrameDone("stream", "full", Passes{{"gbuffer", 0.3}, {"lighting", 2.0}}, 2.3, 4.0, 12.0);
  metrics.FrameDone("stream", "full", Passes{{"gbuffer", 0.3}, {"lighting", 2.0}}, 2.3, 4.0, 30.0);
  metrics.FrameDone("render", "full", Passes{{"gbuffer", 7.0}, {"lighting", -1.0}}, 7.0, 0.05,
                    6000.0);
  // No GPU timer, a failed frame: nothing observed, but the frame still counts.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  metrics.FrameDone("render", "full", Passes{{"gbuffer", nan}}, -1, nan, -1);
  const std::string text = metrics.Text();

  const std::string pass = "tessera_pass_gpu_milliseconds";
  EXPECT_EQ(Sample(text, pass + R"(_count{pass="gbuffer"})"), 3) << text;
  EXPECT_NEAR(*Sample(text, pass + R"(_sum{pass="gbuffer"})"), 7.6, 1e-9);
  EXPECT_EQ(Sample(text, pass + R"(_bucket{pass="gbuffer",le="0.1"})"), 0);
  EXPECT_EQ(Sample(text, pass + R"(_bucket{pass="gbuffer",le="0.25"})"), 0);
  EXPECT_EQ(Sample(text, pass + R"(_bucket{pass="gbuffer",le="0.5"})"), 2);  // cumulative
  EXPECT_EQ(Sample(text, pass + R"(_bucket{pass="gbuffer",le="5"})"), 2);
  EXPECT_EQ(Sample(text, pass + R"(_bucket{pass="gbuffer",le="10"})"), 3);
  EXPECT_EQ(Sample(text, pass + R"(_bucket{pass="gbuffer",le="5000"})"), 3);
  EXPECT_EQ(Sample(text, pass + R"(_bucket{pass="gbuffer",le="+Inf"})"), 3);
  EXPECT_EQ(Sample(text, pass + R"(_count{pass="lighting"})"), 2);  // -1 not observed
  EXPECT_EQ(Sample(text, pass + R"(_bucket{pass="lighting",le="2.5"})"), 2);
  EXPECT_EQ(Sample(text, pass + R"(_bucket{pass="lighting",le="1"})"), 0);

  EXPECT_EQ(Sample(text, "tessera_frame_gpu_milliseconds_count"), 3);
  EXPECT_NEAR(*Sample(text, "tessera_frame_gpu_milliseconds_sum"), 11.6, 1e-9);
  EXPECT_EQ(Sample(text, "tessera_encode_milliseconds_count"), 3);
  EXPECT_EQ(Sample(text, R"(tessera_encode_milliseconds_bucket{le="0.1"})"), 1);
  EXPECT_EQ(Sample(text, R"(tessera_frame_total_milliseconds_count{kind="stream"})"), 2);
  EXPECT_EQ(Sample(text, R"(tessera_frame_total_milliseconds_bucket{kind="stream",le="25"})"), 1);
  EXPECT_EQ(Sample(text, R"(tessera_frame_total_milliseconds_count{kind="render"})"), 1);
  EXPECT_EQ(Sample(text, R"(tessera_frame_total_milliseconds_bucket{kind="render",le="5000"})"), 0);
  EXPECT_EQ(Sample(text, R"(tessera_frame_total_milliseconds_bucket{kind="render",le="+Inf"})"), 1);
  EXPECT_EQ(Sample(text, R"(tessera_frames_total{kind="render",profile="full"})"), 2);
  EXPECT_TRUE(IsExpositionText(text)) << text;
}

TEST(MetricsTest, GaugesAreReadWhenCollected) {
  FakeGauges fake;
  Metrics metrics(fake.Callback());
  MetricsGauges g;
  g.sessions = 3;
  g.parked_sessions = 1;
  g.queue_depth = 5;
  g.frames_in_flight = 2;
  g.uploads_in_progress = 1;
  g.scenes = 4;
  g.scene_device_bytes = 3'000'000'000ull;  // beyond 32 bits
  g.scene_memory_budget_bytes = 0;
  g.pending_frame_bytes = 123456;
  g.jobs_active = 2;
  fake.Set(g);
  std::string text = metrics.Text();
  EXPECT_EQ(Sample(text, "tessera_sessions"), 3) << text;
  EXPECT_EQ(Sample(text, "tessera_parked_sessions"), 1);
  EXPECT_EQ(Sample(text, "tessera_queue_depth"), 5);
  EXPECT_EQ(Sample(text, "tessera_frames_in_flight"), 2);
  EXPECT_EQ(Sample(text, "tessera_uploads_in_progress"), 1);
  EXPECT_EQ(Sample(text, "tessera_scenes"), 4);
  EXPECT_EQ(Sample(text, "tessera_scene_device_bytes"), 3e9);
  EXPECT_EQ(Sample(text, "tessera_scene_memory_budget_bytes"), 0);
  EXPECT_EQ(Sample(text, "tessera_pending_frame_bytes"), 123456);
  EXPECT_EQ(Sample(text, "tessera_jobs_active"), 2);

  g.sessions = 0;
  g.queue_depth = 17;
  g.scene_memory_budget_bytes = 8ull << 30;
  fake.Set(g);
  text = metrics.Text();
  EXPECT_EQ(Sample(text, "tessera_sessions"), 0) << text;
  EXPECT_EQ(Sample(text, "tessera_queue_depth"), 17);
  EXPECT_EQ(Sample(text, "tessera_scene_memory_budget_bytes"), static_cast<double>(8ull << 30));
  EXPECT_TRUE(IsExpositionText(text)) << text;
}

TEST(MetricsTest, ServesTheTextFormatOverHttp) {
  FakeGauges fake;
  MetricsGauges g;
  g.sessions = 2;
  fake.Set(g);
  Metrics metrics(fake.Callback());
  metrics.FrameDone("stream", "interactive", Passes{{"gbuffer", 0.7}}, 0.7, 1.5, 9.0);
  metrics.RpcFinished("Stream", 1);
  absl::StatusOr<int> port = metrics.Serve("127.0.0.1:0");
  ASSERT_TRUE(port.ok()) << port.status();
  ASSERT_GT(*port, 0);

  const std::string response = HttpGet(*port, "/metrics");
  ASSERT_FALSE(response.empty()) << "no response from port " << *port;
  const std::string status_line = response.substr(0, response.find("\r\n"));
  EXPECT_TRUE(status_line.rfind("HTTP/1.1 200", 0) == 0 ||
              status_line.rfind("HTTP/1.0 200", 0) == 0)
      << status_line;
  const size_t header_end = response.find("\r\n\r\n");
  ASSERT_NE(header_end, std::string::npos) << response;
  const std::string body = response.substr(header_end + 4);
  EXPECT_NE(body.find("tessera_frames_total"), std::string::npos) << body;
  EXPECT_TRUE(IsExpositionText(body)) << body;
  EXPECT_EQ(Sample(body, R"(tessera_frames_total{kind="stream",profile="interactive"})"), 1);
  EXPECT_EQ(Sample(body, R"(tessera_rpcs_total{code="CANCELLED",method="Stream"})"), 1);
  EXPECT_EQ(Sample(body, "tessera_sessions"), 2);

  // The next scrape reads the gauges again.
  g.sessions = 7;
  fake.Set(g);
  const std::string again = HttpGet(*port, "/metrics");
  EXPECT_EQ(Sample(again.substr(again.find("\r\n\r\n") + 4), "tessera_sessions"), 7) << again;

  absl::StatusOr<int> twice = metrics.Serve("127.0.0.1:0");
  EXPECT_EQ(twice.status().code(), absl::StatusCode::kFailedPrecondition) << twice.status();
}

TEST(MetricsTest, AddressInUseIsAnError) {
  Metrics first(nullptr);
  absl::StatusOr<int> port = first.Serve("127.0.0.1:0");
  ASSERT_TRUE(port.ok()) << port.status();

  Metrics second(nullptr);
  const std::string taken = "127.0.0.1:" + std::to_string(*port);
  absl::StatusOr<int> again;
  EXPECT_NO_THROW(again = second.Serve(taken));
  EXPECT_EQ(again.status().code(), absl::StatusCode::kUnavailable) << again.status();
  EXPECT_NE(again.status().message().find(taken), std::string::npos) << again.status();

  // Not host:port.
  for (const char* bad : {"", "127.0.0.1", "127.0.0.1:", "127.0.0.1:http", "127.0.0.1:70000"}) {
    absl::StatusOr<int> status = second.Serve(bad);
    EXPECT_EQ(status.status().code(), absl::StatusCode::kInvalidArgument) << bad;
  }
  // A failed Serve may be retried.
  absl::StatusOr<int> retry = second.Serve("127.0.0.1:0");
  ASSERT_TRUE(retry.ok()) << retry.status();
  EXPECT_NE(*retry, *port);
  EXPECT_NE(HttpGet(*retry, "/metrics").find("tessera_frames_total"), std::string::npos);
}

TEST(MetricsTest, ConcurrentRecordingLosesNothing) {
  FakeGauges fake;
  Metrics metrics(fake.Callback());
  constexpr int kThreads = 4;
  constexpr int kFrames = 1000;
  const Passes passes = {{"depth", 0.2}, {"gbuffer", 0.6}, {"lighting", 1.2}, {"post", 0.3}};
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&metrics, &passes, t] {
      for (int i = 0; i < kFrames; ++i) {
        metrics.FrameDone("stream", "full", passes, 2.3, 1.0, 8.0);
        if (i % 10 == 0) metrics.RpcFinished(t % 2 ? "Render" : "Stream", 0);
      }
    });
  }
  // Scrapes while the encoders record.
  for (int i = 0; i < 20; ++i) EXPECT_TRUE(IsExpositionText(metrics.Text()));
  for (std::thread& thread : threads) thread.join();
  const std::string text = metrics.Text();
  EXPECT_EQ(Sample(text, R"(tessera_frames_total{kind="stream",profile="full"})"),
            kThreads * kFrames)
      << text;
  for (const char* pass : {"depth", "gbuffer", "lighting", "post"}) {
    EXPECT_EQ(
        Sample(text, std::string("tessera_pass_gpu_milliseconds_count{pass=\"") + pass + "\"}"),
        kThreads * kFrames)
        << pass;
  }
  EXPECT_EQ(Sample(text, R"(tessera_frame_total_milliseconds_count{kind="stream"})"),
            kThreads * kFrames);
  EXPECT_EQ(Sample(text, R"(tessera_rpcs_total{code="OK",method="Render"})"), 200);
  EXPECT_EQ(Sample(text, R"(tessera_rpcs_total{code="OK",method="Stream"})"), 200);
}

}  // namespace
}  // namespace tessera::server
