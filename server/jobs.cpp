#include "server/jobs.h"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <deque>
#include <optional>
#include <set>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "common/job_spec.h"
#include "common/scene_id.h"
#include "common/status_macros.h"
#include "renderer/log.h"
#include "renderer/scene/gltf_import.h"
#include "server/auth.h"
#include "server/convert.h"

namespace tessera::server {
namespace {

double UnixNow() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

double MsBetween(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}


bool Terminal(v1::JobState s) {
  return s == v1::JOB_SUCCEEDED || s == v1::JOB_FAILED || s == v1::JOB_CANCELLED;
}

std::string JoinPath(const std::string& a, const std::string& b) {
  if (b.empty()) return a;
  if (a.empty()) return b;
  return a.back() == '/' ? a + b : a + "/" + b;
}

// mkdir -p, refusing to follow nothing special: the parts were validated as relative names.
absl::Status MakeDirs(const std::string& path) {
  std::string partial;
  size_t pos = 0;
  while (pos <= path.size()) {
    size_t slash = path.find('/', pos);
    if (slash == std::string::npos) slash = path.size();
    partial = path.substr(0, slash);
    if (!partial.empty() && ::mkdir(partial.c_str(), 0755) != 0 && errno != EEXIST)
      return absl::FailedPreconditionError(
          absl::StrCat("cannot create directory ", partial, ": ", std::strerror(errno)));
    pos = slash + 1;
  }
  struct stat st;
  if (::stat(path.c_str(), &st) != 0 || !S_ISDIR(st.st_mode))
    return absl::FailedPreconditionError(absl::StrCat(path, ": is not a directory"));
  return absl::OkStatus();
}

uint64_t FileSize(const std::string& path) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return UINT64_MAX;
  return static_cast<uint64_t>(st.st_size);
}

absl::Status Prefixed(const absl::Status& s, const std::string& prefix) {
  if (s.ok()) return s;
  return absl::Status(s.code(), absl::StrCat(prefix, s.message()));
}

}  // namespace

namespace {

// The concrete camera of `frame` in a scene, for frames of the given settings.
absl::StatusOr<Camera> JobCamera(const v1::JobSpec& spec, uint32_t frame, const SceneInfo& scene,
                                 const Settings& settings) {
  ASSIGN_OR_RETURN(v1::Camera wire, jobs::CameraAtFrame(spec, frame));
  absl::StatusOr<Camera> camera =
      ResolveCamera(wire, scene, float(settings.width) / float(settings.height));
  if (!camera.ok())
    return Prefixed(camera.status(), absl::StrCat("spec: the camera of frame ", frame, ": "));
  return camera;
}

}  // namespace

absl::StatusOr<RenderWork> JobFrameWork(const v1::JobSpec& spec, uint32_t frame,
                                        const StoredScene& scene, const Settings& defaults,
                                        uint64_t view) {
  absl::StatusOr<Settings> settings = MergeSettings(defaults, spec.settings());
  if (!settings.ok()) return Prefixed(settings.status(), "spec.");
  // The frame's place in the shot; a job's time never follows the wall clock.
  settings->scene_time = jobs::SceneTimeAtFrame(spec, frame);
  settings->play = false;
  RenderWork w;
  ASSIGN_OR_RETURN(w.camera, JobCamera(spec, frame, scene.scene->info(), *settings));
  w.scene = scene.scene;
  w.scene_id = scene.id;
  w.settings = *settings;
  w.format = spec.encoding() == v1::IMAGE_PNG ? ImageFormat::kPng : ImageFormat::kJpeg;
  w.view = view;
  w.fresh_view = true;
  w.accumulate = settings->aa == AaMode::kTaa ? jobs::TaaFrames(spec) : 1;
  w.kind = "job";
  w.requested = Clock::now();
  return w;
}

// ---------------------------------------------------------------------------------------------

class Job final : public RenderClient, public std::enable_shared_from_this<Job> {
 public:
  enum FrameStatus : uint8_t { kTodo, kInFlight, kDone };

  Job(JobManager* m, v1::Job proto, std::vector<uint32_t> frames, uint64_t view)
      : m_(m),
        proto_(std::move(proto)),
        frames_(std::move(frames)),
        status_(frames_.size(), kTodo),
        view_(view) {}

  const std::string& id() const { return proto_.job_id(); }

  v1::Job Snapshot() const {
    std::lock_guard lock(mu_);
    return SnapshotLocked();
  }

  bool terminal() const {
    std::lock_guard lock(mu_);
    return Terminal(proto_.state());
  }

  // A frame found done in the journal (restore): kept if its file is still there, whole.
  void MarkRestored(const JobFrameRecord& r) {
    std::lock_guard lock(mu_);
    std::optional<uint32_t> index = jobs::FrameIndex(proto_.spec().frames(), r.frame);
    if (!index || *index >= frames_.size() || status_[*index] == kDone) return;
    const std::string path = FramePath(r.frame);
    if (FileSize(path) != r.bytes) return;  // missing or torn: redo it
    status_[*index] = kDone;
    done_[r.frame] = {r.frame, path, r.bytes, r.sha256};
  }

  // After restore: how many frames were found, and the job's state made consistent.
  // `failure`: why an unfinished job cannot go on here ("" when it can).
  void FinishRestore(const std::string& failure) {
    std::unique_lock lock(mu_);
    const uint32_t done = static_cast<uint32_t>(done_.size());
    proto_.set_frames_done(done);
    if (Terminal(proto_.state())) return;
    proto_.set_frames_restored(done);
    proto_.set_state(v1::JOB_QUEUED);
    if (!failure.empty()) {
      EndLocked(lock, v1::JOB_FAILED, failure);
    } else if (done == frames_.size()) {
      EndLocked(lock, v1::JOB_SUCCEEDED, "");
    }
  }

  // The scene is there: the job becomes runnable.
  void Start(std::shared_ptr<StoredScene> scene) {
    {
      std::unique_lock lock(mu_);
      if (Terminal(proto_.state())) return;
      scene_ = scene;
      lease_ = std::make_shared<SceneLease>(std::move(scene));
      if (queued_) return;
      queued_ = true;
    }
    m_->loop()->Enqueue(shared_from_this(), Priority::kBackground);
  }

  void Fail(const std::string& error) {
    std::unique_lock lock(mu_);
    if (!Terminal(proto_.state())) EndLocked(lock, v1::JOB_FAILED, error);
  }

  v1::Job Cancel() {
    std::unique_lock lock(mu_);
    if (!Terminal(proto_.state())) {
      EndLocked(lock, v1::JOB_CANCELLED, "");  // releases the lock
      lock.lock();
    }
    return SnapshotLocked();
  }

  void AddWatcher(std::shared_ptr<JobWatcher> w) {
    std::unique_lock lock(mu_);
    v1::JobProgress first;
    *first.mutable_job() = SnapshotLocked();
    // The frames finished before the watch began (a small frame can finish between SubmitJob
    // and WatchJob), as their events told them, each with the job as it is now.
    std::vector<v1::JobProgress> replay(recent_.size());
    for (size_t i = 0; i < recent_.size(); ++i) {
      *replay[i].mutable_job() = first.job();
      *replay[i].mutable_frame() = recent_[i];
    }
    // Shutting down: CloseWatchers may have run already, so this one gets its end now.
    const bool finished = Terminal(proto_.state());
    const bool done = finished || m_->shutting_down();
    if (!done) watchers_.push_back(w);
    std::lock_guard notify(notify_mu_);
    lock.unlock();
    w->Push(first);
    for (const v1::JobProgress& event : replay) w->Push(event);
    if (done)
      w->Close(finished ? absl::OkStatus() : absl::UnavailableError("server is shutting down"));
  }

  void CloseWatchers(const absl::Status& status) {
    std::unique_lock lock(mu_);
    std::vector<std::shared_ptr<JobWatcher>> watchers;
    watchers.swap(watchers_);
    std::lock_guard notify(notify_mu_);
    lock.unlock();
    for (auto& w : watchers) w->Close(status);
  }

  std::optional<JobManager::StoredFrame> FrameFile(uint32_t frame) const {
    std::lock_guard lock(mu_);
    auto it = done_.find(frame);
    if (it == done_.end()) return std::nullopt;
    return it->second;
  }

  std::vector<JobManager::StoredFrame> DoneFrames() const {
    std::lock_guard lock(mu_);
    std::vector<JobManager::StoredFrame> out;
    for (const auto& [frame, f] : done_) out.push_back(f);
    return out;
  }

  std::optional<RenderWork> TakeWork() override {
    std::unique_lock lock(mu_);
    queued_ = false;
    if (Terminal(proto_.state()) || m_->shutting_down() || !scene_) return std::nullopt;
    while (cursor_ < frames_.size() && status_[cursor_] != kTodo) ++cursor_;
    if (cursor_ >= frames_.size()) return std::nullopt;
    const size_t index = cursor_++;
    const uint32_t frame = frames_[index];
    absl::StatusOr<RenderWork> work =
        JobFrameWork(proto_.spec(), frame, *scene_, m_->default_settings(), view_);
    if (!work.ok()) {
      EndLocked(lock, v1::JOB_FAILED, std::string(work.status().message()));
      return std::nullopt;
    }
    work->sequence = index + 1;
    status_[index] = kInFlight;
    ++in_flight_;
    if (proto_.state() == v1::JOB_QUEUED) {
      proto_.set_state(v1::JOB_RUNNING);
      run_start_ = Clock::now();
      Save();
      v1::JobProgress event;
      *event.mutable_job() = SnapshotLocked();
      NotifyLocked(lock, event);
      lock.lock();
    }
    // More to hand out: back in the queue for the next turn (other work goes first).
    size_t next = cursor_;
    while (next < frames_.size() && status_[next] != kTodo) ++next;
    const bool more = next < frames_.size() && !Terminal(proto_.state());
    if (more) queued_ = true;
    lock.unlock();
    if (more) m_->loop()->Enqueue(shared_from_this(), Priority::kBackground);
    return std::move(*work);
  }

  void Deliver(const RenderWork& work, absl::StatusOr<EncodedFrame> frame) override {
    if (work.sequence == 0) {  // dropped from the queue (shutdown) before a turn
      std::lock_guard lock(mu_);
      queued_ = false;
      return;
    }
    const size_t index = work.sequence - 1;
    const uint32_t number = frames_[index];
    std::unique_lock lock(mu_);
    --in_flight_;
    if (Terminal(proto_.state())) {  // cancelled or failed meanwhile: the frame is not kept
      status_[index] = kTodo;
      return;
    }
    if (!frame.ok()) {
      status_[index] = kTodo;
      cursor_ = std::min(cursor_, index);
      if (absl::IsUnavailable(frame.status())) return;  // shutting down: resumed on restart
      EndLocked(lock, v1::JOB_FAILED,
                absl::StrCat("frame ", number, ": ", frame.status().ToString()));
      return;
    }
    const v1::JobSpec& spec = proto_.spec();
    lock.unlock();

    // The file first, then the journal line: a crash in between redoes the frame, never
    // trusts a file that is not whole.
    const std::string_view data(reinterpret_cast<const char*>(frame->data.data()),
                                frame->data.size());
    const std::string sha = Sha256Hex(data.data(), data.size());
    const std::string path = FramePath(number);
    absl::Status written = WriteFileAtomic(path, data);
    if (written.ok())
      written = m_->journal().AppendFrame(id(), JobFrameRecord{number, data.size(), sha});

    lock.lock();
    if (Terminal(proto_.state())) {
      // Cancelled (or deleted) while the file was written: the job's end stands as it is.
      status_[index] = kTodo;
      return;
    }
    if (!written.ok()) {
      status_[index] = kTodo;
      cursor_ = std::min(cursor_, index);
      EndLocked(lock, v1::JOB_FAILED, absl::StrCat("frame ", number, ": ", written.message()));
      return;
    }
    status_[index] = kDone;
    done_[number] = {number, path, data.size(), sha};
    proto_.set_frames_done(static_cast<uint32_t>(done_.size()));
    ++run_frames_;
    v1::JobProgress event;
    v1::JobFrameEvent* e = event.mutable_frame();
    e->set_frame(number);
    e->set_index(static_cast<uint32_t>(index));
    e->set_bytes(data.size());
    e->set_sha256(sha);
    if (spec.output() == v1::JOB_OUTPUT_SERVER_DIR)
      e->set_path(JoinPath(spec.output_dir(), jobs::FrameFileName(spec, number)));
    v1::Frame meta;  // the timings as a Frame has them
    FrameMetaToProto(*frame, &meta);
    *e->mutable_passes() = std::move(*meta.mutable_passes());
    e->set_gpu_total_ms(meta.gpu_total_ms());
    e->set_timing_source(meta.timing_source());
    *e->mutable_cpu() = meta.cpu();
    if (recent_.size() == kWatchReplayFrames) recent_.pop_front();
    recent_.push_back(*e);
    if (done_.size() == frames_.size() && in_flight_ == 0) {
      EndLocked(lock, v1::JOB_SUCCEEDED, "", &event);
      return;
    }
    *event.mutable_job() = SnapshotLocked();
    NotifyLocked(lock, event);
  }

 private:
  std::string FramePath(uint32_t frame) const {
    const v1::JobSpec& spec = proto_.spec();
    const std::string name = jobs::FrameFileName(spec, frame);
    // The directory recorded at submission, so a daemon restarted with another root does
    // not scatter one job's frames over two places.
    if (spec.output() == v1::JOB_OUTPUT_SERVER_DIR) return JoinPath(proto_.output_path(), name);
    return JoinPath(m_->journal().FramesDir(id()), name);
  }

  // What clients see: the spec without its camera list (it can hold 100000 cameras, and goes
  // out with every progress event).
  v1::Job SnapshotLocked() const {
    v1::Job out = proto_;
    out.mutable_spec()->clear_list();
    if (run_frames_ > 0 && !Terminal(proto_.state())) {
      const double per_frame = MsBetween(run_start_, Clock::now()) / run_frames_;
      out.set_mean_frame_ms(per_frame);
      const size_t remaining = frames_.size() - done_.size();
      out.set_eta_s(per_frame * double(remaining) / 1000.0);
    } else if (run_frames_ > 0) {
      out.set_mean_frame_ms(proto_.mean_frame_ms());
    }
    return out;
  }

  void Save() {
    if (absl::Status st = m_->journal().SaveJob(proto_); !st.ok())
      Log().warn("job {}: journal: {}", id(), st.ToString());
  }

  // Ends the job: state, journal, watchers told and closed, scene released. `lock` is held on
  // entry and released on return.
  void EndLocked(std::unique_lock<std::mutex>& lock, v1::JobState state, const std::string& error,
                 v1::JobProgress* event = nullptr) {
    if (run_frames_ > 0)
      proto_.set_mean_frame_ms(MsBetween(run_start_, Clock::now()) / run_frames_);
    proto_.set_state(state);
    proto_.set_error(error);
    proto_.set_eta_s(0.0);
    proto_.set_finished_unix_s(UnixNow());
    Save();
    Log().info("job {} ({}): {} after {} of {} frames{}{}", id(), proto_.spec().name(),
               v1::JobState_Name(state), done_.size(), frames_.size(), error.empty() ? "" : ": ",
               error);
    lease_.reset();
    scene_.reset();
    v1::JobProgress final_event;
    if (event) final_event = std::move(*event);
    *final_event.mutable_job() = SnapshotLocked();
    std::vector<std::shared_ptr<JobWatcher>> watchers;
    watchers.swap(watchers_);
    {
      std::lock_guard notify(notify_mu_);
      lock.unlock();
      for (auto& w : watchers) {
        w->Push(final_event);
        w->Close(absl::OkStatus());
      }
    }
    m_->JobEnded();
  }

  // Tells the watchers; `lock` is held on entry and released on return (the notify lock is
  // taken first, so two deliveries reach every watcher in the order they happened).
  void NotifyLocked(std::unique_lock<std::mutex>& lock, const v1::JobProgress& event) {
    std::erase_if(watchers_, [](const auto& w) { return w->closed(); });
    std::vector<std::shared_ptr<JobWatcher>> watchers = watchers_;
    std::lock_guard notify(notify_mu_);
    lock.unlock();
    for (auto& w : watchers) w->Push(event);
  }

  JobManager* const m_;
  mutable std::mutex mu_;
  std::mutex notify_mu_;
  v1::Job proto_;
  const std::vector<uint32_t> frames_;  // frame numbers
  std::vector<FrameStatus> status_;     // by index
  std::map<uint32_t, JobManager::StoredFrame> done_;  // by frame number
  const uint64_t view_;
  size_t cursor_ = 0;  // no frame before it is kTodo
  uint32_t in_flight_ = 0;
  bool queued_ = false;  // in the loop's background queue (or being taken)
  std::shared_ptr<StoredScene> scene_;
  std::shared_ptr<SceneLease> lease_;
  std::vector<std::shared_ptr<JobWatcher>> watchers_;
  std::deque<v1::JobFrameEvent> recent_;  // the last kWatchReplayFrames frames' events, in order
  Clock::time_point run_start_{};
  uint32_t run_frames_ = 0;
};

// ---------------------------------------------------------------------------------------------

absl::StatusOr<std::shared_ptr<StoredScene>> LoadIntoStore(Renderer* renderer, SceneStore* store,
                                                           const std::string& scene_id,
                                                           const GltfSource& source,
                                                           const SceneLimits& limits) {
  const Clock::time_point t0 = Clock::now();
  ASSIGN_OR_RETURN(CpuScene cpu, ImportGltf(source, limits.import));
  if (limits.max_device_bytes != 0) {
    const uint64_t bytes = renderer->EstimateDeviceBytes(cpu);
    if (bytes > limits.max_device_bytes)
      return absl::ResourceExhaustedError(absl::StrCat(
          source.main_file, ": the scene needs ", bytes,
          " bytes of device memory, over the max_scene_device_bytes limit (",
          limits.max_device_bytes, ")"));
  }
  ASSIGN_OR_RETURN(SceneHandle gpu, renderer->LoadScene(cpu));
  StoredSceneInfo info;
  info.scene = gpu->info();
  info.scene.name = source.main_file;
  for (const auto& [name, data] : source.files) info.upload_bytes += data.size();
  info.load_ms = MsBetween(t0, Clock::now());
  return store->Add(scene_id, std::move(gpu), std::move(info));
}

JobManager::JobManager(const JobManagerOptions& options, std::unique_ptr<JobJournal> journal,
                       Renderer* renderer, SceneStore* store, RenderLoop* loop,
                       ThreadPool* loader, Settings default_settings)
    : options_(options),
      journal_(std::move(journal)),
      renderer_(renderer),
      store_(store),
      loop_(loop),
      loader_(loader),
      default_settings_(std::move(default_settings)) {}

JobManager::~JobManager() { Shutdown(); }

namespace {
absl::Status UnknownJob(const std::string& job_id) {
  return absl::NotFoundError(absl::StrCat(
      "job_id: no job \"", job_id.substr(0, 64), "\"",
      job_id.size() < kMinIdPrefix ? absl::StrCat(" (a prefix needs at least ", kMinIdPrefix,
                                                  " characters; ListJobs lists the ids)")
                                   : " (ListJobs lists them)"));
}
}  // namespace

absl::StatusOr<std::map<std::string, std::shared_ptr<Job>>::const_iterator>
JobManager::ResolveLocked(const std::string& job_id) const {
  auto it = jobs_.find(job_id);
  if (it != jobs_.end()) return it;
  if (job_id.size() >= kMinIdPrefix) {
    // A unique prefix, as `tessera job list` shows them shortened.
    it = jobs_.lower_bound(job_id);
    if (it != jobs_.end() && absl::StartsWith(it->first, job_id)) {
      auto next = std::next(it);
      if (next == jobs_.end() || !absl::StartsWith(next->first, job_id)) return it;
      return absl::InvalidArgumentError(
          absl::StrCat("job_id: prefix \"", job_id, "\" matches more than one job"));
    }
  }
  return UnknownJob(job_id);
}

absl::StatusOr<std::shared_ptr<Job>> JobManager::FindJob(const std::string& job_id) const {
  std::lock_guard lock(mu_);
  ASSIGN_OR_RETURN(auto it, ResolveLocked(job_id));
  return it->second;
}

void JobManager::LoadArchived(
    const std::string& scene_id,
    std::function<void(absl::StatusOr<std::shared_ptr<StoredScene>>)> done) {
  loader_->Submit([this, scene_id, done = std::move(done)] {
    if (shutting_down_) return done(absl::UnavailableError("server is shutting down"));
    if (std::shared_ptr<StoredScene> s = store_->FindExact(scene_id)) return done(s);
    const bool journal = options_.persistent && journal_->HasScene(scene_id);
    if (!journal && !options_.shared_scenes)
      return done(absl::NotFoundError(absl::StrCat("scene ", scene_id, " is not archived")));
    const auto started = std::chrono::steady_clock::now();
    absl::StatusOr<GltfSource> source =
        journal ? journal_->LoadScene(scene_id, options_.max_scene_bytes)
                : options_.shared_scenes->Load(scene_id, options_.max_scene_bytes);
    if (!source.ok() && !journal) {
      // A damaged scene goes from the store, so HasScene says false and the client's next
      // upload writes it again (Save skips a scene that is there).
      if (absl::IsDataLoss(source.status())) {
        Log().error("scene {}: {}; removed from the shared scene store", scene_id.substr(0, 16),
                    std::string(source.status().message()));
        options_.shared_scenes->Remove(scene_id).IgnoreError();
      }
      return done(files::WithPrefix(source.status(), "scene_store_dir: "));
    }
    if (!source.ok()) return done(source.status());
    absl::StatusOr<std::shared_ptr<StoredScene>> stored =
        LoadIntoStore(renderer_, store_, scene_id, *source, options_.scene_limits);
    Log().info("scene {}: loaded from the {} ({:.1f} ms): {}", scene_id.substr(0, 16),
               journal ? "job journal" : "shared scene store",
               std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - started)
                   .count(),
               stored.ok() ? "OK" : stored.status().ToString());
    done(std::move(stored));
  });
}

bool JobManager::HasArchived(const std::string& scene_id) const {
  if (!JobJournal::ValidSceneId(scene_id)) return false;
  return (options_.persistent && journal_->HasScene(scene_id)) ||
         (options_.shared_scenes && options_.shared_scenes->Has(scene_id));
}

void JobManager::Restore(std::vector<std::string>* log) {
  // Jobs restored as finished must not prune the archive of jobs not restored yet.
  restoring_ = true;
  std::vector<std::string> warnings;
  std::vector<JobJournal::LoadedJob> loaded = journal_->LoadJobs(&warnings);
  for (std::string& w : warnings) log->push_back("jobs: " + w);
  std::sort(loaded.begin(), loaded.end(), [](const auto& a, const auto& b) {
    return a.job.created_unix_s() < b.job.created_unix_s();
  });
  std::vector<std::shared_ptr<Job>> resume;
  for (JobJournal::LoadedJob& l : loaded) {
    const std::string id = l.job.job_id();
    absl::StatusOr<std::vector<uint32_t>> frames =
        jobs::FrameNumbers(l.job.spec().frames(), kRestoreFrameCap);
    if (!frames.ok() || !jobs::ValidateJobSpec(l.job.spec(), {kRestoreFrameCap}).ok()) {
      log->push_back(absl::StrCat("jobs: ", id, ": spec no longer valid, dropped"));
      continue;
    }
    const bool unfinished = !Terminal(l.job.state());
    auto job = std::make_shared<Job>(this, l.job, *std::move(frames),
                                     kJobViewBase | next_view_++);
    for (const JobFrameRecord& r : l.frames) job->MarkRestored(r);
    job->FinishRestore(l.job.spec().output() == v1::JOB_OUTPUT_SERVER_DIR &&
                               options_.output_root.empty()
                           ? "restored by a server without --job_output_root"
                           : "");
    {
      std::lock_guard lock(mu_);
      jobs_[id] = job;
      order_.push_back(id);
    }
    const v1::Job snap = job->Snapshot();
    log->push_back(absl::StrCat("jobs: ", id, " (", snap.spec().name(), "): ",
                                v1::JobState_Name(snap.state()), ", ", snap.frames_done(), " of ",
                                snap.frames_total(), " frames done"));
    if (unfinished && !job->terminal()) resume.push_back(job);
  }
  for (const std::shared_ptr<Job>& job : resume) {
    const std::string scene_id = job->Snapshot().scene_id();
    if (std::shared_ptr<StoredScene> s = store_->FindExact(scene_id)) {
      job->Start(std::move(s));
      continue;
    }
    LoadArchived(scene_id, [job, scene_id](absl::StatusOr<std::shared_ptr<StoredScene>> s) {
      if (s.ok()) return job->Start(*std::move(s));
      if (absl::IsUnavailable(s.status())) return;  // shutting down: resumed next start
      job->Fail(absl::StrCat("scene ", scene_id.substr(0, 16),
                             ": could not be restored: ", s.status().message()));
    });
  }
  restoring_ = false;
  PruneArchive();
}

absl::Status JobManager::MakeRoomLocked() {
  if (jobs_.size() < options_.max_jobs) return absl::OkStatus();
  for (auto it = order_.begin(); it != order_.end(); ++it) {
    auto job = jobs_.find(*it);
    if (job == jobs_.end() || !job->second->terminal()) continue;
    if (absl::Status st = journal_->RemoveJob(*it); !st.ok())
      Log().warn("job {}: removing: {}", *it, st.ToString());
    Log().info("job {}: removed (oldest finished job, max_jobs {})", *it, options_.max_jobs);
    jobs_.erase(job);
    order_.erase(it);
    return absl::OkStatus();
  }
  return absl::ResourceExhaustedError(
      absl::StrCat("jobs: the max_jobs limit (", options_.max_jobs,
                   ") is reached and none is finished; wait, or cancel one"));
}

absl::StatusOr<v1::Job> JobManager::Submit(const v1::JobSpec& spec) {
  if (shutting_down_) return absl::UnavailableError("server is shutting down");
  if (absl::Status st = jobs::ValidateJobSpec(spec, {options_.max_job_frames}); !st.ok())
    return st;
  absl::StatusOr<std::vector<uint32_t>> frames =
      jobs::FrameNumbers(spec.frames(), options_.max_job_frames);
  if (!frames.ok()) return frames.status();
  if (spec.output() == v1::JOB_OUTPUT_SERVER_DIR && options_.output_root.empty())
    return absl::FailedPreconditionError(
        "spec.output: SERVER_DIR needs the server's --job_output_root, which is not set; use "
        "RETURN and fetch the frames");

  // The scene: in memory, or (persistent daemons) archived from an earlier run.
  std::shared_ptr<StoredScene> scene;
  absl::StatusOr<std::shared_ptr<StoredScene>> found = store_->Find(spec.scene_id());
  std::string scene_id;
  if (found.ok()) {
    scene = *found;
    scene_id = scene->id;
  } else if (absl::IsNotFound(found.status()) && HasArchived(spec.scene_id())) {
    scene_id = spec.scene_id();
  } else {
    return Prefixed(found.status(), "spec.");
  }
  // The settings and every frame's camera are checked now, not when the frame comes up.
  absl::StatusOr<Settings> settings = MergeSettings(default_settings_, spec.settings());
  if (!settings.ok()) return Prefixed(settings.status(), "spec.");
  if (scene) {
    if (absl::StatusOr<int> a = FindAnimation(scene->scene->info(), settings->animation); !a.ok())
      return Prefixed(a.status(), "spec.");
    for (uint32_t f : *frames) {
      RETURN_IF_ERROR(JobCamera(spec, f, scene->scene->info(), *settings).status());
    }
  }
  std::string output_path;
  if (spec.output() == v1::JOB_OUTPUT_SERVER_DIR) {
    output_path = JoinPath(options_.output_root, spec.output_dir());
    if (absl::Status st = MakeDirs(output_path); !st.ok())
      return absl::FailedPreconditionError(
          absl::StrCat("spec.output_dir: ", st.message()));
  }

  v1::Job proto;
  proto.set_job_id(RandomHex(8));  // 64 bits: unguessable, no collisions
  *proto.mutable_spec() = spec;
  proto.set_state(v1::JOB_QUEUED);
  proto.set_frames_total(static_cast<uint32_t>(frames->size()));
  proto.set_created_unix_s(UnixNow());
  proto.set_output_path(output_path);
  proto.set_scene_id(scene_id);
  auto job = std::make_shared<Job>(this, proto, *std::move(frames), kJobViewBase | next_view_++);
  {
    std::lock_guard lock(mu_);
    RETURN_IF_ERROR(MakeRoomLocked());
    if (absl::Status st = journal_->SaveJob(proto); !st.ok())
      return absl::InternalError(absl::StrCat("jobs: the journal: ", st.message()));
    jobs_[proto.job_id()] = job;
    order_.push_back(proto.job_id());
  }
  Log().info("job {} ({}): {} frames of scene {}, {}", proto.job_id(), spec.name(),
             proto.frames_total(), scene_id.substr(0, 16),
             spec.output() == v1::JOB_OUTPUT_SERVER_DIR ? "to " + output_path : "returned");
  if (scene) {
    job->Start(std::move(scene));
  } else {
    LoadArchived(scene_id, [job, scene_id](absl::StatusOr<std::shared_ptr<StoredScene>> s) {
      if (s.ok()) return job->Start(*std::move(s));
      if (absl::IsUnavailable(s.status())) return;  // shutting down: resumed next start
      job->Fail(absl::StrCat("scene ", scene_id.substr(0, 16), ": ", s.status().message()));
    });
  }
  return job->Snapshot();
}

absl::StatusOr<v1::Job> JobManager::Cancel(const std::string& job_id) {
  ASSIGN_OR_RETURN(std::shared_ptr<Job> job, FindJob(job_id));
  return job->Cancel();
}

absl::Status JobManager::Delete(const std::string& job_id) {
  std::lock_guard lock(mu_);
  ASSIGN_OR_RETURN(auto it, ResolveLocked(job_id));
  const std::string id = it->first;
  if (!it->second->terminal())
    return absl::FailedPreconditionError(
        absl::StrCat("job ", id, ": is still running; cancel it first"));
  RETURN_IF_ERROR(journal_->RemoveJob(id));
  jobs_.erase(it);
  std::erase(order_, id);
  return absl::OkStatus();
}

std::vector<v1::Job> JobManager::List() const {
  std::vector<std::shared_ptr<Job>> jobs;
  {
    std::lock_guard lock(mu_);
    for (const std::string& id : order_) jobs.push_back(jobs_.at(id));
  }
  std::vector<v1::Job> out;
  for (const auto& j : jobs) out.push_back(j->Snapshot());
  return out;
}

absl::StatusOr<v1::Job> JobManager::Get(const std::string& job_id) const {
  ASSIGN_OR_RETURN(std::shared_ptr<Job> job, FindJob(job_id));
  return job->Snapshot();
}

absl::Status JobManager::Watch(const std::string& job_id, std::shared_ptr<JobWatcher> watcher) {
  if (shutting_down_) return absl::UnavailableError("server is shutting down");
  ASSIGN_OR_RETURN(std::shared_ptr<Job> job, FindJob(job_id));
  job->AddWatcher(std::move(watcher));
  return absl::OkStatus();
}

absl::StatusOr<std::vector<JobManager::StoredFrame>> JobManager::Frames(
    const std::string& job_id, const std::vector<uint32_t>& frames) const {
  ASSIGN_OR_RETURN(std::shared_ptr<Job> job, FindJob(job_id));
  if (frames.empty()) return job->DoneFrames();
  std::vector<uint32_t> wanted = frames;
  std::sort(wanted.begin(), wanted.end());
  wanted.erase(std::unique(wanted.begin(), wanted.end()), wanted.end());
  std::vector<StoredFrame> out;
  for (uint32_t f : wanted) {
    std::optional<StoredFrame> file = job->FrameFile(f);
    if (!file)
      return absl::NotFoundError(
          absl::StrCat("frames: frame ", f, " of job ", job_id, " is not done"));
    out.push_back(*std::move(file));
  }
  return out;
}

v1::ImageEncoding JobManager::Encoding(const std::string& job_id) const {
  absl::StatusOr<std::shared_ptr<Job>> job = FindJob(job_id);
  if (!job.ok()) return v1::IMAGE_JPEG;
  return (*job)->Snapshot().spec().encoding() == v1::IMAGE_PNG ? v1::IMAGE_PNG : v1::IMAGE_JPEG;
}

void JobManager::ArchiveScene(const std::string& scene_id, const GltfSource& source) {
  if (!options_.persistent || !JobJournal::ValidSceneId(scene_id)) return;
  // The files are written outside the archive lock (SaveScene publishes them with one rename,
  // and the scene is in the store by now, so a prune meanwhile keeps it).
  if (journal_->HasScene(scene_id)) return;
  if (absl::Status st = journal_->SaveScene(scene_id, source); !st.ok())
    Log().warn("scene {}: not archived for jobs: {}", scene_id.substr(0, 16), st.ToString());
  PruneArchive();  // evicted and deleted scenes go
}

void JobManager::JobEnded() {
  if (!options_.persistent || restoring_ || shutting_down_) return;
  loader_->Submit([this] { PruneArchive(); });  // file I/O off the render and encoder threads
}

// Archived scenes are kept while a scene is in the store or an unfinished job names it.
void JobManager::PruneArchive() {
  if (!options_.persistent || restoring_ || shutting_down_) return;
  std::lock_guard lock(archive_mu_);
  std::set<std::string> keep;
  for (const v1::Job& j : List())
    if (!Terminal(j.state())) keep.insert(j.scene_id());
  for (const std::string& id : journal_->ListScenes()) {
    if (keep.count(id) || store_->FindExact(id)) continue;
    if (absl::Status st = journal_->RemoveScene(id); !st.ok())
      Log().warn("scene {}: archive: {}", id.substr(0, 16), st.ToString());
  }
}

void JobManager::Shutdown() {
  if (shutting_down_.exchange(true)) return;
  std::vector<std::shared_ptr<Job>> jobs;
  {
    std::lock_guard lock(mu_);
    for (auto& [id, job] : jobs_) jobs.push_back(job);
  }
  for (auto& job : jobs) job->CloseWatchers(absl::UnavailableError("server is shutting down"));
}

uint32_t JobManager::active() const {
  uint32_t n = 0;
  for (const v1::Job& j : List()) n += Terminal(j.state()) ? 0 : 1;
  return n;
}

}  // namespace tessera::server
