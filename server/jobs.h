#pragma once
// Render-farm jobs (proto/tessera/v1/job.proto): a camera path over a frame range, rendered on
// the render thread at background priority next to live sessions, written to files, and
// journalled (server/job_journal.h) so that a restarted daemon resumes unfinished jobs without
// redoing finished frames.
//
// A job is a RenderClient in the loop's background queue. Each turn takes the next frame not
// yet done; frames are independent (fresh view, reset temporal state), so several can be out
// on the encoders at once and any frame can be redone anywhere with the same result. The
// encoder thread that delivers a frame writes the file, appends it to the journal and tells
// the job's watchers.
//
// Lock order: a job's mu_, then its notify_mu_ (taken before mu_ is released, so watchers
// hear events in the order they happened), then a watcher channel's mutex. The manager's mu_
// may be held while taking a job's mu_, never the other way round.
#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "renderer/renderer.h"
#include "server/job_journal.h"
#include "server/render_loop.h"
#include "server/scene_store.h"
#include "tessera/v1/job.pb.h"

namespace tessera::server {

class Metrics;

// What one scene may hold: the importer's limits, and the device memory of the upload (its
// CPU estimate, checked before anything is allocated; 0 = unlimited).
struct SceneLimits {
  ImportLimits import;
  uint64_t max_device_bytes = 0;
};

struct JobManagerOptions {
  uint32_t max_jobs = 64;           // jobs kept: queued, running and finished
  uint32_t max_job_frames = 100000;  // frames in one job
  std::string output_root;           // SERVER_DIR outputs go under it; empty: not offered
  bool persistent = false;           // the journal is --state_dir (restored on restart)
  uint64_t max_scene_bytes = 1ull << 30;  // reading an archived scene back
  SceneLimits scene_limits;               // importing it
  // The scene store replicas share (--scene_store_dir), or null: scenes not in memory are
  // loaded from it as from the journal.
  SceneArchive* shared_scenes = nullptr;
};

// Where a watcher's messages go (the WatchJob reactor). Push is called with events in order;
// Close after the last one (status OK: the job finished; else why the watch ends).
class JobWatcher {
 public:
  virtual ~JobWatcher() = default;
  virtual void Push(const v1::JobProgress& progress) = 0;
  virtual void Close(const absl::Status& status) = 0;
  virtual bool closed() const = 0;  // the watch ended (client gone): dropped at the next event
};

class Job;

// The renderer views of job frames: apart from stream session ids (which count from 1).
inline constexpr uint64_t kJobViewBase = uint64_t(1) << 62;
// A new watcher hears of at most this many frames finished before it came (the last this
// daemon finished, with their timings): the WatchJob channel keeps no more for a slow reader.
inline constexpr size_t kWatchReplayFrames = 64;
// A journalled job is restored if its range has at most this many frames (the limit may have
// been lowered since it was submitted; a corrupt range must not allocate gigabytes).
inline constexpr uint32_t kRestoreFrameCap = 1u << 24;

class JobManager {
 public:
  // `journal` holds the jobs' state and RETURN frames (a temporary one when not persistent).
  JobManager(const JobManagerOptions& options, std::unique_ptr<JobJournal> journal,
             Renderer* renderer, SceneStore* store, RenderLoop* loop, ThreadPool* loader,
             Settings default_settings);
  ~JobManager();

  // Restores the journal's jobs: finished ones as records, unfinished ones queued again with
  // their done frames kept (a frame whose file is missing or truncated is redone). Then drops
  // archived scenes no unfinished job names. Lines for the log go to `log`.
  void Restore(std::vector<std::string>* log);

  absl::StatusOr<v1::Job> Submit(const v1::JobSpec& spec);
  absl::StatusOr<v1::Job> Cancel(const std::string& job_id);
  absl::Status Delete(const std::string& job_id);
  std::vector<v1::Job> List() const;
  absl::StatusOr<v1::Job> Get(const std::string& job_id) const;
  // Registers `watcher` and pushes the job's state to it first, then the events of the frames
  // already finished (the last kWatchReplayFrames; under the job's lock, so no event is
  // missed, repeated or reordered). A finished job gets these and Close(OK) at once.
  absl::Status Watch(const std::string& job_id, std::shared_ptr<JobWatcher> watcher);

  struct StoredFrame {
    uint32_t frame = 0;
    std::string path;
    uint64_t bytes = 0;
    std::string sha256;
  };
  // The files of a RETURN job's frames (NOT_FOUND naming a frame that is not done; every done
  // frame when `frames` is empty), in frame order.
  absl::StatusOr<std::vector<StoredFrame>> Frames(const std::string& job_id,
                                                  const std::vector<uint32_t>& frames) const;
  v1::ImageEncoding Encoding(const std::string& job_id) const;

  // Archives an uploaded scene's files when jobs are persistent (so a restarted daemon can
  // load it for its jobs). Cheap when already archived. Loader thread (file I/O).
  void ArchiveScene(const std::string& scene_id, const GltfSource& source);
  // Drops archived scenes that are neither in the store nor named by an unfinished job. Not
  // under the store's lock (it asks the store).
  void PruneArchive();

  // Stops taking jobs and ends every watch with UNAVAILABLE. Running jobs stay in the journal
  // as they are (a persistent daemon resumes them). Idempotent.
  void Shutdown();

  uint32_t active() const;  // queued or running
  uint64_t NewView() { return kJobViewBase | next_view_++; }  // a renderer view of its own
  const JobManagerOptions& options() const { return options_; }
  JobJournal& journal() { return *journal_; }

  // Used by Job.
  RenderLoop* loop() const { return loop_; }
  Renderer* renderer() const { return renderer_; }
  const Settings& default_settings() const { return default_settings_; }
  bool shutting_down() const { return shutting_down_; }
  void JobEnded();  // prunes the scene archive
  // A scene not in memory that LoadArchived can load: in the journal of a persistent daemon,
  // or in the shared scene store. Full ids only.
  bool HasArchived(const std::string& scene_id) const;
  // Loads an archived scene into the store (loader thread); the result goes to `done`.
  void LoadArchived(const std::string& scene_id,
                    std::function<void(absl::StatusOr<std::shared_ptr<StoredScene>>)> done);

 private:
  // The job with this id or unique prefix of kMinIdPrefix+ characters; NOT_FOUND (saying how
  // long a prefix must be when it is shorter), INVALID_ARGUMENT when ambiguous.
  absl::StatusOr<std::shared_ptr<Job>> FindJob(const std::string& job_id) const;
  absl::StatusOr<std::map<std::string, std::shared_ptr<Job>>::const_iterator> ResolveLocked(
      const std::string& job_id) const;
  absl::Status MakeRoomLocked();  // drops the oldest finished job when max_jobs are kept

  const JobManagerOptions options_;
  std::unique_ptr<JobJournal> journal_;
  Renderer* renderer_;
  SceneStore* store_;
  RenderLoop* loop_;
  ThreadPool* loader_;
  const Settings default_settings_;
  std::atomic<bool> shutting_down_{false};
  std::atomic<bool> restoring_{false};
  std::atomic<uint64_t> next_view_{1};
  mutable std::mutex mu_;
  std::map<std::string, std::shared_ptr<Job>> jobs_;  // by id
  std::vector<std::string> order_;                    // submission order
  std::mutex archive_mu_;                             // one archive prune or save at a time
};

// Parses, imports and uploads a scene and adds it to the store under `scene_id` (uploads and
// archived scenes take this one path). RESOURCE_EXHAUSTED naming the limit when the scene is
// over one of `limits`.
absl::StatusOr<std::shared_ptr<StoredScene>> LoadIntoStore(Renderer* renderer, SceneStore* store,
                                                           const std::string& scene_id,
                                                           const GltfSource& source,
                                                           const SceneLimits& limits);

// Builds the render work of frame `frame` of `spec` against a stored scene (the settings
// merged over `defaults`, the camera resolved): what a job turn and RenderJobFrame render, so
// both make the same pixels. INVALID_ARGUMENT naming the field.
absl::StatusOr<RenderWork> JobFrameWork(const v1::JobSpec& spec, uint32_t frame,
                                        const StoredScene& scene, const Settings& defaults,
                                        uint64_t view);

}  // namespace tessera::server
