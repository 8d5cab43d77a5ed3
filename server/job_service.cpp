// The job RPCs of RenderService (server/jobs.h does the work).
#include <deque>
#include <optional>

#include "absl/strings/str_cat.h"
#include "renderer/log.h"
#include "server/job_journal.h"
#include "common/job_spec.h"
#include "server/jobs.h"
#include "server/service.h"
#include "common/scene_id.h"

namespace tessera::server {
namespace {

// At most this many progress messages wait for a slow watcher; past it the oldest frame event
// goes (the job snapshot in every message keeps the counts exact; state changes always go).
constexpr size_t kMaxPendingProgress = kWatchReplayFrames;

// WatchJob. The job pushes events into the channel from encoder threads; writes go out one at
// a time. Decisions are made under the channel's mutex and the gRPC calls after unlocking.
class WatchReactor final : public grpc::ServerWriteReactor<v1::JobProgress> {
 public:
  struct Channel final : JobWatcher {
    std::mutex mu;
    WatchReactor* reactor = nullptr;  // null after OnDone
    std::deque<v1::JobProgress> pending;
    v1::JobProgress current;  // being written
    bool writing = false;
    bool gone = false;  // cancelled or a write failed
    std::optional<grpc::Status> finish;  // Close asked for it
    bool finished = false;               // Finish called

    void Push(const v1::JobProgress& progress) override {
      WatchReactor* start = nullptr;
      {
        std::lock_guard lock(mu);
        if (gone || finish || !reactor) return;
        if (pending.size() >= kMaxPendingProgress) {
          auto it = std::find_if(pending.begin(), pending.end(),
                                 [](const v1::JobProgress& p) { return p.has_frame(); });
          if (it != pending.end()) pending.erase(it);
        }
        pending.push_back(progress);
        if (!writing) {
          writing = true;
          current = std::move(pending.front());
          pending.pop_front();
          start = reactor;
        }
      }
      if (start) start->StartWrite(&current);
    }

    void Close(const absl::Status& status) override {
      WatchReactor* r = nullptr;
      grpc::Status st = ToGrpc(status);
      {
        std::lock_guard lock(mu);
        if (finish || finished || !reactor) return;
        finish = st;
        if (!writing) {
          finished = true;
          r = reactor;
        }
      }
      if (r) r->Finish(st);
    }

    bool closed() const override {
      std::lock_guard lock(const_cast<std::mutex&>(mu));
      return gone || finished || !reactor;
    }

    void WriteDone(bool ok) {
      WatchReactor* r = nullptr;
      bool write = false;
      grpc::Status st;
      {
        std::lock_guard lock(mu);
        if (!ok) {
          gone = true;
          pending.clear();
        }
        if (ok && !pending.empty()) {
          current = std::move(pending.front());
          pending.pop_front();
          write = true;
        } else {
          writing = false;
          if (!finished && (gone || finish)) {
            finished = true;
            st = gone ? grpc::Status(grpc::StatusCode::CANCELLED, "watcher went away") : *finish;
          } else {
            return;
          }
        }
        r = reactor;
      }
      if (write) {
        r->StartWrite(&current);
      } else {
        r->Finish(st);
      }
    }

    void Cancelled() {
      WatchReactor* r = nullptr;
      {
        std::lock_guard lock(mu);
        gone = true;
        if (writing || finished) return;  // the write fails and finishes
        finished = true;
        r = reactor;
      }
      r->Finish(grpc::Status(grpc::StatusCode::CANCELLED, "watcher went away"));
    }
  };

  WatchReactor(ServiceState* state, grpc::CallbackServerContext* ctx,
               const v1::WatchJobRequest* req)
      : state_(state), ctx_(ctx), channel_(std::make_shared<Channel>()), job_id_(req->job_id()) {
    channel_->reactor = this;
    absl::Status st = state_->Authorize(ctx).status();
    if (st.ok()) st = state_->jobs->Watch(job_id_, channel_);
    if (!st.ok()) {
      {
        std::lock_guard lock(channel_->mu);
        channel_->finished = true;
        channel_->finish = ToGrpc(st);
      }
      Finish(ToGrpc(st));
    }
  }

  void OnWriteDone(bool ok) override { channel_->WriteDone(ok); }
  void OnCancel() override { channel_->Cancelled(); }
  void OnDone() override {
    {
      std::lock_guard lock(channel_->mu);
      channel_->reactor = nullptr;
      status_ = channel_->finish.value_or(grpc::Status(grpc::StatusCode::CANCELLED, ""));
    }
    Log().info("WatchJob {} ended peer={}", job_id_.substr(0, 64), ctx_->peer());
    state_->CountRpc("WatchJob", status_);
    delete this;
  }

 private:
  ServiceState* state_;
  grpc::CallbackServerContext* ctx_;
  std::shared_ptr<Channel> channel_;
  std::string job_id_;
  grpc::Status status_;
};

// FetchJobFrames: one file read and written at a time.
class FetchReactor final : public grpc::ServerWriteReactor<v1::JobFrame> {
 public:
  FetchReactor(ServiceState* state, grpc::CallbackServerContext* ctx,
               const v1::FetchJobFramesRequest* req)
      : state_(state), ctx_(ctx), job_id_(req->job_id()) {
    absl::Status st = state_->Authorize(ctx).status();
    if (st.ok()) {
      std::vector<uint32_t> wanted(req->frames().begin(), req->frames().end());
      absl::StatusOr<std::vector<JobManager::StoredFrame>> frames =
          state_->jobs->Frames(job_id_, wanted);
      if (frames.ok()) {
        frames_ = *std::move(frames);
        encoding_ = state_->jobs->Encoding(job_id_);
      }
      st = frames.status();
    }
    if (!st.ok()) {
      Done(st);
      return;
    }
    Next();
  }

  void OnWriteDone(bool ok) override {
    if (!ok) return Done(absl::CancelledError("client went away"));
    Next();
  }

  void OnDone() override { delete this; }

 private:
  void Next() {
    if (next_ >= frames_.size()) return Done(absl::OkStatus());
    const JobManager::StoredFrame& f = frames_[next_++];
    absl::StatusOr<std::string> data = ReadWholeFile(f.path, f.bytes);
    if (!data.ok() || data->size() != f.bytes ||
        Sha256Hex(data->data(), data->size()) != f.sha256)
      return Done(absl::DataLossError(absl::StrCat(
          "frame ", f.frame, ": the stored file changed or is unreadable",
          data.ok() ? "" : absl::StrCat(" (", data.status().message(), ")"))));
    out_.Clear();
    out_.set_frame(f.frame);
    out_.set_encoding(encoding_);
    out_.set_data(*std::move(data));
    out_.set_sha256(f.sha256);
    bytes_ += f.bytes;
    StartWrite(&out_);
  }

  void Done(const absl::Status& st) {
    Log().info("FetchJobFrames {}: {} frames, {} bytes -> {} peer={}", job_id_.substr(0, 64),
               next_, bytes_, st.ok() ? "OK" : st.ToString(), ctx_->peer());
    state_->CountRpc("FetchJobFrames", ToGrpc(st));
    Finish(ToGrpc(st));
  }

  ServiceState* state_;
  grpc::CallbackServerContext* ctx_;
  std::string job_id_;
  std::vector<JobManager::StoredFrame> frames_;
  v1::ImageEncoding encoding_ = v1::IMAGE_JPEG;
  size_t next_ = 0;
  uint64_t bytes_ = 0;
  v1::JobFrame out_;
};

}  // namespace

grpc::ServerUnaryReactor* RenderServiceImpl::SubmitJob(grpc::CallbackServerContext* ctx,
                                                       const v1::SubmitJobRequest* req,
                                                       v1::Job* response) {
  if (absl::Status st = state_->Authorize(ctx).status(); !st.ok())
    return Reply(state_, ctx, "SubmitJob", st);
  if (state_->shutting_down) return Reply(state_, ctx, "SubmitJob", Unavailable());
  absl::StatusOr<v1::Job> job = state_->jobs->Submit(req->spec());
  Log().info("SubmitJob {} ({} frames) -> {} peer={}", req->spec().name().substr(0, 80),
             jobs::FrameCount(req->spec().frames()),
             job.ok() ? job->job_id() : job.status().ToString(), ctx->peer());
  if (job.ok()) *response = *std::move(job);
  return Reply(state_, ctx, "SubmitJob", job.status());
}

grpc::ServerWriteReactor<v1::JobProgress>* RenderServiceImpl::WatchJob(
    grpc::CallbackServerContext* ctx, const v1::WatchJobRequest* req) {
  return new WatchReactor(state_, ctx, req);
}

grpc::ServerUnaryReactor* RenderServiceImpl::CancelJob(grpc::CallbackServerContext* ctx,
                                                       const v1::CancelJobRequest* req,
                                                       v1::Job* response) {
  if (absl::Status st = state_->Authorize(ctx).status(); !st.ok())
    return Reply(state_, ctx, "CancelJob", st);
  absl::StatusOr<v1::Job> job = state_->jobs->Cancel(req->job_id());
  Log().info("CancelJob {} -> {} peer={}", req->job_id().substr(0, 64),
             job.ok() ? v1::JobState_Name(job->state()) : job.status().ToString(), ctx->peer());
  if (job.ok()) *response = *std::move(job);
  return Reply(state_, ctx, "CancelJob", job.status());
}

grpc::ServerUnaryReactor* RenderServiceImpl::DeleteJob(grpc::CallbackServerContext* ctx,
                                                       const v1::DeleteJobRequest* req,
                                                       v1::DeleteJobResponse*) {
  if (absl::Status st = state_->Authorize(ctx).status(); !st.ok())
    return Reply(state_, ctx, "DeleteJob", st);
  absl::Status st = state_->jobs->Delete(req->job_id());
  Log().info("DeleteJob {} -> {} peer={}", req->job_id().substr(0, 64),
             st.ok() ? "OK" : st.ToString(), ctx->peer());
  return Reply(state_, ctx, "DeleteJob", st);
}

grpc::ServerUnaryReactor* RenderServiceImpl::ListJobs(grpc::CallbackServerContext* ctx,
                                                      const v1::ListJobsRequest*,
                                                      v1::ListJobsResponse* response) {
  if (absl::Status st = state_->Authorize(ctx).status(); !st.ok())
    return Reply(state_, ctx, "ListJobs", st);
  for (v1::Job& job : state_->jobs->List()) *response->add_jobs() = std::move(job);
  return Reply(state_, ctx, "ListJobs", absl::OkStatus());
}

grpc::ServerWriteReactor<v1::JobFrame>* RenderServiceImpl::FetchJobFrames(
    grpc::CallbackServerContext* ctx, const v1::FetchJobFramesRequest* req) {
  return new FetchReactor(state_, ctx, req);
}

grpc::ServerUnaryReactor* RenderServiceImpl::RenderJobFrame(grpc::CallbackServerContext* ctx,
                                                            const v1::RenderJobFrameRequest* req,
                                                            v1::Frame* response) {
  grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
  ServiceState* state = state_;
  auto fail = [state, ctx, req, reactor](const absl::Status& st) {
    Log().info("RenderJobFrame {} frame {} -> {} peer={}", req->spec().name().substr(0, 80),
               req->frame(), st.ToString(), ctx->peer());
    state->CountRpc("RenderJobFrame", ToGrpc(st));
    reactor->Finish(ToGrpc(st));
  };
  // Renders once the scene is there (at once, or after it is read back from the archive).
  auto render = [state, ctx, req, reactor, response, fail](const StoredScene& scene) {
    absl::StatusOr<RenderWork> work = JobFrameWork(req->spec(), req->frame(), scene,
                                                   state->default_settings,
                                                   state->jobs->NewView());
    if (!work.ok()) return fail(work.status());
    if (state->unary_queued.fetch_add(1) >= kMaxQueuedRenders) {
      --state->unary_queued;
      return fail(absl::ResourceExhaustedError(absl::StrCat(
          "render queue: ", kMaxQueuedRenders, " renders are waiting (limit); retry later")));
    }
    work->sequence = 1;
    state->loop->Enqueue(
        MakeUnaryRender(state, ctx, reactor, response, *std::move(work), "RenderJobFrame"),
        Priority::kBackground);
  };
  if (absl::Status st = state_->Authorize(ctx).status(); !st.ok()) {
    fail(st);
    return reactor;
  }
  if (state_->shutting_down) {
    fail(Unavailable());
    return reactor;
  }
  const v1::JobSpec& spec = req->spec();
  absl::Status valid = jobs::ValidateJobSpec(spec, {state_->jobs->options().max_job_frames});
  if (valid.ok() && !jobs::FrameIndex(spec.frames(), req->frame()))
    valid = absl::InvalidArgumentError(absl::StrCat(
        "frame: ", req->frame(), " is not a frame of spec.frames (", spec.frames().first(), "..",
        spec.frames().last(), " step ", std::max(1u, spec.frames().step()), ")"));
  if (!valid.ok()) {
    fail(valid);
    return reactor;
  }
  absl::StatusOr<std::shared_ptr<StoredScene>> scene = state_->store->Find(spec.scene_id());
  if (scene.ok()) {
    render(**scene);
    return reactor;
  }
  // A persistent daemon that restarted (or evicted the scene) still has it archived, and a
  // replica finds what another uploaded in the shared scene store: a farm client's frames
  // keep working without a new upload.
  JobManager* jobs = state_->jobs;
  if (absl::IsNotFound(scene.status()) && jobs->HasArchived(spec.scene_id())) {
    jobs->LoadArchived(spec.scene_id(),
                       [render, fail](absl::StatusOr<std::shared_ptr<StoredScene>> s) {
                         if (!s.ok()) return fail(s.status());
                         render(**s);
                       });
    return reactor;
  }
  fail(absl::Status(scene.status().code(), absl::StrCat("spec.", scene.status().message())));
  return reactor;
}

}  // namespace tessera::server
