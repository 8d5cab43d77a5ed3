#pragma once
// gRPC client helpers of the integration tests (server_test, service_test, stream_stress_test):
// channels and stubs, the camera orbit of the stream tests and the events built on it, uploads
// of file sets, closing a stream, waiting on the server's stats, and the fixture of a suite
// that shares one in-process server.
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"
#include "renderer/scene/gltf_import.h"
#include "server/server.h"
#include "common/scene_id.h"
#include "tessera/v1/render_service.grpc.pb.h"

// Expects `status` to have the grpc::StatusCode `code` and a message that names `text`.
#define EXPECT_CODE(status, code, text)                                         \
  do {                                                                          \
    const grpc::Status& st_ = (status);                                         \
    EXPECT_EQ(st_.error_code(), grpc::StatusCode::code) << st_.error_message(); \
    EXPECT_NE(st_.error_message().find(text), std::string::npos)                \
        << "message \"" << st_.error_message() << "\" should name " << text;    \
  } while (0)

namespace tessera::test_client {

#ifdef TESSERAD_PATH
// A tesserad process on a free loopback port (--port_file), with `args` after the defaults and
// `env` (NAME=VALUE) in its environment; port 0 when it did not start within 60 s.
struct TesseradChild {
  pid_t pid = -1;
  int port = 0;
};
inline TesseradChild SpawnTesserad(const std::string& port_file,
                                   const std::vector<std::string>& args = {},
                                   const std::vector<std::string>& env = {}) {
  std::filesystem::remove(port_file);
  std::vector<std::string> argv = {TESSERAD_PATH, "--listen=127.0.0.1:0",
                                   "--port_file=" + port_file, "--log_level=warn"};
  argv.insert(argv.end(), args.begin(), args.end());
  TesseradChild child;
  child.pid = fork();
  if (child.pid == 0) {
    for (const std::string& e : env) putenv(const_cast<char*>(e.c_str()));
    std::vector<char*> raw;
    for (std::string& a : argv) raw.push_back(a.data());
    raw.push_back(nullptr);
    execv(TESSERAD_PATH, raw.data());
    _exit(127);
  }
  for (int i = 0; child.pid > 0 && i < 600 && child.port == 0; ++i) {  // 60 s on a busy machine
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    std::ifstream in(port_file);
    in >> child.port;
  }
  return child;
}
#endif

using StreamRW = grpc::ClientReaderWriter<v1::ClientEvent, v1::Frame>;

inline std::string AssetsDir() {
  const char* env = std::getenv("TESSERA_ASSETS_DIR");
  return env ? env : TESSERA_DEFAULT_ASSETS_DIR;
}

// --- channels ------------------------------------------------------------------------------

struct ConnectOptions {
  std::shared_ptr<grpc::ChannelCredentials> creds = grpc::InsecureChannelCredentials();
  // A fixed 64 KiB stream window (no BDP probing), so a slow reader really pushes back on the
  // server.
  bool small_window = false;
  // A connection of its own (a local subchannel pool: channels to the same address would
  // otherwise share one TCP connection), as a separate viewer has.
  bool own_connection = false;
};

// A channel that takes frames up to 64 MiB.
inline std::shared_ptr<grpc::Channel> NewChannel(const std::string& address,
                                                 const ConnectOptions& o = {}) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(64 << 20);
  if (o.small_window) args.SetInt(GRPC_ARG_HTTP2_BDP_PROBE, 0);
  if (o.own_connection) args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  return grpc::CreateCustomChannel(address, o.creds, args);
}

inline std::unique_ptr<v1::RenderService::Stub> Connect(const std::string& address,
                                                        const ConnectOptions& o = {}) {
  return v1::RenderService::NewStub(NewChannel(address, o));
}

// --- requests and stream events ------------------------------------------------------------

inline v1::RenderRequest DemoRequest(uint32_t w, uint32_t h) {
  v1::RenderRequest req;
  req.set_scene_id("demo");
  req.mutable_settings()->set_width(w);
  req.mutable_settings()->set_height(h);
  return req;
}

inline void SetLookAt(v1::Camera* cam, float ex, float ey, float ez) {
  v1::LookAt* l = cam->mutable_look_at();
  l->mutable_eye()->set_x(ex);
  l->mutable_eye()->set_y(ey);
  l->mutable_eye()->set_z(ez);
  l->mutable_target()->set_y(0.5f);
}

// Eye of camera event (or step) k in the stream tests: a circle, so every event is a new view.
inline void OrbitEye(uint64_t k, v1::Camera* cam) {
  const float a = 0.2f * float(k);
  SetLookAt(cam, 6.0f * std::cos(a), 2.5f, 6.0f * std::sin(a));
}

inline float EyeX(uint64_t k) {
  v1::Camera c;
  OrbitEye(k, &c);
  return c.look_at().eye().x();
}

// Opens a session on `scene` at w x h (target_fps `fps`, 0: on events only), camera step 0.
inline v1::ClientEvent OpenEvent(const std::string& scene, uint32_t w, uint32_t h, float fps = 0) {
  v1::ClientEvent e;
  e.set_event_id(0);
  e.mutable_open()->set_scene_id(scene);
  e.mutable_open()->mutable_settings()->set_width(w);
  e.mutable_open()->mutable_settings()->set_height(h);
  e.mutable_open()->set_target_fps(fps);
  OrbitEye(0, e.mutable_open()->mutable_camera());
  return e;
}

inline v1::ClientEvent CameraEvent(uint64_t id) {
  v1::ClientEvent e;
  e.set_event_id(id);
  OrbitEye(id, e.mutable_camera());
  return e;
}

// Reads until a frame reflects `event` (bounded by the stream ending).
inline bool ReadUntilEvent(StreamRW* rw, uint64_t event, v1::Frame* f) {
  while (rw->Read(f))
    if (f->event_id() >= event) return true;
  return false;
}

// Half-closes, reads what the server still sends, and returns how the stream ended.
inline grpc::Status CloseStream(StreamRW* rw) {
  rw->WritesDone();
  v1::Frame f;
  while (rw->Read(&f)) {
  }
  return rw->Finish();
}

// --- uploads -------------------------------------------------------------------------------

struct UploadPart {
  std::string name;
  std::string bytes;
};

// Uploads files as given (no validation here: the server must do it), in `chunk`-byte chunks,
// on `ctx` (a fresh context when null).
inline grpc::Status UploadRaw(v1::RenderService::Stub* stub, const std::vector<UploadPart>& files,
                              v1::SceneInfo* info, const std::string& main_file = "",
                              size_t chunk = 1 << 20, bool with_sha = true,
                              grpc::ClientContext* ctx = nullptr) {
  grpc::ClientContext own_ctx;
  auto writer = stub->UploadScene(ctx ? ctx : &own_ctx, info);
  v1::UploadRequest req;
  v1::UploadManifest* m = req.mutable_manifest();
  m->set_main_file(main_file);
  for (const UploadPart& f : files) {
    v1::UploadFile* uf = m->add_files();
    uf->set_name(f.name);
    uf->set_size(f.bytes.size());
    if (with_sha) uf->set_sha256(Sha256Hex(f.bytes.data(), f.bytes.size()));
  }
  bool ok = writer->Write(req);
  for (size_t i = 0; ok && i < files.size(); ++i) {
    for (size_t off = 0; ok && off < files[i].bytes.size(); off += chunk) {
      v1::UploadRequest c;
      c.mutable_chunk()->set_file_index(static_cast<uint32_t>(i));
      c.mutable_chunk()->set_offset(off);
      c.mutable_chunk()->set_data(files[i].bytes.substr(off, chunk));
      ok = writer->Write(c);
    }
  }
  writer->WritesDone();
  return writer->Finish();
}

// The glTF file set at `path` (the file and what it references); none, after a test failure,
// when it cannot be read.
inline std::vector<UploadPart> PartsFromDisk(const std::string& path) {
  absl::StatusOr<GltfSource> src = LoadGltfSourceFromDisk(path);
  EXPECT_TRUE(src.ok()) << src.status();
  std::vector<UploadPart> parts;
  if (!src.ok()) return parts;
  for (const auto& [name, data] : src->files)
    parts.push_back({name, std::string(data.begin(), data.end())});
  return parts;
}

inline std::string MainName(const std::string& path) {
  return std::filesystem::path(path).filename().string();
}

// Uploads the glTF file set at `path` (1 MiB chunks, no checksums) on `ctx` (a fresh context
// when null).
inline grpc::Status UploadFromDisk(v1::RenderService::Stub* stub, const std::string& path,
                                   v1::SceneInfo* info, grpc::ClientContext* ctx = nullptr) {
  const std::vector<UploadPart> parts = PartsFromDisk(path);
  if (parts.empty()) return grpc::Status(grpc::StatusCode::INTERNAL, "read");
  return UploadRaw(stub, parts, info, MainName(path), 1 << 20, /*with_sha=*/false, ctx);
}

// --- health ---------------------------------------------------------------------------------

// grpc.health.v1.Health/Check for `service` ("" = the server as a whole, liveness;
// server::kReadinessService = readiness): 1 SERVING, 2 NOT_SERVING; minus the gRPC status code
// when the call fails (-5: NOT_FOUND, a service name the server has not set); -1000 after 10 s
// without an answer.
inline int HealthStatus(const std::string& address, const std::string& service = "",
                        std::shared_ptr<grpc::ChannelCredentials> creds =
                            grpc::InsecureChannelCredentials()) {
  grpc::GenericStub generic(grpc::CreateChannel(address, creds));
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
  // HealthCheckRequest {string service = 1}: short names only (one length byte).
  std::string request_bytes;
  if (!service.empty()) {
    request_bytes.push_back('\x0a');
    request_bytes.push_back(static_cast<char>(service.size()));
    request_bytes += service;
  }
  grpc::Slice slice(request_bytes);
  grpc::ByteBuffer request(&slice, 1), response;
  std::mutex mu;
  std::condition_variable cv;
  bool done = false;
  grpc::Status status;
  generic.UnaryCall(&ctx, "/grpc.health.v1.Health/Check", grpc::StubOptions(), &request,
                    &response, [&](grpc::Status s) {
                      std::lock_guard lock(mu);
                      status = s;
                      done = true;
                      cv.notify_one();
                    });
  std::unique_lock lock(mu);
  if (!cv.wait_for(lock, std::chrono::seconds(15), [&] { return done; })) return -1000;
  if (!status.ok()) return -static_cast<int>(status.error_code());
  // HealthCheckResponse {status = 1}: field 1, varint (SERVING 1, NOT_SERVING 2).
  std::vector<grpc::Slice> slices;
  if (!response.Dump(&slices).ok()) return -1001;
  std::string bytes;
  for (const auto& s : slices) bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
  return bytes.size() == 2 && bytes[0] == '\x08' ? bytes[1] : -1002;
}

inline bool HealthServing(const std::string& address,
                          std::shared_ptr<grpc::ChannelCredentials> creds =
                              grpc::InsecureChannelCredentials()) {
  return HealthStatus(address, "", std::move(creds)) == 1;
}

// --- metrics ------------------------------------------------------------------------------

// The samples of a Prometheus text exposition: "name{labels}" -> value. Labels are kept as
// written (prometheus-cpp sorts them by name).
inline std::map<std::string, double> ParseMetrics(const std::string& text) {
  std::map<std::string, double> out;
  for (absl::string_view line : absl::StrSplit(text, '\n')) {
    if (line.empty() || line[0] == '#') continue;
    const size_t space = line.rfind(' ');
    double v = 0;
    if (space == absl::string_view::npos) continue;
    absl::string_view value = line.substr(space + 1);
    if (value == "+Inf")
      v = INFINITY;
    else if (!absl::SimpleAtod(value, &v))
      continue;
    out[std::string(line.substr(0, space))] = v;
  }
  return out;
}

// --- the server ----------------------------------------------------------------------------

// An in-process server's options for a test: port 0 on loopback, validation layers as
// TESSERA_VALIDATION says.
inline server::ServerOptions BaseOptions() {
  server::ServerOptions o;
  o.listen = "127.0.0.1:0";
  o.validation = std::getenv("TESSERA_VALIDATION") != nullptr;
  return o;
}

// Starts it (a failed start is a test failure and nullptr).
inline std::unique_ptr<server::Server> StartServer(const server::ServerOptions& o) {
  absl::StatusOr<std::unique_ptr<server::Server>> s = server::Server::Start(o);
  EXPECT_TRUE(s.ok()) << s.status();
  return s.ok() ? *std::move(s) : nullptr;
}

// Waits (bounded: `ms`, polling every `poll_ms`) until `pred` holds on the server's stats.
template <typename Pred>
bool WaitFor(const server::Server& server, Pred pred, int ms = 10000, int poll_ms = 10) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(ms);
  while (std::chrono::steady_clock::now() < end) {
    if (pred(server.stats())) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(poll_ms));
  }
  return pred(server.stats());
}

// The fixture of a suite that shares one in-process server: the suite's SetUpTestSuite starts
// it into server_, every test gets stub_ on it, and the suite's end shuts it down and expects
// no validation messages. `Suite` (the derived fixture) gives each suite a server_ of its own.
template <typename Suite>
class SharedServerTest : public ::testing::Test {
 protected:
  static void TearDownTestSuite() {
    if (!server_) return;
    server_->Shutdown();
    EXPECT_EQ(server_->stats().validation_messages, 0u);
    delete server_;
    server_ = nullptr;
  }
  void SetUp() override {
    ASSERT_NE(server_, nullptr);
    stub_ = Connect(server_->address());
  }

  static inline server::Server* server_ = nullptr;
  std::unique_ptr<v1::RenderService::Stub> stub_;
};

}  // namespace tessera::test_client
