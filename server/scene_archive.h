#pragma once
// Uploaded scenes on disk, by scene id: the --state_dir journal's archive of the scenes its jobs
// render, and the --scene_store_dir store that tesserad replicas share (a directory on a
// shared volume, e.g. a ReadWriteMany PersistentVolumeClaim).
//
//   <dir>/<scene_id>/main      the main file's name
//   <dir>/<scene_id>/files/…   the uploaded files under their upload names
//
// A scene appears by renaming a complete temporary directory into place and disappears by
// renaming it out of the way before deleting it, so no reader, in this process or another
// replica's, ever sees half a scene; a crash leaves a ".tmp-*" name that Open removes once it
// is older than `stale_after`. Load checks that the files still hash to the scene id (the id
// is SHA-256 of their hashes: common/scene_id.h), so a damaged or edited archive is refused,
// never rendered.
//
// With a size limit, Save evicts the least recently used scenes (Load, Save and MarkUsed mark a
// scene used) until the new one fits. A scene being loaded, by any process, is never evicted:
// Load holds a shared flock(2) on its main file (and marks the id in this process, since flock
// emulated by POSIX locks, as on NFS, does not exclude within one), and eviction takes the
// exclusive lock without waiting and skips the scene when it cannot. Only what the files say
// is DATA_LOSS; failing I/O is reported as itself. Thread-safe, and safe for several
// processes on one directory (local file systems, NFSv4 and CephFS).
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "renderer/scene/gltf_import.h"

namespace tessera::server {

// The scene id an upload of `source` gets (common/scene_id.h over its files' SHA-256).
std::string SceneIdOf(const GltfSource& source);

struct SceneArchiveOptions {
  // Bytes of scene files the directory may hold (0: no limit). Past it Save evicts.
  uint64_t max_bytes = 0;
  // ".tmp-*" names at least this old are a crash's leftovers, removed by Open. 0 for a
  // directory only this process uses; a shared one needs longer than any Save takes.
  std::chrono::seconds stale_after{0};
};

class SceneArchive {
 public:
  // Creates the directory (0700) and checks it is writable. Errors name the directory and
  // start with `what` (e.g. "scene_store_dir").
  static absl::StatusOr<std::unique_ptr<SceneArchive>> Open(const std::string& dir,
                                                            const SceneArchiveOptions& options,
                                                            const std::string& what);
  const std::string& dir() const { return dir_; }

  // Scene ids are 64 lower-case hex characters (SHA-256); anything else is never a path.
  static bool ValidSceneId(const std::string& id);

  // Writes the file set into a temporary directory, then renames it into place. Already
  // there: OK without writing (marked used). File names are checked with ValidateUploadName
  // (server/upload.h) before they touch the file system; the main file must be one of them.
  // The id is not recomputed (the caller has it from UploadAssembler::Finish; Load checks
  // it). RESOURCE_EXHAUSTED when the scene alone is larger than max_bytes, or when it does not
  // fit and every other scene is being loaded.
  absl::Status Save(const std::string& scene_id, const GltfSource& source);
  bool Has(const std::string& scene_id) const;
  // Reads a scene back (each name re-validated; at most max_bytes in total: RESOURCE_EXHAUSTED)
  // and checks it hashes to its id. NOT_FOUND naming the id when absent or removed meanwhile;
  // DATA_LOSS when damaged (no main file, something other than files and directories, or
  // contents that do not hash to the id).
  absl::StatusOr<GltfSource> Load(const std::string& scene_id, uint64_t max_bytes) const;
  absl::Status Remove(const std::string& scene_id);  // OK if absent
  std::vector<std::string> List() const;             // sorted
  uint64_t Bytes(const std::string& scene_id) const; // 0 if absent
  uint64_t TotalBytes() const;
  uint64_t evictions() const;
  // Marks a scene used now (LRU), for a scene served from memory: its loads are rare then.
  void MarkUsed(const std::string& scene_id) const;

 private:
  SceneArchive(std::string dir, SceneArchiveOptions options);
  std::string SceneDir(const std::string& scene_id) const;
  // Makes room for `incoming` more bytes, never evicting `keep`.
  absl::Status MakeRoomLocked(uint64_t incoming, const std::string& keep);
  // Renames the scene to a fresh ".tmp-del-*" name, then deletes it.
  absl::Status RemoveLocked(const std::string& scene_id);

  // Ids this process is loading (a multiset: loads of one id may overlap).
  bool Loading(const std::string& scene_id) const;
  class LoadingMark {
   public:
    LoadingMark(const SceneArchive* archive, std::string id);
    ~LoadingMark();

   private:
    const SceneArchive* archive_;
    std::string id_;
  };

  const std::string dir_;
  const SceneArchiveOptions options_;
  mutable std::mutex mu_;  // serializes renames and eviction within the process
  uint64_t evictions_ = 0;
  mutable std::mutex loading_mu_;
  mutable std::multiset<std::string> loading_;
};

}  // namespace tessera::server
