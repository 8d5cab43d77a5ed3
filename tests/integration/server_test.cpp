// Integration tests: a real tesserad (in-process Server on port 0, or the tesserad binary for
// signal handling) driven over real gRPC with the generated stubs.
#include "server/server.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/dynamic_message.h>
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <thread>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "renderer/image_io.h"
#include "renderer/scene/gltf_import.h"
#include "common/scene_id.h"
#include "tessera/v1/render_service.grpc.pb.h"
#include "tests/integration/client_helpers.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;
using server::Server;
using server::ServerOptions;
using namespace test_client;  // client_helpers.h

// --- fixture: one in-process server for the suite ----------------------------------------

class ServerTest : public SharedServerTest<ServerTest> {
 protected:
  static void SetUpTestSuite() {
    ServerOptions o;
    o.listen = "127.0.0.1:0";
    o.validation = std::getenv("TESSERA_VALIDATION") != nullptr;
    o.max_sessions = 8;
    absl::StatusOr<std::unique_ptr<Server>> s = Server::Start(o);
    ASSERT_TRUE(s.ok()) << s.status();
    server_ = s->release();
  }
  void TearDown() override {
    // Every test leaves the server healthy: a plain render still works.
    ExpectServes();
    EXPECT_EQ(server_->stats().validation_messages, 0u);
  }

  void ExpectServes() {
    grpc::ClientContext ctx;
    v1::Frame f;
    grpc::Status st = stub_->Render(&ctx, DemoRequest(32, 24), &f);
    EXPECT_TRUE(st.ok()) << st.error_message();
    EXPECT_EQ(f.width(), 32u);
  }

  grpc::Status Render(const v1::RenderRequest& req, v1::Frame* f) {
    grpc::ClientContext ctx;
    return stub_->Render(&ctx, req, f);
  }

  // Waits (bounded) until `pred` holds on the server's stats.
  template <typename Pred>
  bool WaitFor(Pred pred, int ms = 5000) {
    for (int i = 0; i < ms / 10; ++i) {
      if (pred(server_->stats())) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return pred(server_->stats());
  }
};

// --- info, health, reflection ------------------------------------------------------------

TEST_F(ServerTest, ServerInfoDescribesDeviceLimitsAndChoices) {
  grpc::ClientContext ctx;
  v1::ServerInfo info;
  ASSERT_TRUE(stub_->GetServerInfo(&ctx, {}, &info).ok());
  EXPECT_FALSE(info.version().empty());
  EXPECT_FALSE(info.device().name().empty());
  EXPECT_FALSE(info.device().driver_name().empty());
  EXPECT_GE(info.limits().max_samples(), 1u);
  EXPECT_GE(info.limits().max_width(), 4096u);
  EXPECT_EQ(info.limits().max_chunk_bytes(), 1u << 20);
  EXPECT_GE(info.scenes_loaded(), 1u);  // demo
  EXPECT_GE(info.uptime_s(), 0.0);
  auto has = [](const auto& list, const std::string& v) {
    return std::find(list.begin(), list.end(), v) != list.end();
  };
  EXPECT_TRUE(has(info.choices().aa(), "msaa"));
  EXPECT_TRUE(has(info.choices().culling(), "gpu_occlusion"));
  EXPECT_TRUE(has(info.choices().debug_view(), "normals"));
  EXPECT_TRUE(has(info.choices().light_binning(), "gpu"));
  EXPECT_EQ(info.default_settings().width(), 1280u);
  // The glTF extensions the importer reads, as SupportedGltfExtensions() lists them.
  EXPECT_TRUE(has(info.gltf_extensions(), "KHR_mesh_quantization"));
  EXPECT_TRUE(has(info.gltf_extensions(), "KHR_lights_punctual"));
  EXPECT_TRUE(has(info.gltf_extensions(), "EXT_meshopt_compression"));
  EXPECT_TRUE(has(info.gltf_extensions(), "KHR_draco_mesh_compression"));
  EXPECT_EQ(size_t(info.gltf_extensions_size()), SupportedGltfExtensions().size());
}

// grpc.health.v1.Health/Check: the server as a whole and readiness (client_helpers.h).
TEST_F(ServerTest, HealthReportsServing) {
  EXPECT_EQ(HealthStatus(server_->address()), 1);
  EXPECT_EQ(HealthStatus(server_->address(), server::kReadinessService), 1);
  EXPECT_EQ(HealthStatus(server_->address(), "no.such.Service"),
            -static_cast<int>(grpc::StatusCode::NOT_FOUND));
}

// Server reflection: list_services must include tessera.v1.RenderService. The reflection
// messages' descriptors come from the reflection library the server links.
TEST_F(ServerTest, ReflectionListsRenderService) {
  namespace pb = google::protobuf;
  const pb::DescriptorPool* pool = pb::DescriptorPool::generated_pool();
  const pb::Descriptor* req_d =
      pool->FindMessageTypeByName("grpc.reflection.v1alpha.ServerReflectionRequest");
  const pb::Descriptor* resp_d =
      pool->FindMessageTypeByName("grpc.reflection.v1alpha.ServerReflectionResponse");
  ASSERT_NE(req_d, nullptr);
  ASSERT_NE(resp_d, nullptr);
  pb::DynamicMessageFactory factory(pool);
  std::unique_ptr<pb::Message> req(factory.GetPrototype(req_d)->New());
  req->GetReflection()->SetString(req.get(), req_d->FindFieldByName("list_services"), "");
  std::string req_bytes = req->SerializeAsString();

  auto channel = grpc::CreateChannel(server_->address(), grpc::InsecureChannelCredentials());
  grpc::GenericStub generic(channel);
  grpc::ClientContext ctx;
  grpc::CompletionQueue cq;
  auto call = generic.PrepareCall(
      &ctx, "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo", &cq);
  auto step = [&](intptr_t tag) {
    void* got = nullptr;
    bool ok = false;
    EXPECT_TRUE(cq.Next(&got, &ok));
    EXPECT_EQ(reinterpret_cast<intptr_t>(got), tag);
    return ok;
  };
  call->StartCall(reinterpret_cast<void*>(1));
  ASSERT_TRUE(step(1));
  grpc::Slice slice(req_bytes);
  grpc::ByteBuffer out(&slice, 1);
  call->Write(out, reinterpret_cast<void*>(2));
  ASSERT_TRUE(step(2));
  call->WritesDone(reinterpret_cast<void*>(3));
  ASSERT_TRUE(step(3));
  grpc::ByteBuffer in;
  call->Read(&in, reinterpret_cast<void*>(4));
  ASSERT_TRUE(step(4));
  grpc::Status status;
  call->Finish(&status, reinterpret_cast<void*>(5));
  step(5);
  EXPECT_TRUE(status.ok()) << status.error_message();
  std::vector<grpc::Slice> slices;
  ASSERT_TRUE(in.Dump(&slices).ok());
  std::string bytes;
  for (const auto& s : slices) bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
  std::unique_ptr<pb::Message> resp(factory.GetPrototype(resp_d)->New());
  ASSERT_TRUE(resp->ParseFromString(bytes));
  const pb::Message& list =
      resp->GetReflection()->GetMessage(*resp, resp_d->FindFieldByName("list_services_response"));
  const pb::FieldDescriptor* service_f = list.GetDescriptor()->FindFieldByName("service");
  std::vector<std::string> names;
  for (int i = 0; i < list.GetReflection()->FieldSize(list, service_f); ++i) {
    const pb::Message& svc = list.GetReflection()->GetRepeatedMessage(list, service_f, i);
    names.push_back(
        svc.GetReflection()->GetString(svc, svc.GetDescriptor()->FindFieldByName("name")));
  }
  EXPECT_NE(std::find(names.begin(), names.end(), "tessera.v1.RenderService"), names.end());
  EXPECT_NE(std::find(names.begin(), names.end(), "grpc.health.v1.Health"), names.end());
}

// --- uploads and renders -----------------------------------------------------------------

TEST_F(ServerTest, RenderDemoAsJpegAndPng) {
  v1::Frame f;
  ASSERT_TRUE(Render(DemoRequest(160, 90), &f).ok());
  EXPECT_EQ(f.encoding(), v1::IMAGE_JPEG);
  absl::StatusOr<RgbaImage> img =
      DecodeJpeg(std::vector<uint8_t>(f.data().begin(), f.data().end()));
  ASSERT_TRUE(img.ok()) << img.status();
  EXPECT_EQ(img->width, 160u);
  EXPECT_EQ(img->height, 90u);
  EXPECT_EQ(f.sequence(), 1u);
  EXPECT_FALSE(f.passes().empty());
  EXPECT_GT(f.gpu_total_ms(), 0.0);
  EXPECT_GT(f.cpu().encode_ms(), 0.0);
  EXPECT_GE(f.cpu().total_ms(), f.cpu().encode_ms());
  EXPECT_EQ(f.settings().width(), 160u);
  EXPECT_GT(f.stats().draws(), 0u);

  v1::RenderRequest png = DemoRequest(64, 48);
  png.set_encoding(v1::IMAGE_PNG);
  ASSERT_TRUE(Render(png, &f).ok());
  absl::StatusOr<RgbaImage> p = DecodePng(std::vector<uint8_t>(f.data().begin(), f.data().end()));
  ASSERT_TRUE(p.ok()) << p.status();
  EXPECT_EQ(p->width, 64u);
}

// TAA in a unary Render starts from an empty history of its own: the same request gives the
// same bytes whatever was rendered before, and differs from the frame without AA (the 8
// accumulated renders smooth the edges).
TEST_F(ServerTest, UnaryTaaRendersAreReproducible) {
  v1::RenderRequest taa = DemoRequest(96, 64);
  taa.mutable_settings()->set_aa(v1::AA_TAA);
  v1::Frame a, b, other, none;
  ASSERT_TRUE(Render(taa, &a).ok());
  v1::RenderRequest moved = taa;
  moved.mutable_camera()->mutable_frame()->mutable_direction()->set_x(-0.6f);
  moved.mutable_camera()->mutable_frame()->mutable_direction()->set_y(0.5f);
  moved.mutable_camera()->mutable_frame()->mutable_direction()->set_z(0.6f);
  ASSERT_TRUE(Render(moved, &other).ok());
  ASSERT_TRUE(Render(taa, &b).ok());
  EXPECT_EQ(a.data(), b.data()) << "two identical taa renders differ";
  ASSERT_TRUE(Render(DemoRequest(96, 64), &none).ok());
  EXPECT_NE(a.data(), none.data());
}

TEST_F(ServerTest, SettingsTheDeviceCannotDoAreClampedAndReported) {
  v1::RenderRequest req = DemoRequest(64, 48);
  req.mutable_settings()->set_aa(v1::AA_MSAA);
  req.mutable_settings()->set_samples(8);
  v1::Frame f;
  ASSERT_TRUE(Render(req, &f).ok());
  grpc::ClientContext ctx;
  v1::ServerInfo info;
  ASSERT_TRUE(stub_->GetServerInfo(&ctx, {}, &info).ok());
  EXPECT_EQ(f.settings().samples(), std::min(8u, info.limits().max_samples()));
  if (info.limits().max_samples() < 8) {
    bool noted = false;
    for (const auto& n : f.notes()) noted |= n.field() == "samples";
    EXPECT_TRUE(noted);
  }
}

// Every sample model, as .glb and as .gltf + .bin + images, uploads and renders.
TEST_F(ServerTest, UploadAndRenderEveryAsset) {
  std::vector<std::string> paths;
  for (const auto& e : fs::recursive_directory_iterator(AssetsDir())) {
    const std::string ext = e.path().extension().string();
    if (ext == ".gltf" || ext == ".glb") paths.push_back(e.path().string());
  }
  std::sort(paths.begin(), paths.end());
  ASSERT_GE(paths.size(), 10u) << "assets missing in " << AssetsDir();
  std::vector<std::string> ids;
  for (const std::string& path : paths) {
    SCOPED_TRACE(path);
    v1::SceneInfo info;
    grpc::Status st = UploadRaw(stub_.get(), PartsFromDisk(path), &info, MainName(path));
    ASSERT_TRUE(st.ok()) << st.error_message();
    EXPECT_EQ(info.scene_id().size(), 64u);
    EXPECT_GT(info.counts().triangles(), 0u);
    EXPECT_GT(info.device_bytes(), 0u);
    v1::RenderRequest req;
    req.set_scene_id(info.scene_id());
    req.mutable_settings()->set_width(96);
    req.mutable_settings()->set_height(64);
    v1::Frame f;
    st = Render(req, &f);
    ASSERT_TRUE(st.ok()) << st.error_message();
    absl::StatusOr<RgbaImage> img =
        DecodeJpeg(std::vector<uint8_t>(f.data().begin(), f.data().end()));
    ASSERT_TRUE(img.ok()) << img.status();
    EXPECT_EQ(img->width, 96u);
    EXPECT_EQ(img->height, 64u);
    ids.push_back(info.scene_id());
  }
  // The store is bounded: free them again.
  for (const std::string& id : ids) {
    grpc::ClientContext ctx;
    v1::DeleteSceneRequest del;
    del.set_scene_id(id);
    v1::DeleteSceneResponse r;
    EXPECT_TRUE(stub_->DeleteScene(&ctx, del, &r).ok());
  }
}

TEST_F(ServerTest, SceneIdIsTheContentHashAndReuploadIsFree) {
  const std::string path = AssetsDir() + "/BoxTextured/glTF/BoxTextured.gltf";
  std::vector<UploadPart> parts = PartsFromDisk(path);
  std::map<std::string, std::string> hashes;
  for (const UploadPart& p : parts) hashes[p.name] = Sha256Hex(p.bytes.data(), p.bytes.size());
  const std::string expected = SceneId(hashes, "BoxTextured.gltf");

  v1::HasSceneRequest has;
  has.set_scene_id(expected);
  v1::HasSceneResponse hr;
  {
    grpc::ClientContext ctx;
    ASSERT_TRUE(stub_->HasScene(&ctx, has, &hr).ok());
  }
  EXPECT_FALSE(hr.present());

  v1::SceneInfo first, second;
  ASSERT_TRUE(UploadRaw(stub_.get(), parts, &first, "BoxTextured.gltf").ok());
  EXPECT_EQ(first.scene_id(), expected);
  ASSERT_TRUE(UploadRaw(stub_.get(), parts, &second, "BoxTextured.gltf").ok());
  EXPECT_EQ(second.scene_id(), expected);
  EXPECT_EQ(second.load_ms(), first.load_ms()) << "the second upload must not load again";
  {
    grpc::ClientContext ctx;
    ASSERT_TRUE(stub_->HasScene(&ctx, has, &hr).ok());
  }
  EXPECT_TRUE(hr.present());
  EXPECT_EQ(hr.info().counts().triangles(), 12u);

  // A unique prefix works as an id.
  v1::RenderRequest req;
  req.set_scene_id(expected.substr(0, 10));
  req.mutable_settings()->set_width(32);
  req.mutable_settings()->set_height(32);
  v1::Frame f;
  EXPECT_TRUE(Render(req, &f).ok());
  EXPECT_EQ(f.scene_id(), expected);

  v1::ListScenesResponse list;
  {
    grpc::ClientContext ctx;
    ASSERT_TRUE(stub_->ListScenes(&ctx, {}, &list).ok());
  }
  ASSERT_GE(list.scenes_size(), 2);
  EXPECT_EQ(list.scenes(0).scene_id(), "demo");
  int found = 0;
  for (const auto& s : list.scenes()) found += s.scene_id() == expected;
  EXPECT_EQ(found, 1);

  grpc::ClientContext ctx;
  v1::DeleteSceneRequest del;
  del.set_scene_id(expected);
  v1::DeleteSceneResponse dr;
  ASSERT_TRUE(stub_->DeleteScene(&ctx, del, &dr).ok());
  EXPECT_EQ(dr.sessions_still_using(), 0u);
  EXPECT_CODE(Render(req, &f), NOT_FOUND, "scene_id");
}

// --- bad input: the right code, a message naming the culprit, and the server goes on -------

TEST_F(ServerTest, GarbageBytesAreInvalidArgumentNamingTheFile) {
  v1::SceneInfo info;
  std::string garbage(4096, '\0');
  for (size_t i = 0; i < garbage.size(); ++i) garbage[i] = char((i * 2654435761u) >> 13);
  EXPECT_CODE(UploadRaw(stub_.get(), {{"garbage.glb", garbage}}, &info), INVALID_ARGUMENT,
              "garbage.glb");
  EXPECT_CODE(UploadRaw(stub_.get(), {{"garbage.gltf", "{not json"}}, &info), INVALID_ARGUMENT,
              "garbage.gltf");
}

TEST_F(ServerTest, TruncatedGlbIsInvalidArgument) {
  std::vector<UploadPart> parts = PartsFromDisk(AssetsDir() + "/Box/glTF-Binary/Box.glb");
  ASSERT_EQ(parts.size(), 1u);
  parts[0].bytes.resize(parts[0].bytes.size() / 2);
  v1::SceneInfo info;
  EXPECT_CODE(UploadRaw(stub_.get(), parts, &info), INVALID_ARGUMENT, "Box.glb");
}

TEST_F(ServerTest, UrisOutsideTheUploadSetAreRefused) {
  const std::string gltf = R"({"asset":{"version":"2.0"},
    "buffers":[{"uri":"../../etc/passwd","byteLength":4}]})";
  v1::SceneInfo info;
  grpc::Status st = UploadRaw(stub_.get(), {{"escape.gltf", gltf}}, &info);
  EXPECT_CODE(st, INVALID_ARGUMENT, "escape.gltf");
  EXPECT_NE(st.error_message().find("passwd"), std::string::npos) << st.error_message();
  // A manifest may not name such a file either.
  EXPECT_CODE(UploadRaw(stub_.get(), {{"escape.gltf", gltf}, {"../../etc/passwd", "root"}}, &info,
                        "escape.gltf"),
              INVALID_ARGUMENT, "manifest.files[1]");
  EXPECT_CODE(UploadRaw(stub_.get(), {{"/abs/escape.gltf", gltf}}, &info), INVALID_ARGUMENT,
              "manifest.files[0]");
}

TEST_F(ServerTest, MalformedUploadStreamsAreRefused) {
  v1::SceneInfo info;
  // A chunk before any manifest.
  {
    grpc::ClientContext ctx;
    auto w = stub_->UploadScene(&ctx, &info);
    v1::UploadRequest c;
    c.mutable_chunk()->set_data("x");
    w->Write(c);
    w->WritesDone();
    EXPECT_CODE(w->Finish(), INVALID_ARGUMENT, "manifest");
  }
  // Bytes missing at the end.
  {
    grpc::ClientContext ctx;
    auto w = stub_->UploadScene(&ctx, &info);
    v1::UploadRequest m;
    auto* f = m.mutable_manifest()->add_files();
    f->set_name("short.glb");
    f->set_size(100);
    w->Write(m);
    v1::UploadRequest c;
    c.mutable_chunk()->set_data(std::string(10, 'x'));
    w->Write(c);
    w->WritesDone();
    EXPECT_CODE(w->Finish(), INVALID_ARGUMENT, "short.glb");
  }
  // Wrong sha256.
  EXPECT_EQ(UploadRaw(stub_.get(), {{"a.glb", "abc"}}, &info, "", 1 << 20, false).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  {
    grpc::ClientContext ctx;
    auto w = stub_->UploadScene(&ctx, &info);
    v1::UploadRequest m;
    auto* f = m.mutable_manifest()->add_files();
    f->set_name("a.glb");
    f->set_size(3);
    f->set_sha256(std::string(64, '0'));
    w->Write(m);
    v1::UploadRequest c;
    c.mutable_chunk()->set_data("abc");
    w->Write(c);
    w->WritesDone();
    EXPECT_CODE(w->Finish(), DATA_LOSS, "a.glb");
  }
}

TEST_F(ServerTest, OversizeUploadIsResourceExhaustedNamingTheLimit) {
  grpc::ClientContext ctx;
  v1::SceneInfo info;
  auto w = stub_->UploadScene(&ctx, &info);
  v1::UploadRequest m;
  auto* f = m.mutable_manifest()->add_files();
  f->set_name("huge.glb");
  f->set_size(uint64_t(1) << 40);  // 1 TiB declared: refused before any byte is stored
  w->Write(m);
  w->WritesDone();
  EXPECT_CODE(w->Finish(), RESOURCE_EXHAUSTED, "max_upload_bytes");
  // A chunk larger than max_chunk_bytes.
  grpc::ClientContext ctx2;
  auto w2 = stub_->UploadScene(&ctx2, &info);
  v1::UploadRequest m2;
  auto* f2 = m2.mutable_manifest()->add_files();
  f2->set_name("big.glb");
  f2->set_size(3 << 20);
  w2->Write(m2);
  v1::UploadRequest c;
  c.mutable_chunk()->set_data(std::string(2 << 20, 'x'));
  w2->Write(c);
  w2->WritesDone();
  EXPECT_EQ(w2->Finish().error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
}

TEST_F(ServerTest, BadResolutionsCameraAndSceneIds) {
  v1::Frame f;
  EXPECT_CODE(Render(DemoRequest(0, 0), &f), INVALID_ARGUMENT, "settings.width");
  EXPECT_CODE(Render(DemoRequest(100000, 100000), &f), INVALID_ARGUMENT, "settings.width");
  EXPECT_CODE(Render(DemoRequest(64, 0), &f), INVALID_ARGUMENT, "settings.height");

  v1::RenderRequest nan = DemoRequest(64, 64);
  SetLookAt(nan.mutable_camera(), std::nanf(""), 1.0f, 1.0f);
  EXPECT_CODE(Render(nan, &f), INVALID_ARGUMENT, "camera.look_at.eye");
  v1::RenderRequest inf = DemoRequest(64, 64);
  inf.mutable_camera()->set_yfov(INFINITY);
  EXPECT_CODE(Render(inf, &f), INVALID_ARGUMENT, "camera.yfov");
  v1::RenderRequest mat = DemoRequest(64, 64);
  mat.mutable_camera()->mutable_view_matrix()->add_m(1.0f);
  EXPECT_CODE(Render(mat, &f), INVALID_ARGUMENT, "camera.view_matrix");
  v1::RenderRequest cam = DemoRequest(64, 64);
  cam.mutable_camera()->set_scene_camera(7);
  EXPECT_CODE(Render(cam, &f), INVALID_ARGUMENT, "camera.scene_camera");

  v1::RenderRequest unknown = DemoRequest(64, 64);
  unknown.set_scene_id("0123456789abcdef");
  EXPECT_CODE(Render(unknown, &f), NOT_FOUND, "scene_id");
  unknown.set_scene_id("");
  EXPECT_CODE(Render(unknown, &f), INVALID_ARGUMENT, "scene_id");

  v1::RenderRequest enums = DemoRequest(64, 64);
  enums.mutable_settings()->set_aa(static_cast<v1::AaMode>(99));
  EXPECT_CODE(Render(enums, &f), INVALID_ARGUMENT, "settings.aa");

  grpc::ClientContext ctx;
  v1::DeleteSceneRequest del;
  del.set_scene_id("demo");
  v1::DeleteSceneResponse dr;
  EXPECT_EQ(stub_->DeleteScene(&ctx, del, &dr).error_code(), grpc::StatusCode::FAILED_PRECONDITION);
}

TEST_F(ServerTest, ClientLeavingMidUploadLeavesNothingBehind) {
  {
    grpc::ClientContext ctx;
    v1::SceneInfo info;
    auto w = stub_->UploadScene(&ctx, &info);
    v1::UploadRequest m;
    auto* f = m.mutable_manifest()->add_files();
    f->set_name("partial.glb");
    f->set_size(8 << 20);
    ASSERT_TRUE(w->Write(m));
    v1::UploadRequest c;
    c.mutable_chunk()->set_data(std::string(1 << 20, 'x'));
    ASSERT_TRUE(w->Write(c));
    EXPECT_TRUE(WaitFor([](const server::ServerStats& s) { return s.uploads_in_progress == 1; }));
    ctx.TryCancel();
    w->Finish();
  }
  EXPECT_TRUE(WaitFor([](const server::ServerStats& s) { return s.uploads_in_progress == 0; }));
}

// --- streams -------------------------------------------------------------------------------

// 30 camera updates sent as fast as possible: frames come in order, each names the newest
// event it reflects (its camera is that event's camera), and the last reflects event 30.
TEST_F(ServerTest, StreamFramesNameTheNewestEventTheyReflect) {
  grpc::ClientContext ctx;
  std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
  ASSERT_TRUE(rw->Write(OpenEvent("demo", 96, 64)));
  for (uint64_t k = 1; k <= 30; ++k) ASSERT_TRUE(rw->Write(CameraEvent(k)));
  uint64_t last_seq = 0, last_event = 0;
  int frames = 0;
  v1::Frame f;
  while (last_event < 30 && rw->Read(&f)) {
    ++frames;
    EXPECT_GT(f.sequence(), last_seq);
    EXPECT_GE(f.event_id(), last_event);
    EXPECT_LE(f.event_id(), 30u);
    EXPECT_NEAR(f.camera().eye().x(), EyeX(f.event_id()), 1e-4) << "event " << f.event_id();
    EXPECT_EQ(f.width(), 96u);
    EXPECT_EQ(f.profile(), "full");
    EXPECT_FALSE(f.passes().empty());
    last_seq = f.sequence();
    last_event = f.event_id();
  }
  EXPECT_EQ(last_event, 30u);
  EXPECT_LE(frames, 31) << "one frame per change at most";
  rw->WritesDone();
  while (rw->Read(&f)) {
  }
  grpc::Status st = rw->Finish();
  EXPECT_TRUE(st.ok()) << st.error_message();
}

TEST_F(ServerTest, StreamSettingsUpdatesMergeAndBadEventsEndTheStream) {
  grpc::ClientContext ctx;
  std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
  ASSERT_TRUE(rw->Write(OpenEvent("demo", 64, 48)));
  v1::Frame f;
  ASSERT_TRUE(rw->Read(&f));
  v1::ClientEvent e;
  e.set_event_id(1);
  e.mutable_settings()->set_width(80);  // height stays 48
  ASSERT_TRUE(rw->Write(e));
  ASSERT_TRUE(rw->Read(&f));
  EXPECT_EQ(f.width(), 80u);
  EXPECT_EQ(f.height(), 48u);
  EXPECT_EQ(f.event_id(), 1u);
  v1::ClientEvent bad;
  bad.set_event_id(2);
  bad.mutable_settings()->set_tile_size(7);
  rw->Write(bad);
  while (rw->Read(&f)) {
  }
  EXPECT_CODE(rw->Finish(), INVALID_ARGUMENT, "settings.tile_size");

  grpc::ClientContext ctx2;
  std::unique_ptr<StreamRW> rw2 = stub_->Stream(&ctx2);
  rw2->Write(CameraEvent(1));  // no open
  while (rw2->Read(&f)) {
  }
  EXPECT_CODE(rw2->Finish(), INVALID_ARGUMENT, "open");

  grpc::ClientContext ctx3;
  std::unique_ptr<StreamRW> rw3 = stub_->Stream(&ctx3);
  rw3->Write(OpenEvent("no-such-scene", 64, 64));
  while (rw3->Read(&f)) {
  }
  EXPECT_CODE(rw3->Finish(), NOT_FOUND, "scene_id");
}

// TAA on a resting camera keeps refining: after the open (and after each change) 16 full
// frames arrive, each closer to the converged picture, and then nothing until a change. The
// client half-closes after the first change's frames; the stream then ends OK.
TEST_F(ServerTest, TaaStreamConvergesWhileTheCameraRests) {
  grpc::ClientContext ctx;
  std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
  v1::ClientEvent open = OpenEvent("demo", 64, 48);
  open.mutable_open()->mutable_settings()->set_aa(v1::AA_TAA);
  ASSERT_TRUE(rw->Write(open));
  std::vector<std::string> frames;
  v1::Frame f;
  for (int i = 0; i < 16; ++i) {
    ASSERT_TRUE(rw->Read(&f)) << "frame " << i;
    EXPECT_EQ(f.event_id(), 0u);
    frames.push_back(f.data());
  }
  EXPECT_NE(frames.front(), frames.back()) << "the resting frames did not change";
  // Nothing more comes while nothing changes: a camera event's frame is the next one.
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ASSERT_TRUE(rw->Write(CameraEvent(1)));
  ASSERT_TRUE(rw->Read(&f));
  EXPECT_EQ(f.event_id(), 1u) << "a frame came without a change";
  rw->WritesDone();
  while (rw->Read(&f)) {
  }
  EXPECT_TRUE(rw->Finish().ok());
}

// A stream's renderer view (here its TAA history, a pair of frame-sized images) is given back
// when the stream ends, not kept with the renderer until 64 other views push it out.
TEST_F(ServerTest, AnEndedStreamGivesBackItsView) {
  auto info = [&] {
    grpc::ClientContext ctx;
    v1::ServerInfo i;
    EXPECT_TRUE(stub_->GetServerInfo(&ctx, {}, &i).ok());
    return i;
  };
  auto device_bytes = [&] { return info().device_memory_bytes(); };
  // A session ends just after its call does: wait until none is open.
  auto settled = [&] {
    for (int i = 0; i < 250 && info().active_sessions() != 0; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    EXPECT_EQ(info().active_sessions(), 0u);
    return device_bytes();
  };
  // A size no other test uses, so the frame targets are this test's too; a first stream makes
  // them (they stay in the pool), the second one's history is what must go.
  auto run = [&] {
    grpc::ClientContext ctx;
    std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
    v1::ClientEvent open = OpenEvent("demo", 200, 150);
    open.mutable_open()->mutable_settings()->set_aa(v1::AA_TAA);
    EXPECT_TRUE(rw->Write(open));
    v1::Frame f;
    EXPECT_TRUE(rw->Read(&f));
    const uint64_t during = device_bytes();
    rw->WritesDone();
    while (rw->Read(&f)) {
    }
    EXPECT_TRUE(rw->Finish().ok());
    return during;
  };
  run();
  const uint64_t before = settled();
  const uint64_t during = run();
  EXPECT_GT(during, before) << "the stream's view holds no device memory: the test shows nothing";
  EXPECT_EQ(settled(), before) << "during the stream: " << during;
}

// A reader much slower than the render rate gets fewer frames, each recent, while the frames
// the server holds for it stay bounded.
TEST_F(ServerTest, SlowReaderGetsRecentFramesAndServerMemoryStaysBounded) {
  auto slow_stub = Connect(server_->address(), {.small_window = true});
  grpc::ClientContext ctx;
  std::unique_ptr<StreamRW> rw = slow_stub->Stream(&ctx);
  ASSERT_TRUE(rw->Write(OpenEvent("demo", 320, 240)));
  std::atomic<uint64_t> sent{0};
  std::atomic<bool> stop{false};
  std::thread writer([&] {
    for (uint64_t k = 1; !stop; ++k) {
      if (!rw->Write(CameraEvent(k))) break;
      sent = k;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  });
  v1::Frame f;
  uint64_t max_pending = 0, max_frame = 0, min_frame = UINT64_MAX;
  int frames = 0;
  std::vector<uint64_t> lag;
  const auto t_end = std::chrono::steady_clock::now() + std::chrono::seconds(4);
  while (std::chrono::steady_clock::now() < t_end && rw->Read(&f)) {
    ++frames;
    max_frame = std::max<uint64_t>(max_frame, f.data().size());
    min_frame = std::min<uint64_t>(min_frame, f.data().size());
    lag.push_back(sent - std::min<uint64_t>(sent, f.event_id()));
    for (int i = 0; i < 4; ++i) {  // a slow reader: 400 ms per frame
      max_pending = std::max(max_pending, server_->stats().pending_frame_bytes);
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }
  stop = true;
  writer.join();
  const uint64_t total_sent = sent;
  rw->WritesDone();
  ctx.TryCancel();
  rw->Finish();
  ASSERT_GE(frames, 5);
  EXPECT_LT(uint64_t(frames), total_sent / 4) << "a slow reader must get fewer frames";
  // At most the frame being written plus the newest one waiting. Those two are frames this
  // reader mostly never reads (it sees one in ~80), so each may be larger than the largest it
  // read by as much as the frames it read differ among themselves: with the largest read alone
  // as the bound, two held frames 295 bytes over it failed under ASan's timing. A third frame
  // held would still be over this (frames read here: 19.8-22.6 KB, so the bound is 51.9 KB
  // against ~63 KB for three).
  const uint64_t held_bound = 2 * (max_frame + (max_frame - min_frame)) + 1024;
  EXPECT_LE(max_pending, held_bound) << "frames read " << min_frame << ".." << max_frame;
  // Recent: a frame reflects events at most ~2 read periods older than the newest sent (the
  // frame being written and the newest one waiting: 2 x 400 ms / 5 ms = 160 events), plus what
  // the transport holds on the way: HTTP/2 flow control lets up to its 64 KiB window of frames
  // sit in the client's buffers, each a read period (80 events) old by the time it is read.
  std::sort(lag.begin() + 2, lag.end());
  const uint64_t in_window = (65535 + min_frame - 1) / std::max<uint64_t>(min_frame, 1);
  const uint64_t bound = (2 + in_window) * 80 + 20;
  std::printf("slow reader: median lag %llu events (bound %llu), frames %llu..%llu bytes\n",
              (unsigned long long)lag[2 + (lag.size() - 2) / 2], (unsigned long long)bound,
              (unsigned long long)min_frame, (unsigned long long)max_frame);
  EXPECT_LT(lag[2 + (lag.size() - 2) / 2], bound)
      << "median event lag; frames of " << min_frame << ".." << max_frame << " bytes";
  EXPECT_TRUE(WaitFor([](const server::ServerStats& s) { return s.sessions == 0; }));
}

TEST_F(ServerTest, TwoClientsStreamingAtOnceBothProgress) {
  auto run = [&](int* frames_out) {
    auto stub = Connect(server_->address());
    grpc::ClientContext ctx;
    std::unique_ptr<StreamRW> rw = stub->Stream(&ctx);
    rw->Write(OpenEvent("demo", 128, 96));
    v1::Frame f;
    int frames = 0;
    for (uint64_t k = 1; k <= 12 && rw->Read(&f); ++k) {
      ++frames;
      rw->Write(CameraEvent(k));  // ping-pong: a new view after each frame
    }
    rw->WritesDone();
    while (rw->Read(&f)) ++frames;
    EXPECT_TRUE(rw->Finish().ok());
    *frames_out = frames;
  };
  int a = 0, b = 0;
  std::thread ta(run, &a), tb(run, &b);
  ta.join();
  tb.join();
  EXPECT_GE(a, 12);
  EXPECT_GE(b, 12);
}

TEST_F(ServerTest, ContinuousStreamRendersWithoutEvents) {
  grpc::ClientContext ctx;
  std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
  ASSERT_TRUE(rw->Write(OpenEvent("demo", 64, 48, /*fps=*/30.0f)));
  v1::Frame f;
  uint64_t last = 0;
  for (int i = 0; i < 5; ++i) {
    ASSERT_TRUE(rw->Read(&f));
    EXPECT_GT(f.sequence(), last);
    last = f.sequence();
    EXPECT_EQ(f.event_id(), 0u);
  }
  rw->WritesDone();
  while (rw->Read(&f)) {
  }
  EXPECT_TRUE(rw->Finish().ok());
}

// Sends settings `change` as event `id` and returns the first frame that reflects it.
v1::Frame ChangeSettings(StreamRW* rw, uint64_t id, const v1::RenderSettings& change) {
  v1::ClientEvent e;
  e.set_event_id(id);
  *e.mutable_settings() = change;
  v1::Frame f;
  EXPECT_TRUE(rw->Write(e));
  EXPECT_TRUE(ReadUntilEvent(rw, id, &f)) << "the stream ended";
  return f;
}

// play: the session renders on its own (target_fps 0) and each frame's settings carry the scene
// time it shows, advancing with the wall clock; a pause holds the time, an event's scene_time
// restarts the clock from there, and without loop play stops at the animation's end. An unknown
// animation ends the stream naming the field.
TEST_F(ServerTest, APlayingStreamAdvancesItsSceneTimeWithTheClock) {
  v1::SceneInfo info;
  ASSERT_TRUE(UploadFromDisk(stub_.get(),
                             std::string(TESSERA_ANIMATED_DIR) + "/skinned_cylinder.gltf", &info)
                  .ok());
  // One frame of the posed scene at the stream's size first, so that the stream's first frames
  // do not also create the skinning's pipelines and the view's targets: under ASan with
  // validation, beside another test on a 2-core machine, that once took longer than the
  // animation (2 frames in 3.5 s, the second already past the end with play off).
  v1::RenderRequest warm;
  warm.set_scene_id(info.scene_id());
  warm.mutable_settings()->set_width(64);
  warm.mutable_settings()->set_height(48);
  warm.mutable_settings()->set_animation("bend");
  v1::Frame warm_frame;
  const grpc::Status warm_status = Render(warm, &warm_frame);
  ASSERT_TRUE(warm_status.ok()) << warm_status.error_message();
  grpc::ClientContext ctx;
  std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
  v1::ClientEvent open = OpenEvent(info.scene_id(), 64, 48);
  v1::RenderSettings& s = *open.mutable_open()->mutable_settings();
  s.set_animation("bend");
  s.set_play(true);
  s.set_loop(false);  // the time grows without wrapping (the animation lasts 2 s)
  ASSERT_TRUE(rw->Write(open));
  v1::Frame f;
  std::vector<float> times;
  std::set<std::string> images;
  const auto t0 = std::chrono::steady_clock::now();
  // Up to 6 playing frames; a machine slow enough to reach the end (play off, at 2 s) first
  // gives fewer, and 2 still show the time advancing.
  while (times.size() < 6) {
    ASSERT_TRUE(rw->Read(&f)) << "frames keep coming without events while playing";
    if (!f.settings().play()) {
      EXPECT_EQ(f.settings().scene_time(), 2.0f) << "play stopped before the end";
      break;
    }
    times.push_back(f.settings().scene_time());
    images.insert(f.data());
  }
  ASSERT_GE(times.size(), 2u) << "the animation ended before a second frame";
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (size_t i = 1; i < times.size(); ++i) EXPECT_GE(times[i], times[i - 1]);
  EXPECT_GT(times.back(), times.front());
  EXPECT_LE(times.back() - times.front(), elapsed + 0.05) << "no faster than the clock";
  EXPECT_GT(images.size(), 1u) << "the cylinder moves";

  // Pause: the time stays where it got to, and frames come only on change again.
  v1::RenderSettings change;
  change.set_play(false);
  f = ChangeSettings(rw.get(), 1, change);
  EXPECT_FALSE(f.settings().play());
  const float paused = f.settings().scene_time();
  EXPECT_GE(paused, times.back());
  // A set time while paused is shown as given; play then runs on from it.
  change.Clear();
  change.set_scene_time(1.0f);
  f = ChangeSettings(rw.get(), 2, change);
  EXPECT_EQ(f.settings().scene_time(), 1.0f);
  change.Clear();
  change.set_play(true);
  f = ChangeSettings(rw.get(), 3, change);
  EXPECT_GE(f.settings().scene_time(), 1.0f);
  EXPECT_LT(f.settings().scene_time(), 1.0f + 5.0f);
  // Without loop, play stops at the end (2 s): that frame shows the end with play off.
  while (f.settings().play()) ASSERT_TRUE(rw->Read(&f));
  EXPECT_EQ(f.settings().scene_time(), 2.0f);

  v1::ClientEvent bad;
  bad.set_event_id(4);
  bad.mutable_settings()->set_animation("walk");
  ASSERT_TRUE(rw->Write(bad));
  while (rw->Read(&f)) {
  }
  const grpc::Status st = rw->Finish();
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("settings.animation"), std::string::npos) << st.error_message();
}

// Turning loop off while a looping animation plays goes on from the time shown, not from where
// the clock would be without wrapping (which would jump to the end and stop).
TEST_F(ServerTest, ALoopTurnedOffWhilePlayingGoesOnFromTheTimeShown) {
  v1::SceneInfo info;
  ASSERT_TRUE(
      UploadFromDisk(stub_.get(), std::string(TESSERA_ANIMATED_DIR) + "/trs_nodes.gltf", &info)
          .ok());
  grpc::ClientContext ctx;
  std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
  v1::ClientEvent open = OpenEvent(info.scene_id(), 32, 24);
  open.mutable_open()->mutable_settings()->set_animation("move");  // 1 s long
  open.mutable_open()->mutable_settings()->set_play(true);
  ASSERT_TRUE(rw->Write(open));
  v1::Frame f;
  const auto t0 = std::chrono::steady_clock::now();
  do {
    ASSERT_TRUE(rw->Read(&f));
  } while (std::chrono::steady_clock::now() - t0 < std::chrono::milliseconds(1400));
  const float before = f.settings().scene_time();
  EXPECT_LT(before, 1.0f) << "looping";
  v1::RenderSettings unloop;
  unloop.set_loop(false);
  f = ChangeSettings(rw.get(), 1, unloop);
  EXPECT_FALSE(f.settings().loop());
  EXPECT_LT(std::abs(f.settings().scene_time() - before), 0.3f)
      << "from " << before << " s to " << f.settings().scene_time() << " s";
  EXPECT_TRUE(CloseStream(rw.get()).ok());
}

TEST_F(ServerTest, DeletedSceneStaysUntilItsSessionEnds) {
  v1::SceneInfo info;
  ASSERT_TRUE(
      UploadRaw(stub_.get(), PartsFromDisk(AssetsDir() + "/Box/glTF-Binary/Box.glb"), &info).ok());
  const uint32_t scenes_before = server_->stats().scenes;
  grpc::ClientContext ctx;
  std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
  ASSERT_TRUE(rw->Write(OpenEvent(info.scene_id(), 64, 48)));
  v1::Frame f;
  ASSERT_TRUE(rw->Read(&f));
  {
    grpc::ClientContext dctx;
    v1::DeleteSceneRequest del;
    del.set_scene_id(info.scene_id());
    v1::DeleteSceneResponse dr;
    ASSERT_TRUE(stub_->DeleteScene(&dctx, del, &dr).ok());
    EXPECT_EQ(dr.sessions_still_using(), 1u);
  }
  v1::RenderRequest req;
  req.set_scene_id(info.scene_id());
  EXPECT_EQ(Render(req, &f).error_code(), grpc::StatusCode::NOT_FOUND);
  // The session still renders it.
  ASSERT_TRUE(rw->Write(CameraEvent(1)));
  ASSERT_TRUE(rw->Read(&f));
  EXPECT_EQ(f.event_id(), 1u);
  EXPECT_EQ(server_->stats().scenes, scenes_before);
  rw->WritesDone();
  while (rw->Read(&f)) {
  }
  EXPECT_TRUE(rw->Finish().ok());
  EXPECT_TRUE(WaitFor([&](const server::ServerStats& s) { return s.scenes == scenes_before - 1; }));
}

TEST_F(ServerTest, ClientLeavingMidStreamLeavesNothingBehind) {
  {
    grpc::ClientContext ctx;
    std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
    ASSERT_TRUE(rw->Write(OpenEvent("demo", 64, 48, 60.0f)));
    v1::Frame f;
    ASSERT_TRUE(rw->Read(&f));
    ctx.TryCancel();
    rw->Finish();
  }
  EXPECT_TRUE(WaitFor(
      [](const server::ServerStats& s) { return s.sessions == 0 && s.pending_frame_bytes == 0; }));
}

TEST_F(ServerTest, SessionLimitIsResourceExhausted) {
  std::vector<std::unique_ptr<grpc::ClientContext>> ctxs;
  std::vector<std::unique_ptr<StreamRW>> streams;
  v1::Frame f;
  for (int i = 0; i < 8; ++i) {  // the fixture's max_sessions
    ctxs.push_back(std::make_unique<grpc::ClientContext>());
    streams.push_back(stub_->Stream(ctxs.back().get()));
    ASSERT_TRUE(streams.back()->Write(OpenEvent("demo", 16, 16)));
    ASSERT_TRUE(streams.back()->Read(&f));
  }
  grpc::ClientContext ctx;
  auto extra = stub_->Stream(&ctx);
  extra->Write(OpenEvent("demo", 16, 16));
  while (extra->Read(&f)) {
  }
  EXPECT_CODE(extra->Finish(), RESOURCE_EXHAUSTED, "max_sessions");
  for (auto& s : streams) {
    s->WritesDone();
    while (s->Read(&f)) {
    }
    EXPECT_TRUE(s->Finish().ok());
  }
  EXPECT_TRUE(WaitFor([](const server::ServerStats& s) { return s.sessions == 0; }));
}

// --- import limits ---------------------------------------------------------------------------

// Limits set on the server are reported by GetServerInfo and enforced on uploads with
// RESOURCE_EXHAUSTED naming them; the server goes on serving.
TEST(ImportLimits, ReportedAndEnforcedNamingTheLimit) {
  ServerOptions o = BaseOptions();
  ASSERT_EQ(ParseImportLimits("max_nodes=1,max_image_dimension=128", &o.import_limits), "");
  auto server = StartServer(o);
  ASSERT_NE(server, nullptr);
  auto stub = Connect(server->address());
  grpc::ClientContext ctx;
  v1::ServerInfo info;
  ASSERT_TRUE(stub->GetServerInfo(&ctx, {}, &info).ok());
  const v1::ImportLimits& l = info.limits().scene_import();
  EXPECT_EQ(l.max_nodes(), 1u);
  EXPECT_EQ(l.max_image_dimension(), 128u);
  EXPECT_EQ(l.max_json_depth(), ImportLimits{}.max_json_depth);
  EXPECT_EQ(l.max_total_image_bytes(), ImportLimits{}.max_total_image_bytes);
  EXPECT_EQ(info.limits().max_scene_device_bytes(), o.max_scene_device_bytes);
  EXPECT_GT(info.device_memory_bytes(), 0u);  // the demo scene and the renderer's own buffers

  v1::SceneInfo scene;
  EXPECT_CODE(UploadFromDisk(stub.get(), AssetsDir() + "/Box/glTF/Box.gltf", &scene),
              RESOURCE_EXHAUSTED, "Box.gltf: nodes: 2 nodes exceed the max_nodes limit (1)");
  EXPECT_CODE(UploadFromDisk(stub.get(), AssetsDir() + "/SimpleMeshes/glTF/SimpleMeshes.gltf",
                             &scene),
              RESOURCE_EXHAUSTED, "max_nodes limit (1)");
  // One node, but a 256x256 texture: the image limit.
  std::vector<UploadPart> textured =
      PartsFromDisk(AssetsDir() + "/BoxTextured/glTF/BoxTextured.gltf");
  for (UploadPart& p : textured) {
    if (p.name != "BoxTextured.gltf") continue;
    nlohmann::json j = nlohmann::json::parse(p.bytes);
    j["nodes"] = {j["nodes"][1]};
    j["scenes"][0]["nodes"] = {0};
    p.bytes = j.dump();
  }
  EXPECT_CODE(UploadRaw(stub.get(), textured, &scene, "BoxTextured.gltf"), RESOURCE_EXHAUSTED,
              "256x256 exceeds the max_image_dimension limit (128)");
  // A scene's device memory, refused from the CPU estimate before the upload.
  ServerOptions small = BaseOptions();
  small.max_scene_device_bytes = 1000;
  auto server2 = StartServer(small);
  ASSERT_NE(server2, nullptr);
  auto stub2 = Connect(server2->address());
  EXPECT_CODE(UploadFromDisk(stub2.get(), AssetsDir() + "/Box/glTF/Box.gltf", &scene),
              RESOURCE_EXHAUSTED, "over the max_scene_device_bytes limit (1000)");
  EXPECT_EQ(server2->stats().scenes, 1u);  // only the demo scene
  grpc::ClientContext rctx;
  v1::Frame f;
  EXPECT_TRUE(stub->Render(&rctx, DemoRequest(32, 24), &f).ok());
}

// --- the tesserad binary: SIGTERM during a stream ------------------------------------------

TEST(TesseradProcess, SigtermDuringAStreamEndsItWithUnavailableAndExitsZero) {
  const std::string port_file =
      (fs::temp_directory_path() / absl::StrCat("tesserad_port_", getpid())).string();
  const auto [pid, port] = SpawnTesserad(port_file);
  ASSERT_GT(pid, 0);
  ASSERT_GT(port, 0) << "tesserad did not start";
  auto stub = Connect(absl::StrCat("127.0.0.1:", port));
  grpc::ClientContext ctx;
  std::unique_ptr<StreamRW> rw = stub->Stream(&ctx);
  ASSERT_TRUE(rw->Write(OpenEvent("demo", 64, 48, /*fps=*/30.0f)));
  v1::Frame f;
  ASSERT_TRUE(rw->Read(&f));
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_EQ(kill(pid, SIGTERM), 0);
  while (rw->Read(&f)) {
  }
  grpc::Status st = rw->Finish();
  EXPECT_EQ(st.error_code(), grpc::StatusCode::UNAVAILABLE) << st.error_message();
  int status = 0;
  pid_t done = 0;
  for (int i = 0; i < 100 && done == 0; ++i) {
    done = waitpid(pid, &status, WNOHANG);
    if (done == 0) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  if (done == 0) {
    kill(pid, SIGKILL);
    waitpid(pid, &status, 0);
    FAIL() << "tesserad did not exit within 10 s of SIGTERM";
  }
  EXPECT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(5));
  fs::remove(port_file);
}

}  // namespace
}  // namespace tessera
