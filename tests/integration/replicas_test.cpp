// Replicas: in-process tesserads sharing one --scene_store_dir (a scene uploaded through one
// renders, streams and serves farm frames on another; a delete or a damaged archive is seen by
// all), and readiness (grpc.health.v1 "tessera.v1.RenderService") following the session load.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "server/server.h"
#include "tessera/v1/render_service.grpc.pb.h"
#include "tests/integration/client_helpers.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;
using namespace test_client;  // client_helpers.h

v1::ServerInfo Info(v1::RenderService::Stub* stub) {
  grpc::ClientContext ctx;
  v1::ServerInfo info;
  grpc::Status st = stub->GetServerInfo(&ctx, v1::GetServerInfoRequest(), &info);
  EXPECT_TRUE(st.ok()) << st.error_message();
  return info;
}

bool Has(v1::RenderService::Stub* stub, const std::string& id, v1::HasSceneResponse* r) {
  grpc::ClientContext ctx;
  v1::HasSceneRequest req;
  req.set_scene_id(id);
  grpc::Status st = stub->HasScene(&ctx, req, r);
  EXPECT_TRUE(st.ok()) << st.error_message();
  return r->present();
}

grpc::Status RenderScene(v1::RenderService::Stub* stub, const std::string& id, v1::Frame* f) {
  v1::RenderRequest req = DemoRequest(64, 48);
  req.set_scene_id(id);
  grpc::ClientContext ctx;
  return stub->Render(&ctx, req, f);
}

class SharedStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string tmpl = (fs::temp_directory_path() / "tessera_replicas_XXXXXX").string();
    ASSERT_NE(mkdtemp(tmpl.data()), nullptr);
    root_ = tmpl;
  }
  void TearDown() override {
    for (auto& s : servers_) {
      s->Shutdown();
      EXPECT_EQ(s->stats().validation_messages, 0u);
    }
    servers_.clear();
    fs::remove_all(root_);
  }

  // A replica on the shared store; its stub.
  std::unique_ptr<v1::RenderService::Stub> Replica() {
    server::ServerOptions o = BaseOptions();
    o.scene_store_dir = root_ + "/store";
    o.load_demo_scene = false;
    servers_.push_back(StartServer(o));
    if (!servers_.back()) return nullptr;
    return Connect(servers_.back()->address());
  }

  std::string Upload(v1::RenderService::Stub* stub, const std::string& asset) {
    v1::SceneInfo info;
    grpc::Status st = UploadFromDisk(stub, AssetsDir() + "/" + asset, &info);
    EXPECT_TRUE(st.ok()) << st.error_message();
    return info.scene_id();
  }

  std::string root_;
  std::vector<std::unique_ptr<server::Server>> servers_;
};

TEST_F(SharedStoreTest, ASceneUploadedThroughOneReplicaRendersStreamsAndServesJobsOnAnother) {
  auto a = Replica(), b = Replica();
  ASSERT_TRUE(a && b);
  EXPECT_TRUE(Info(a.get()).scene_store());
  const std::string id = Upload(a.get(), "Box/glTF/Box.gltf");
  ASSERT_EQ(id.size(), 64u);
  EXPECT_TRUE(fs::is_directory(root_ + "/store/" + id));

  // B has not loaded it, but its store has it.
  v1::HasSceneResponse has;
  EXPECT_TRUE(Has(b.get(), id, &has));
  EXPECT_FALSE(has.has_info());
  EXPECT_EQ(Info(b.get()).scenes_loaded(), 0u);

  // A stream opened on B loads it and gets frames.
  {
    grpc::ClientContext ctx;
    auto rw = b->Stream(&ctx);
    ASSERT_TRUE(rw->Write(OpenEvent(id, 64, 48)));
    v1::Frame f;
    ASSERT_TRUE(rw->Read(&f));
    EXPECT_EQ(f.scene_id(), id);
    EXPECT_EQ(f.width(), 64u);
    EXPECT_GT(f.stats().triangles_submitted(), 0u);
    grpc::Status st = CloseStream(rw.get());
    EXPECT_TRUE(st.ok()) << st.error_message();
  }
  EXPECT_EQ(Info(b.get()).scenes_loaded(), 1u);

  // A Render and a farm frame on a third replica, each loading it on first use.
  auto c = Replica();
  v1::Frame f;
  grpc::Status st = RenderScene(c.get(), id, &f);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_GT(f.data().size(), 0u);
  auto d = Replica();
  v1::RenderJobFrameRequest job;
  job.mutable_spec()->set_name("shot");
  job.mutable_spec()->set_scene_id(id);
  job.mutable_spec()->mutable_settings()->set_width(48);
  job.mutable_spec()->mutable_settings()->set_height(32);
  job.mutable_spec()->mutable_frames()->set_last(0);
  job.mutable_spec()->mutable_list()->add_cameras();
  job.set_frame(0);
  grpc::ClientContext jctx;
  v1::Frame jf;
  st = d->RenderJobFrame(&jctx, job, &jf);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(jf.width(), 48u);
}

TEST_F(SharedStoreTest, ADeleteReachesEveryReplicaThatHasNotLoadedTheScene) {
  auto a = Replica(), b = Replica();
  const std::string id = Upload(a.get(), "Box/glTF/Box.gltf");
  grpc::ClientContext ctx;
  v1::DeleteSceneRequest req;
  req.set_scene_id(id.substr(0, 12));  // a prefix of a scene loaded on A
  v1::DeleteSceneResponse resp;
  grpc::Status st = a->DeleteScene(&ctx, req, &resp);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_FALSE(fs::exists(root_ + "/store/" + id));
  v1::HasSceneResponse has;
  EXPECT_FALSE(Has(b.get(), id, &has));
  v1::Frame f;
  EXPECT_EQ(RenderScene(b.get(), id, &f).error_code(), grpc::StatusCode::NOT_FOUND);

  // A scene only in the store (not loaded on the replica asked) is deleted by its full id.
  const std::string id2 = Upload(a.get(), "BoxTextured/glTF/BoxTextured.gltf");
  grpc::ClientContext ctx2;
  req.set_scene_id(id2);
  st = b->DeleteScene(&ctx2, req, &resp);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_FALSE(Has(b.get(), id2, &has));
}

TEST_F(SharedStoreTest, ADamagedSceneIsDataLossNamingTheStoreAndAnUploadRepairsIt) {
  auto a = Replica(), b = Replica();
  const std::string id = Upload(a.get(), "Box/glTF/Box.gltf");
  {
    std::fstream bin(root_ + "/store/" + id + "/files/Box0.bin",
                     std::ios::in | std::ios::out | std::ios::binary);
    ASSERT_TRUE(bin.good());
    bin.seekp(100);
    bin.put('\x7f');
  }
  v1::Frame f;
  grpc::Status st = RenderScene(b.get(), id, &f);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::DATA_LOSS);
  EXPECT_NE(st.error_message().find("scene_id: scene_store_dir: scene " + id),
            std::string::npos)
      << st.error_message();
  // Gone from the store: HasScene says so, and the client's upload writes it again.
  v1::HasSceneResponse has;
  EXPECT_FALSE(Has(b.get(), id, &has));
  EXPECT_EQ(Upload(b.get(), "Box/glTF/Box.gltf"), id);
  auto c = Replica();
  st = RenderScene(c.get(), id, &f);
  EXPECT_TRUE(st.ok()) << st.error_message();
}

TEST(ReadinessTest, FollowsTheSessionLoadWhileLivenessStaysServing) {
  server::ServerOptions o = BaseOptions();
  o.max_sessions = 1;
  std::unique_ptr<server::Server> server = StartServer(o);
  ASSERT_NE(server, nullptr);
  auto stub = Connect(server->address());
  const std::string ready = server::kReadinessService;
  EXPECT_EQ(HealthStatus(server->address(), ready), 1);
  EXPECT_EQ(HealthStatus(server->address(), ""), 1);
  EXPECT_TRUE(Info(stub.get()).accepting_sessions());
  EXPECT_EQ(ParseMetrics(server->MetricsText()).at("tessera_accepting_sessions"), 1.0);
  {
    grpc::ClientContext ctx;
    auto rw = stub->Stream(&ctx);
    ASSERT_TRUE(rw->Write(OpenEvent("demo", 32, 24)));
    v1::Frame f;
    ASSERT_TRUE(rw->Read(&f));
    // Full: readiness drops within the health check's period (250 ms), liveness does not.
    EXPECT_FALSE(Info(stub.get()).accepting_sessions());
    bool dropped = false;
    for (int i = 0; i < 100 && !dropped; ++i) {
      dropped = HealthStatus(server->address(), ready) == 2;
      if (!dropped) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    EXPECT_TRUE(dropped);
    EXPECT_EQ(HealthStatus(server->address(), ""), 1);
    EXPECT_EQ(ParseMetrics(server->MetricsText()).at("tessera_accepting_sessions"), 0.0);
    grpc::Status st = CloseStream(rw.get());
    EXPECT_TRUE(st.ok()) << st.error_message();
  }
  bool back = false;
  for (int i = 0; i < 100 && !back; ++i) {
    back = HealthStatus(server->address(), ready) == 1;
    if (!back) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_TRUE(back);
  EXPECT_TRUE(Info(stub.get()).accepting_sessions());
  server->Shutdown();
  EXPECT_EQ(server->stats().validation_messages, 0u);
}

}  // namespace
}  // namespace tessera
