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
#include "tessera/v1/job.pb.h"

namespace tessera::server {

// Writes `data` to `path` atomically: a temporary file in the same directory, fsync, rename,
// fsync of the directory. Errors name the path and strerror. The file gets mode 0666 less the
// umask, as a plain open(O_CREAT) would; a temporary file left by a crash is named
// ".<name>.tmp-*" (JobJournal::Open removes those in the journal).
absl::Status WriteFileAtomic(const std::string& path, std::string_view data);
// Reads a whole file; FAILED_PRECONDITION/NOT_FOUND naming the path; RESOURCE_EXHAUSTED when it is
// larger than max_bytes.
absl::StatusOr<std::string> ReadWholeFile(const std::string& path, uint64_t max_bytes);

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
//   <dir>/scenes/<scene_id>/main     the main file's name
//   <dir>/scenes/<scene_id>/files/…  the uploaded files under their upload names
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

  // Scene ids are 64 lower-case hex characters (SHA-256), else INVALID_ARGUMENT.
  static bool ValidSceneId(const std::string& id);
  // Writes the file set into a temporary directory, then renames it into place (a crash
  // leaves either the old state or the complete archive; stale temporary dirs are removed by
  // Open). Already archived: OK without writing. File names are checked with
  // ValidateUploadName (from server/upload.h) before they touch the file system; the main file
  // must be one of them. The id is not recomputed from the contents (the caller has it from
  // UploadAssembler::Finish).
  absl::Status SaveScene(const std::string& scene_id, const GltfSource& source);
  bool HasScene(const std::string& scene_id) const;
  // Reads an archived file set back (each name re-validated; at most max_bytes in total:
  // RESOURCE_EXHAUSTED). NOT_FOUND naming the id when absent; DATA_LOSS when the archive is
  // damaged (no main file, or something other than files and directories in it).
  absl::StatusOr<GltfSource> LoadScene(const std::string& scene_id, uint64_t max_bytes) const;
  absl::Status RemoveScene(const std::string& scene_id);   // OK if absent
  std::vector<std::string> ListScenes() const;             // sorted
  uint64_t SceneBytes(const std::string& scene_id) const;  // 0 if absent

 private:
  explicit JobJournal(std::string dir);
  std::string JobDir(const std::string& job_id) const;
  std::string SceneDir(const std::string& scene_id) const;
  // Renames `path` (a directory under `parent`) to a fresh ".tmp-del-*" name, then deletes it:
  // a crash mid-delete leaves a name Open removes, never a half-deleted job or scene.
  absl::Status RemoveDirectory(const std::string& parent, const std::string& name);

  const std::string dir_;
  const std::string jobs_dir_;
  const std::string scenes_dir_;
  mutable std::mutex mu_;
};

}  // namespace tessera::server
