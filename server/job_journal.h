#pragma once
// The --state_dir journal: render-farm jobs and the scenes they render, kept on disk so that a
// restarted tesserad resumes unfinished jobs without redoing finished frames, and can reload
// the uploaded scenes those jobs name.
//
// Every write is crash-safe against SIGKILL and power loss: whole files are replaced by rename
// (WriteFileAtomic), scenes appear by renaming a complete temporary directory into place, and
// removals rename a directory out of the way before deleting it, so a reader never sees half a
// job or half a scene. The one file that is appended to, frames.log, is self-checking line by
// line and its reader drops a torn last line.
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "renderer/scene/gltf_import.h"
#include "server/fs_util.h"
#include "server/scene_archive.h"
#include "tessera/v1/job.pb.h"

namespace tessera::server {

struct JobFrameRecord {
  uint32_t frame = 0;
  uint64_t bytes = 0;
  std::string sha256;  // hex, 64 chars
};

// The on-disk state of jobs and archived scenes under a state directory:
//   <dir>/jobs/<job_id>/job.pb       the v1::Job message (spec, state, counts), replaced atomically
//   <dir>/jobs/<job_id>/frames.log   one line per finished frame "<frame> <bytes> <sha256>\n",
//                                    appended with O_APPEND and fdatasync'd
//   <dir>/jobs/<job_id>/frames/      the encoded frames of RETURN jobs
//   <dir>/scenes/                    a SceneArchive (scene_archive.h) of the scenes jobs name
// Names starting with ".tmp-" in jobs/ and scenes/ are work in progress (a scene being written,
// a job or scene being deleted); Open removes any left by a crash.
// Thread-safe (one mutex; the calls are short file operations). The bulk of SaveScene and
// LoadScene (the file contents) runs outside the mutex, so a large scene does not hold up
// AppendFrame; they are still safe against concurrent calls because a scene directory only
// ever appears and disappears by rename.
class JobJournal {
 public:
  // Creates the directories (0700) and checks they are writable. Errors name the directory.
  static absl::StatusOr<std::unique_ptr<JobJournal>> Open(const std::string& dir);
  const std::string& dir() const { return dir_; }

  // Job ids are what the server makes: 16 lower-case hex characters. Anything else is
  // INVALID_ARGUMENT (never used as a path).
  static bool ValidJobId(const std::string& id);
  // Atomically replaces job.pb, creating the job's directory (and frames/) the first time.
  // INVALID_ARGUMENT when the message would not parse back (a string field that is not UTF-8),
  // rather than a journal entry that a restarted daemon would have to skip.
  absl::Status SaveJob(const v1::Job& job);
  // One line appended to frames.log and fdatasync'd. FAILED_PRECONDITION when the job has no
  // directory (SaveJob first); INVALID_ARGUMENT when record.sha256 is not 64 lower-case hex.
  absl::Status AppendFrame(const std::string& job_id, const JobFrameRecord& record);
  // The directory a RETURN job's frames go in (created by SaveJob). The id must be valid.
  std::string FramesDir(const std::string& job_id) const;
  struct LoadedJob {
    v1::Job job;
    std::vector<JobFrameRecord> frames;  // in log order, duplicates removed (last wins)
  };
  // Every job directory that parses, oldest first (created_unix_s, then job id). A directory
  // that does not (bad id, missing/corrupt job.pb, a job_id that is not the directory's) is
  // skipped with a line in `warnings`; a torn last line of frames.log (a crash mid-append: no
  // newline, or fields that do not parse) is ignored with a warning, and so is any malformed
  // line. A duplicate frame keeps the position of its first line and the values of its last.
  std::vector<LoadedJob> LoadJobs(std::vector<std::string>* warnings) const;
  absl::Status RemoveJob(const std::string& job_id);  // the whole directory; OK if absent

  // The scenes jobs name (SceneArchive: Save, Load, Remove, ...), without a size limit.
  static bool ValidSceneId(const std::string& id) { return SceneArchive::ValidSceneId(id); }
  absl::Status SaveScene(const std::string& scene_id, const GltfSource& source) {
    return scenes_->Save(scene_id, source);
  }
  bool HasScene(const std::string& scene_id) const { return scenes_->Has(scene_id); }
  absl::StatusOr<GltfSource> LoadScene(const std::string& scene_id, uint64_t max_bytes) const {
    return scenes_->Load(scene_id, max_bytes);
  }
  absl::Status RemoveScene(const std::string& scene_id) { return scenes_->Remove(scene_id); }
  std::vector<std::string> ListScenes() const { return scenes_->List(); }
  uint64_t SceneBytes(const std::string& scene_id) const { return scenes_->Bytes(scene_id); }

 private:
  explicit JobJournal(std::string dir);
  std::string JobDir(const std::string& job_id) const;

  const std::string dir_;
  const std::string jobs_dir_;
  std::unique_ptr<SceneArchive> scenes_;
  mutable std::mutex mu_;
};

}  // namespace tessera::server
