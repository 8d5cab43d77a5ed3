// Render-farm jobs against an in-process tesserad: submit, watch, fetch; frames identical to
// RenderJobFrame's and independent of what was rendered before; every bad spec refused naming
// its field; cancel, delete, the max_jobs limit, SERVER_DIR output; and a restart that resumes
// an unfinished job (with its uploaded scene) without redoing a finished frame.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "renderer/image_io.h"
#include "server/jobs.h"
#include "server/server.h"
#include "common/scene_id.h"
#include "tessera/v1/render_service.grpc.pb.h"
#include "tests/integration/client_helpers.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;
using server::Server;
using server::ServerOptions;
using namespace test_client;  // client_helpers.h

// A fresh directory under the test's temp dir, removed at the end of the test.
class TempDir {
 public:
  TempDir() {
    std::string templ = (fs::path(::testing::TempDir()) / "tessera-job-XXXXXX").string();
    path_ = ::mkdtemp(templ.data()) ? templ : "";
  }
  ~TempDir() {
    std::error_code ec;
    if (!path_.empty()) fs::remove_all(path_, ec);
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

// An orbit of `n` frames at w x h (explicit cameras: the job and the test agree on them).
v1::JobSpec OrbitSpec(const std::string& scene, uint32_t n, uint32_t w, uint32_t h) {
  v1::JobSpec spec;
  spec.set_name("orbit");
  spec.set_scene_id(scene);
  spec.mutable_settings()->set_width(w);
  spec.mutable_settings()->set_height(h);
  spec.mutable_frames()->set_first(0);
  spec.mutable_frames()->set_last(n - 1);
  spec.set_encoding(v1::IMAGE_PNG);
  for (uint32_t i = 0; i < n; ++i) OrbitEye(i, spec.mutable_list()->add_cameras());
  return spec;
}

grpc::Status Submit(v1::RenderService::Stub* stub, const v1::JobSpec& spec, v1::Job* job) {
  grpc::ClientContext ctx;
  v1::SubmitJobRequest req;
  *req.mutable_spec() = spec;
  return stub->SubmitJob(&ctx, req, job);
}

struct Watched {
  grpc::Status status;
  std::vector<v1::JobProgress> events;
};

Watched WatchToEnd(v1::RenderService::Stub* stub, const std::string& id) {
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(120));
  v1::WatchJobRequest req;
  req.set_job_id(id);
  auto reader = stub->WatchJob(&ctx, req);
  Watched w;
  v1::JobProgress p;
  while (reader->Read(&p)) w.events.push_back(p);
  w.status = reader->Finish();
  return w;
}

std::map<uint32_t, v1::JobFrame> FetchAll(v1::RenderService::Stub* stub, const std::string& id,
                                          grpc::Status* status,
                                          const std::vector<uint32_t>& frames = {}) {
  grpc::ClientContext ctx;
  v1::FetchJobFramesRequest req;
  req.set_job_id(id);
  for (uint32_t f : frames) req.add_frames(f);
  auto reader = stub->FetchJobFrames(&ctx, req);
  std::map<uint32_t, v1::JobFrame> out;
  v1::JobFrame f;
  while (reader->Read(&f)) out[f.frame()] = f;
  *status = reader->Finish();
  return out;
}

absl::StatusOr<v1::Job> GetJob(v1::RenderService::Stub* stub, const std::string& id) {
  grpc::ClientContext ctx;
  v1::ListJobsResponse list;
  grpc::Status st = stub->ListJobs(&ctx, v1::ListJobsRequest(), &list);
  if (!st.ok()) return absl::InternalError(st.error_message());
  for (const v1::Job& j : list.jobs())
    if (j.job_id() == id) return j;
  return absl::NotFoundError(id);
}

// Polls ListJobs until `pred(job)` (bounded).
template <typename Pred>
v1::Job WaitJob(v1::RenderService::Stub* stub, const std::string& id, Pred pred, int ms = 60000) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(ms);
  absl::StatusOr<v1::Job> j = GetJob(stub, id);
  while (std::chrono::steady_clock::now() < end && (!j.ok() || !pred(*j))) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    j = GetJob(stub, id);
  }
  return j.ok() ? *j : v1::Job();
}

grpc::Status RenderJobFrame(v1::RenderService::Stub* stub, const v1::JobSpec& spec,
                            uint32_t frame, v1::Frame* out) {
  grpc::ClientContext ctx;
  v1::RenderJobFrameRequest req;
  *req.mutable_spec() = spec;
  req.set_frame(frame);
  return stub->RenderJobFrame(&ctx, req, out);
}

std::vector<std::string> Lines(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> out;
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

class JobTest : public ::testing::Test {
 protected:
  void Start(ServerOptions o) {
    server_ = StartServer(o);
    ASSERT_NE(server_, nullptr);
    stub_ = Connect(server_->address());
  }
  void TearDown() override {
    if (!server_) return;
    server_->Shutdown();
    EXPECT_EQ(server_->stats().validation_messages, 0u);
  }
  TempDir state_;
  std::unique_ptr<Server> server_;
  std::unique_ptr<v1::RenderService::Stub> stub_;
};

TEST_F(JobTest, SubmitWatchFetchAndTheSamePixelsAsRenderJobFrame) {
  ServerOptions o = BaseOptions();
  o.state_dir = state_.path();
  Start(o);
  const v1::JobSpec spec = OrbitSpec("demo", 6, 96, 64);
  v1::Job job;
  ASSERT_TRUE(Submit(stub_.get(), spec, &job).ok());
  EXPECT_EQ(job.job_id().size(), 16u);
  EXPECT_EQ(job.frames_total(), 6u);
  EXPECT_EQ(job.scene_id(), "demo");

  // Watched by the 8-character prefix `tessera job list` shows; a shorter one is refused and
  // says how long a prefix must be.
  const Watched w = WatchToEnd(stub_.get(), job.job_id().substr(0, 8));
  ASSERT_TRUE(w.status.ok()) << w.status.error_message();
  ASSERT_FALSE(w.events.empty());
  EXPECT_FALSE(w.events.front().has_frame()) << "the first message is the job's state";
  {
    grpc::ClientContext ctx;
    v1::DeleteJobRequest r;
    r.set_job_id(job.job_id().substr(0, 7));
    v1::DeleteJobResponse got;
    EXPECT_CODE(stub_->DeleteJob(&ctx, r, &got), NOT_FOUND, "at least 8 characters");
  }
  const v1::Job& last = w.events.back().job();
  EXPECT_EQ(last.state(), v1::JOB_SUCCEEDED);
  EXPECT_EQ(last.frames_done(), 6u);
  EXPECT_GT(last.finished_unix_s(), 0.0);
  std::set<uint32_t> seen;
  uint32_t previous_done = 0;
  for (const v1::JobProgress& p : w.events) {
    EXPECT_GE(p.job().frames_done(), previous_done) << "counts never go back";
    previous_done = p.job().frames_done();
    if (!p.has_frame()) continue;
    seen.insert(p.frame().frame());
    EXPECT_EQ(p.frame().sha256().size(), 64u);
    EXPECT_GT(p.frame().gpu_total_ms(), 0.0);
    EXPECT_GT(p.frame().passes_size(), 0);
  }
  EXPECT_EQ(seen, (std::set<uint32_t>{0, 1, 2, 3, 4, 5})) << "one event per frame";

  grpc::Status st;
  std::map<uint32_t, v1::JobFrame> frames = FetchAll(stub_.get(), job.job_id(), &st);
  ASSERT_TRUE(st.ok()) << st.error_message();
  ASSERT_EQ(frames.size(), 6u);
  for (const auto& [n, f] : frames) {
    EXPECT_EQ(f.encoding(), v1::IMAGE_PNG);
    EXPECT_EQ(Sha256Hex(f.data().data(), f.data().size()), f.sha256());
    absl::StatusOr<RgbaImage> img = DecodePng(
        std::span(reinterpret_cast<const uint8_t*>(f.data().data()), f.data().size()));
    ASSERT_TRUE(img.ok()) << img.status();
    EXPECT_EQ(img->width, 96u);
    EXPECT_EQ(img->height, 64u);
  }
  EXPECT_NE(frames[0].data(), frames[3].data()) << "the camera moves";

  // The farm path renders the same bytes for the same frame.
  v1::Frame f3;
  ASSERT_TRUE(RenderJobFrame(stub_.get(), spec, 3, &f3).ok());
  EXPECT_EQ(f3.data(), frames[3].data());

  // Only some frames, and a frame not done.
  frames = FetchAll(stub_.get(), job.job_id(), &st, {4, 1});
  ASSERT_TRUE(st.ok());
  EXPECT_EQ(frames.size(), 2u);
  FetchAll(stub_.get(), job.job_id(), &st, {99});
  EXPECT_CODE(st, NOT_FOUND, "frame 99");

  // Cancelling a finished job returns it unchanged (twice: nothing hangs).
  for (int i = 0; i < 2; ++i) {
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
    v1::CancelJobRequest r;
    r.set_job_id(job.job_id());
    v1::Job j;
    ASSERT_TRUE(stub_->CancelJob(&ctx, r, &j).ok());
    EXPECT_EQ(j.state(), v1::JOB_SUCCEEDED);
    EXPECT_FALSE(j.spec().has_list()) << "responses leave the camera list out";
  }
}

// A watch that begins after frames finished (a small frame can finish between SubmitJob and
// WatchJob) still hears of them, with their timings: at most the last kWatchReplayFrames.
TEST_F(JobTest, AWatchAfterTheFramesFinishedStillHearsOfThem) {
  Start(BaseOptions());
  const uint32_t n = server::kWatchReplayFrames + 6;
  v1::JobSpec spec = OrbitSpec("demo", n, 16, 16);
  spec.set_encoding(v1::IMAGE_JPEG);
  v1::Job job;
  ASSERT_TRUE(Submit(stub_.get(), spec, &job).ok());
  const v1::Job done =
      WaitJob(stub_.get(), job.job_id(), [](const v1::Job& j) { return j.finished_unix_s() > 0; });
  ASSERT_EQ(done.state(), v1::JOB_SUCCEEDED) << done.error();

  for (int watch = 0; watch < 2; ++watch) {  // a second watch hears the same
    const Watched w = WatchToEnd(stub_.get(), job.job_id());
    ASSERT_TRUE(w.status.ok()) << w.status.error_message();
    ASSERT_EQ(w.events.size(), 1 + server::kWatchReplayFrames);
    EXPECT_FALSE(w.events.front().has_frame()) << "the first message is the job's state";
    std::set<uint32_t> seen;
    for (size_t i = 1; i < w.events.size(); ++i) {
      const v1::JobProgress& p = w.events[i];
      ASSERT_TRUE(p.has_frame());
      EXPECT_EQ(p.job().state(), v1::JOB_SUCCEEDED) << "each with the job as it is now";
      EXPECT_EQ(p.job().frames_done(), n);
      EXPECT_EQ(p.frame().index(), p.frame().frame());
      EXPECT_EQ(p.frame().sha256().size(), 64u);
      EXPECT_GT(p.frame().bytes(), 0u);
      EXPECT_GT(p.frame().passes_size(), 0) << "the frame's timings as it finished";
      seen.insert(p.frame().frame());
    }
    EXPECT_EQ(seen.size(), server::kWatchReplayFrames) << "no frame twice";
    EXPECT_FALSE(seen.count(0)) << "the last frames finished, not the first";
  }
}

// taa history and occlusion history start from reset for every job frame: the bytes do not
// depend on what the daemon rendered before (what lets any daemon render any frame).
TEST_F(JobTest, FramesDoNotDependOnWhatWasRenderedBefore) {
  Start(BaseOptions());
  v1::JobSpec spec = OrbitSpec("demo", 4, 96, 64);
  spec.mutable_settings()->set_aa(v1::AA_TAA);
  spec.mutable_settings()->set_culling(v1::CULLING_GPU_OCCLUSION);
  spec.set_taa_frames(4);
  v1::Frame a, b, c, other;
  ASSERT_TRUE(RenderJobFrame(stub_.get(), spec, 2, &a).ok());
  // Other views of other cameras in between, and the job's neighbouring frame.
  for (uint32_t f : {0u, 3u}) ASSERT_TRUE(RenderJobFrame(stub_.get(), spec, f, &other).ok());
  {
    grpc::ClientContext ctx;
    v1::RenderRequest r = DemoRequest(96, 64);
    r.mutable_settings()->set_aa(v1::AA_TAA);
    ASSERT_TRUE(stub_->Render(&ctx, r, &other).ok());
  }
  ASSERT_TRUE(RenderJobFrame(stub_.get(), spec, 2, &b).ok());
  EXPECT_EQ(a.data(), b.data());
  EXPECT_EQ(a.settings().aa(), v1::AA_TAA);

  // Accumulation really happens: one taa frame is not the converged one.
  spec.set_taa_frames(1);
  ASSERT_TRUE(RenderJobFrame(stub_.get(), spec, 2, &c).ok());
  EXPECT_NE(a.data(), c.data());
}

// Beside a viewer that keeps the render thread busy (a continuous stream it cannot render as
// fast as it asks), a job still gets its share and finishes, and the viewer keeps streaming.
TEST_F(JobTest, AJobProgressesBesideARenderBoundViewer) {
  Start(BaseOptions());
  grpc::ClientContext stream_ctx;
  std::unique_ptr<StreamRW> stream = stub_->Stream(&stream_ctx);
  v1::ClientEvent open = OpenEvent("demo", 960, 540, 60);
  open.mutable_open()->mutable_settings()->set_aa(v1::AA_MSAA);
  ASSERT_TRUE(stream->Write(open));
  std::atomic<int> viewer_frames{0};
  std::thread reader([&] {
    v1::Frame f;
    while (stream->Read(&f)) ++viewer_frames;
  });
  while (viewer_frames < 3) std::this_thread::sleep_for(std::chrono::milliseconds(5));

  v1::Job job;
  ASSERT_TRUE(Submit(stub_.get(), OrbitSpec("demo", 3, 64, 48), &job).ok());
  const int before = viewer_frames;
  const Watched w = WatchToEnd(stub_.get(), job.job_id());
  ASSERT_TRUE(w.status.ok()) << w.status.error_message();
  EXPECT_EQ(w.events.back().job().state(), v1::JOB_SUCCEEDED) << "the job must not starve";
  EXPECT_GT(viewer_frames.load(), before) << "the viewer kept getting frames meanwhile";
  stream_ctx.TryCancel();
  reader.join();
  stream->Finish();
}

// An animated file: frame n of a job with fps is the scene at n / fps seconds, the same pixels as
// a single Render at that time, and the same bytes from another daemon (RenderJobFrame).
TEST_F(JobTest, AnAnimationRendersToFramesThatMatchRendersAtTheirTimes) {
  Start(BaseOptions());
  const std::string file = std::string(TESSERA_ANIMATED_DIR) + "/skinned_cylinder.gltf";
  v1::SceneInfo info;
  ASSERT_TRUE(UploadFromDisk(stub_.get(), file, &info).ok());
  ASSERT_EQ(info.animations_size(), 1);
  EXPECT_EQ(info.animations(0).name(), "bend");
  v1::JobSpec spec;
  spec.set_scene_id(info.scene_id());
  spec.mutable_frames()->set_last(4);
  spec.set_encoding(v1::IMAGE_PNG);
  spec.set_fps(4.0);
  v1::RenderSettings& s = *spec.mutable_settings();
  s.set_width(96);
  s.set_height(64);
  s.set_animation("bend");
  s.set_scene_time(0.25f);  // frame n shows 0.25 + n / 4 s
  v1::Job job;
  ASSERT_TRUE(Submit(stub_.get(), spec, &job).ok());
  const Watched w = WatchToEnd(stub_.get(), job.job_id());
  ASSERT_TRUE(w.status.ok()) << w.status.error_message();
  ASSERT_EQ(w.events.back().job().state(), v1::JOB_SUCCEEDED) << w.events.back().job().error();
  grpc::Status st;
  std::map<uint32_t, v1::JobFrame> frames = FetchAll(stub_.get(), job.job_id(), &st);
  ASSERT_TRUE(st.ok()) << st.error_message();
  ASSERT_EQ(frames.size(), 5u);
  auto decode = [](const std::string& bytes) {
    absl::StatusOr<RgbaImage> img =
        DecodePng(std::span(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()));
    EXPECT_TRUE(img.ok()) << img.status();
    return img.ok() ? img->pixels : std::vector<uint8_t>();
  };
  for (uint32_t n = 0; n < 5; ++n) {
    grpc::ClientContext ctx;
    v1::RenderRequest req;
    req.set_scene_id(info.scene_id());
    *req.mutable_settings() = s;
    req.mutable_settings()->set_scene_time(0.25f + float(n) / 4.0f);
    req.set_encoding(v1::IMAGE_PNG);
    v1::Frame single;
    ASSERT_TRUE(stub_->Render(&ctx, req, &single).ok());
    EXPECT_TRUE(decode(single.data()) == decode(frames[n].data())) << "frame " << n;
    EXPECT_FLOAT_EQ(single.settings().scene_time(), 0.25f + float(n) / 4.0f);
  }
  // 0.25 s (22.5 degrees), 0.5 s (45), 1 s (90): the cylinder bends.
  EXPECT_TRUE(frames[0].data() != frames[1].data());
  EXPECT_TRUE(frames[1].data() != frames[3].data());

  // A second daemon renders the same bytes for the same frames.
  ServerOptions o2 = BaseOptions();
  std::unique_ptr<Server> other = StartServer(o2);
  ASSERT_NE(other, nullptr);
  std::unique_ptr<v1::RenderService::Stub> other_stub = Connect(other->address());
  v1::SceneInfo info2;
  ASSERT_TRUE(UploadFromDisk(other_stub.get(), file, &info2).ok());
  ASSERT_EQ(info2.scene_id(), info.scene_id());
  for (uint32_t n : {1u, 3u}) {
    v1::Frame f;
    ASSERT_TRUE(RenderJobFrame(other_stub.get(), spec, n, &f).ok());
    EXPECT_TRUE(f.data() == frames[n].data()) << "frame " << n;
  }
  other->Shutdown();

  // An animation the file does not have is refused at submission, naming the field.
  spec.mutable_settings()->set_animation("walk");
  EXPECT_CODE(Submit(stub_.get(), spec, &job), INVALID_ARGUMENT, "spec.settings.animation");
}

TEST_F(JobTest, BadSpecsAreRefusedNamingTheirField) {
  ServerOptions o = BaseOptions();
  o.max_job_frames = 100;
  Start(o);
  struct Case {
    const char* what;
    std::function<void(v1::JobSpec*)> change;
    grpc::StatusCode code;
    const char* text;
  };
  const std::vector<Case> cases = {
      {"last before first", [](v1::JobSpec* s) { s->mutable_frames()->set_first(9); },
       grpc::StatusCode::INVALID_ARGUMENT, "spec.frames.last"},
      {"too many frames",
       [](v1::JobSpec* s) {
         s->clear_list();
         s->mutable_frames()->set_last(500);
       },
       grpc::StatusCode::RESOURCE_EXHAUSTED, "max_job_frames"},
      {"unknown scene", [](v1::JobSpec* s) { s->set_scene_id("0123456789abcdef"); },
       grpc::StatusCode::NOT_FOUND, "scene_id"},
      {"bad settings", [](v1::JobSpec* s) { s->mutable_settings()->set_width(0); },
       grpc::StatusCode::INVALID_ARGUMENT, "spec.settings.width"},
      {"server dir without a root",
       [](v1::JobSpec* s) { s->set_output(v1::JOB_OUTPUT_SERVER_DIR); },
       grpc::StatusCode::FAILED_PRECONDITION, "job_output_root"},
      {"output dir escaping", [](v1::JobSpec* s) { s->set_output_dir("../x"); },
       grpc::StatusCode::INVALID_ARGUMENT, "spec.output_dir"},
      {"name pattern with a slash", [](v1::JobSpec* s) { s->set_name_pattern("a/%d.png"); },
       grpc::StatusCode::INVALID_ARGUMENT, "spec.name_pattern"},
      {"camera list too short",
       [](v1::JobSpec* s) { s->mutable_list()->mutable_cameras()->RemoveLast(); },
       grpc::StatusCode::INVALID_ARGUMENT, "spec.list"},
      {"a camera looking at itself",
       [](v1::JobSpec* s) {
         v1::LookAt* l = s->mutable_list()->mutable_cameras(2)->mutable_look_at();
         *l->mutable_target() = l->eye();
       },
       grpc::StatusCode::INVALID_ARGUMENT, "camera of frame 2"},
      {"keys out of order",
       [](v1::JobSpec* s) {
         s->clear_list();
         v1::CameraPath* p = s->mutable_path();
         for (uint32_t f : {4u, 2u}) {
           v1::CameraKeyframe* k = p->add_keyframes();
           k->set_frame(f);
           k->mutable_look_at()->mutable_eye()->set_z(3);
         }
       },
       grpc::StatusCode::INVALID_ARGUMENT, "spec.path.keyframes[1].frame"},
      {"too many taa frames", [](v1::JobSpec* s) { s->set_taa_frames(65); },
       grpc::StatusCode::INVALID_ARGUMENT, "spec.taa_frames"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    v1::JobSpec spec = OrbitSpec("demo", 4, 64, 48);
    c.change(&spec);
    v1::Job job;
    grpc::Status st = Submit(stub_.get(), spec, &job);
    EXPECT_EQ(st.error_code(), c.code) << st.error_message();
    EXPECT_NE(st.error_message().find(c.text), std::string::npos)
        << "\"" << st.error_message() << "\" should name " << c.text;
  }
  v1::Frame frame;
  EXPECT_CODE(RenderJobFrame(stub_.get(), OrbitSpec("demo", 4, 64, 48), 7, &frame),
              INVALID_ARGUMENT, "frame: 7");
  // Unknown job ids, everywhere.
  const std::string unknown = "0123456789abcdef";
  EXPECT_CODE(WatchToEnd(stub_.get(), unknown).status, NOT_FOUND, "job_id");
  {
    grpc::ClientContext ctx;
    v1::CancelJobRequest r;
    r.set_job_id(unknown);
    v1::Job j;
    EXPECT_CODE(stub_->CancelJob(&ctx, r, &j), NOT_FOUND, "job_id");
  }
  {
    grpc::ClientContext ctx;
    v1::DeleteJobRequest r;
    r.set_job_id("../../etc");
    v1::DeleteJobResponse resp;
    EXPECT_CODE(stub_->DeleteJob(&ctx, r, &resp), NOT_FOUND, "job_id");
  }
  grpc::Status st;
  FetchAll(stub_.get(), unknown, &st);
  EXPECT_CODE(st, NOT_FOUND, "job_id");
}

TEST_F(JobTest, CancelStopsTheJobAndDeleteRemovesIt) {
  ServerOptions o = BaseOptions();
  o.state_dir = state_.path();
  Start(o);
  v1::JobSpec spec = OrbitSpec("demo", 2000, 64, 48);
  spec.clear_list();  // frames the bounds: 2000 cameras are not needed to keep it busy
  v1::Job job;
  ASSERT_TRUE(Submit(stub_.get(), spec, &job).ok());
  v1::Job running = WaitJob(stub_.get(), job.job_id(), [](const v1::Job& j) {
    return j.frames_done() >= 2;
  });
  ASSERT_GE(running.frames_done(), 2u);
  {
    grpc::ClientContext ctx;
    v1::DeleteJobRequest r;
    r.set_job_id(job.job_id());
    v1::DeleteJobResponse resp;
    EXPECT_CODE(stub_->DeleteJob(&ctx, r, &resp), FAILED_PRECONDITION, "cancel it first");
  }
  v1::Job cancelled;
  {
    grpc::ClientContext ctx;
    v1::CancelJobRequest r;
    r.set_job_id(job.job_id());
    ASSERT_TRUE(stub_->CancelJob(&ctx, r, &cancelled).ok());
  }
  EXPECT_EQ(cancelled.state(), v1::JOB_CANCELLED);
  EXPECT_LT(cancelled.frames_done(), 2000u);
  // A watch of a finished job gets its state, the frames it finished, and ends.
  Watched w = WatchToEnd(stub_.get(), job.job_id());
  ASSERT_TRUE(w.status.ok());
  ASSERT_EQ(w.events.size(),
            1 + std::min<size_t>(cancelled.frames_done(), server::kWatchReplayFrames));
  for (const v1::JobProgress& p : w.events) {
    EXPECT_EQ(p.job().state(), v1::JOB_CANCELLED);
    EXPECT_EQ(p.has_frame(), &p != &w.events[0]);
  }
  // Nothing more is rendered for it.
  const uint64_t rendered = server_->stats().frames_rendered;
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_LE(server_->stats().frames_rendered, rendered + 3) << "only frames already in flight";
  EXPECT_EQ(server_->stats().jobs_active, 0u);

  const fs::path dir = fs::path(state_.path()) / "jobs" / job.job_id();
  EXPECT_TRUE(fs::exists(dir));
  {
    grpc::ClientContext ctx;
    v1::DeleteJobRequest r;
    r.set_job_id(job.job_id());
    v1::DeleteJobResponse resp;
    ASSERT_TRUE(stub_->DeleteJob(&ctx, r, &resp).ok());
  }
  EXPECT_FALSE(fs::exists(dir)) << "the journal and the kept frames go with the job";
  EXPECT_FALSE(GetJob(stub_.get(), job.job_id()).ok());
}

TEST_F(JobTest, MaxJobsDropsTheOldestFinishedJobOrRefuses) {
  ServerOptions o = BaseOptions();
  o.max_jobs = 2;
  Start(o);
  std::vector<std::string> ids;
  for (int i = 0; i < 3; ++i) {
    v1::Job job;
    ASSERT_TRUE(Submit(stub_.get(), OrbitSpec("demo", 1, 32, 32), &job).ok());
    ASSERT_TRUE(WatchToEnd(stub_.get(), job.job_id()).status.ok());
    ids.push_back(job.job_id());
  }
  EXPECT_FALSE(GetJob(stub_.get(), ids[0]).ok()) << "the oldest finished job made room";
  EXPECT_TRUE(GetJob(stub_.get(), ids[2]).ok());
  // Two running jobs: no room for a third.
  v1::JobSpec big = OrbitSpec("demo", 5000, 32, 32);
  big.clear_list();
  std::vector<std::string> running;
  for (int i = 0; i < 2; ++i) {
    v1::Job job;
    ASSERT_TRUE(Submit(stub_.get(), big, &job).ok());
    running.push_back(job.job_id());
  }
  v1::Job refused;
  EXPECT_CODE(Submit(stub_.get(), big, &refused), RESOURCE_EXHAUSTED, "max_jobs");
  for (const std::string& id : running) {
    grpc::ClientContext ctx;
    v1::CancelJobRequest r;
    r.set_job_id(id);
    v1::Job j;
    EXPECT_TRUE(stub_->CancelJob(&ctx, r, &j).ok());
  }
}

TEST_F(JobTest, ServerDirOutputIsWrittenUnderTheRoot) {
  TempDir root;
  ServerOptions o = BaseOptions();
  o.job_output_root = root.path();
  Start(o);
  v1::JobSpec spec = OrbitSpec("demo", 3, 64, 48);
  spec.set_output(v1::JOB_OUTPUT_SERVER_DIR);
  spec.set_output_dir("shots/a");
  spec.set_name_pattern("s_%03d.png");
  v1::Job job;
  ASSERT_TRUE(Submit(stub_.get(), spec, &job).ok());
  const Watched w = WatchToEnd(stub_.get(), job.job_id());
  ASSERT_TRUE(w.status.ok());
  EXPECT_EQ(w.events.back().job().state(), v1::JOB_SUCCEEDED);
  for (const v1::JobProgress& p : w.events) {
    if (p.has_frame()) {
      EXPECT_EQ(p.frame().path().rfind("shots/a/s_00", 0), 0u) << p.frame().path();
    }
  }
  grpc::Status st;
  std::map<uint32_t, v1::JobFrame> frames = FetchAll(stub_.get(), job.job_id(), &st);
  ASSERT_TRUE(st.ok());
  for (uint32_t f = 0; f < 3; ++f) {
    const fs::path file = fs::path(root.path()) / "shots/a" / ("s_00" + std::to_string(f) + ".png");
    ASSERT_TRUE(fs::exists(file)) << file;
    std::ifstream in(file, std::ios::binary);
    std::stringstream bytes;
    bytes << in.rdbuf();
    EXPECT_EQ(bytes.str(), frames[f].data()) << "fetch reads the written file";
  }
}

TEST_F(JobTest, JobCallsNeedAToken) {
  TempDir dir;
  const std::string tokens = (fs::path(dir.path()) / "tokens").string();
  std::ofstream(tokens) << "s3cret-token-value alice\n";
  ServerOptions o = BaseOptions();
  o.token_file = tokens;
  Start(o);
  v1::Job job;
  EXPECT_CODE(Submit(stub_.get(), OrbitSpec("demo", 1, 32, 32), &job), UNAUTHENTICATED, "token");
  v1::Frame frame;
  EXPECT_CODE(RenderJobFrame(stub_.get(), OrbitSpec("demo", 1, 32, 32), 0, &frame),
              UNAUTHENTICATED, "token");
  EXPECT_CODE(WatchToEnd(stub_.get(), "0123456789abcdef").status, UNAUTHENTICATED, "token");
}

// A daemon stopped mid-job and started again on the same --state_dir: the job resumes (its
// uploaded scene read back from the archive) and no finished frame is rendered again.
TEST_F(JobTest, RestartResumesTheJobWithoutRedoingFinishedFrames) {
  ServerOptions o = BaseOptions();
  o.state_dir = state_.path();
  Start(o);
  v1::SceneInfo box;
  ASSERT_TRUE(
      UploadFromDisk(stub_.get(), AssetsDir() + "/Box/glTF-Binary/Box.glb", &box).ok());
  v1::JobSpec spec = OrbitSpec(box.scene_id(), 400, 64, 48);
  spec.clear_list();
  v1::Job job;
  ASSERT_TRUE(Submit(stub_.get(), spec, &job).ok());
  EXPECT_EQ(job.scene_id(), box.scene_id());
  WaitJob(stub_.get(), job.job_id(), [](const v1::Job& j) { return j.frames_done() >= 5; });
  server_->Shutdown();
  const std::string log = (fs::path(state_.path()) / "jobs" / job.job_id() / "frames.log").string();
  const size_t logged = Lines(log).size();
  ASSERT_GE(logged, 5u);
  ASSERT_LT(logged, 400u) << "the job should still have been running";

  Start(o);  // the same state dir
  const v1::Job resumed =
      WaitJob(stub_.get(), job.job_id(), [](const v1::Job& j) {
        return j.state() == v1::JOB_SUCCEEDED || j.state() == v1::JOB_FAILED;
      }, 120000);
  ASSERT_EQ(resumed.state(), v1::JOB_SUCCEEDED) << resumed.error();
  EXPECT_EQ(resumed.frames_restored(), logged);
  EXPECT_EQ(resumed.frames_done(), 400u);
  // Every frame logged exactly once: none was rendered twice.
  std::set<std::string> frames;
  for (const std::string& line : Lines(log)) {
    EXPECT_TRUE(frames.insert(line.substr(0, line.find(' '))).second) << "twice: " << line;
  }
  EXPECT_EQ(frames.size(), 400u);
  // The scene came back from the archive (the new daemon never saw the upload).
  grpc::ClientContext ctx;
  v1::HasSceneRequest has;
  has.set_scene_id(box.scene_id());
  v1::HasSceneResponse present;
  ASSERT_TRUE(stub_->HasScene(&ctx, has, &present).ok());
  EXPECT_TRUE(present.present());
}

}  // namespace
}  // namespace tessera
