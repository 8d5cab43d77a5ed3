#include "server/scene_archive.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <filesystem>
#include <map>
#include <set>
#include <system_error>
#include <utility>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "common/scene_id.h"
#include "common/status_macros.h"
#include "server/fs_util.h"
#include "server/upload.h"

namespace tessera::server {
namespace {

namespace fs = std::filesystem;
using namespace files;  // NOLINT

absl::Status InvalidSceneId(const std::string& id) {
  return absl::InvalidArgumentError(
      absl::StrCat("scene id ", Quote(id), ": must be 64 lower-case hex characters"));
}

// Writes one file of a scene archive and makes its contents durable (before the rename that
// publishes the archive).
absl::Status WriteNewFile(const std::string& path, std::string_view data) {
  Fd fd(OpenRetry(path, O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600));
  if (!fd.ok()) return absl::ErrnoToStatus(errno, absl::StrCat("create ", path));
  RETURN_IF_ERROR(WriteAll(fd.get(), data, path));
  if (fsync(fd.get()) != 0) return absl::ErrnoToStatus(errno, absl::StrCat("fsync ", path));
  if (fd.Close() != 0) return absl::ErrnoToStatus(errno, absl::StrCat("close ", path));
  return absl::OkStatus();
}

// The archive layout under `root` (a fresh temporary directory): main, files/<name>...
absl::Status WriteSceneTree(const std::string& root, const GltfSource& source) {
  const std::string files_dir = root + "/files";
  if (mkdir(files_dir.c_str(), 0700) != 0)
    return absl::ErrnoToStatus(errno, absl::StrCat("mkdir ", files_dir));
  std::set<std::string> dirs = {root, files_dir};  // to fsync: their entries must be durable
  for (const auto& [name, data] : source.files) {
    // Names are valid upload names: relative, no empty, "." or ".." segments.
    for (size_t slash = name.find('/'); slash != std::string::npos;
         slash = name.find('/', slash + 1)) {
      const std::string sub = absl::StrCat(files_dir, "/", name.substr(0, slash));
      if (dirs.count(sub)) continue;
      if (mkdir(sub.c_str(), 0700) != 0) {
        if (errno == EEXIST)  // a file of that name: "a" and "a/b" in one upload
          return absl::InvalidArgumentError(
              absl::StrCat("file ", Quote(name), " needs ", Quote(name.substr(0, slash)),
                           " to be a directory, but the upload has a file of that name"));
        return absl::ErrnoToStatus(errno, absl::StrCat("mkdir ", sub));
      }
      dirs.insert(sub);
    }
    const std::string path = absl::StrCat(files_dir, "/", name);
    if (dirs.count(path))
      return absl::InvalidArgumentError(
          absl::StrCat("file ", Quote(name), " is also a directory of other files in the upload"));
    const std::string_view bytes(reinterpret_cast<const char*>(data.data()), data.size());
    RETURN_IF_ERROR(WriteNewFile(path, bytes));
  }
  RETURN_IF_ERROR(WriteNewFile(root + "/main", source.main_file));
  for (const std::string& dir : dirs) {
    RETURN_IF_ERROR(FsyncDir(dir));
  }
  return absl::OkStatus();
}

uint64_t TreeBytes(const std::string& root) {
  uint64_t total = 0;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(root, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code size_ec;
    if (!it->is_symlink(size_ec) && it->is_regular_file(size_ec)) {
      const uintmax_t size = it->file_size(size_ec);
      if (!size_ec) total += size;
    }
  }
  return total;
}

uint64_t SourceBytes(const GltfSource& source) {
  uint64_t total = 0;
  for (const auto& [name, data] : source.files) total += data.size();
  return total;
}

// Marks a scene used (its directory's modification time is never changed otherwise: a
// published scene's entries do not change).
void Touch(const std::string& dir) { utimensat(AT_FDCWD, dir.c_str(), nullptr, 0); }

}  // namespace

std::string SceneIdOf(const GltfSource& source) {
  std::map<std::string, std::string> hashes;
  for (const auto& [name, data] : source.files) hashes[name] = Sha256Hex(data.data(), data.size());
  return SceneId(hashes, source.main_file);
}

SceneArchive::SceneArchive(std::string dir, SceneArchiveOptions options)
    : dir_(std::move(dir)), options_(options) {}

absl::StatusOr<std::unique_ptr<SceneArchive>> SceneArchive::Open(
    const std::string& dir_arg, const SceneArchiveOptions& options, const std::string& what) {
  std::string dir = dir_arg;
  while (dir.size() > 1 && dir.back() == '/') dir.pop_back();
  if (dir.empty()) return absl::InvalidArgumentError(absl::StrCat(what, ": the path is empty"));
  const std::string prefix = absl::StrCat(what, " ", dir, ": ");
  if (absl::Status st = MakeDirs(dir); !st.ok()) return WithPrefix(st, prefix);
  if (absl::Status st = CheckWritable(dir); !st.ok()) return WithPrefix(st, prefix);
  // What a crash (of any process using the directory) left; errors are left for a later sweep
  // (another process may be removing the same names).
  RemoveStale(dir, /*prefix_only=*/true, options.stale_after).IgnoreError();
  return std::unique_ptr<SceneArchive>(new SceneArchive(dir, options));
}

bool SceneArchive::ValidSceneId(const std::string& id) { return IsLowerHex(id, 64); }

std::string SceneArchive::SceneDir(const std::string& scene_id) const {
  return absl::StrCat(dir_, "/", scene_id);
}

absl::Status SceneArchive::Save(const std::string& scene_id, const GltfSource& source) {
  if (!ValidSceneId(scene_id)) return InvalidSceneId(scene_id);
  const std::string prefix = absl::StrCat("scene ", scene_id, ": ");
  for (const auto& entry : source.files) {
    if (absl::Status st = ValidateUploadName(entry.first); !st.ok())
      return absl::InvalidArgumentError(absl::StrCat(prefix, st.message()));
  }
  if (!source.files.count(source.main_file))
    return absl::InvalidArgumentError(absl::StrCat(
        prefix, "the main file ", Quote(source.main_file), " is not one of its files"));
  if (Has(scene_id)) {
    Touch(SceneDir(scene_id));
    if (Has(scene_id)) return absl::OkStatus();  // else evicted meanwhile: written again
  }
  if (options_.max_bytes > 0) {
    std::lock_guard<std::mutex> lock(mu_);
    if (absl::Status st = MakeRoomLocked(SourceBytes(source), scene_id); !st.ok())
      return WithPrefix(st, prefix);
  }
  // Written outside the mutex (it can be a gigabyte, with an fsync per file) under a name of
  // its own; only the rename that publishes it is serialized.
  std::string tmp = absl::StrCat(dir_, "/", kTmpPrefix, "new-", scene_id, "-XXXXXX");
  if (mkdtemp(tmp.data()) == nullptr)
    return absl::ErrnoToStatus(errno, absl::StrCat(prefix, "mkdtemp ", tmp));
  absl::Status st = WriteSceneTree(tmp, source);
  if (st.ok()) {
    std::lock_guard<std::mutex> lock(mu_);
    const std::string final_dir = SceneDir(scene_id);
    if (rename(tmp.c_str(), final_dir.c_str()) == 0) return FsyncDir(dir_);
    // A complete archive is never an empty directory, so the rename cannot replace one; it
    // fails when another call (or replica) saved the same scene meanwhile, which is success.
    if (errno != EEXIST && errno != ENOTEMPTY)
      st = absl::ErrnoToStatus(errno, absl::StrCat("rename ", tmp, " to ", final_dir));
  }
  RemoveAll(tmp).IgnoreError();  // if this fails too, a later Open removes it
  return st.ok() ? st : WithPrefix(st, prefix);
}

bool SceneArchive::Has(const std::string& scene_id) const {
  return ValidSceneId(scene_id) && IsDirectory(SceneDir(scene_id));
}

absl::StatusOr<GltfSource> SceneArchive::Load(const std::string& scene_id,
                                              uint64_t max_bytes) const {
  if (!ValidSceneId(scene_id)) return InvalidSceneId(scene_id);
  // Not under the mutex: a scene directory is complete from the moment it has its name, and
  // one removed meanwhile makes this fail, never read a mix. The shared lock on the main file
  // keeps eviction (by any process) away until the files are read.
  const std::string dir = SceneDir(scene_id);
  const std::string main_path = dir + "/main";
  const auto not_found = [&] {
    return absl::NotFoundError(absl::StrCat("scene ", scene_id, " is not in ", dir_));
  };
  const auto damaged = [&](absl::string_view what) {
    return absl::DataLossError(
        absl::StrCat("scene ", scene_id, ": the archive ", dir, " is damaged: ", what));
  };
  struct stat st;
  if (lstat(dir.c_str(), &st) != 0) {
    if (errno == ENOENT) return not_found();
    return absl::ErrnoToStatus(errno, absl::StrCat("scene ", scene_id, ": stat ", dir));
  }
  if (!S_ISDIR(st.st_mode)) return damaged("not a directory");
  // This process's own evictions skip it (flock emulated by POSIX locks, as on NFS, does not
  // exclude within a process); marked before the lock is taken.
  LoadingMark mark(this, scene_id);
  // Only what the files say is DATA_LOSS (the caller removes such a scene): a failing open,
  // read or listing (EMFILE, EIO, ESTALE, a removal meanwhile) is reported as itself.
  Fd lock(OpenRetry(main_path, O_RDONLY | O_NOFOLLOW | O_CLOEXEC));
  if (!lock.ok()) {
    if (errno == ENOENT)
      return IsDirectory(dir) ? damaged("no main file") : not_found();  // removed meanwhile
    return absl::ErrnoToStatus(errno, absl::StrCat("scene ", scene_id, ": open ", main_path));
  }
  int locked;
  do {
    locked = flock(lock.get(), LOCK_SH);
  } while (locked != 0 && errno == EINTR);
  if (locked != 0)
    return absl::ErrnoToStatus(errno, absl::StrCat("scene ", scene_id, ": flock ", main_path));
  // Evicted between the open and the lock: the name now leads elsewhere, or nowhere.
  struct stat held, named;
  if (fstat(lock.get(), &held) != 0 || stat(main_path.c_str(), &named) != 0 ||
      held.st_ino != named.st_ino || held.st_dev != named.st_dev)
    return absl::NotFoundError(absl::StrCat("scene ", scene_id, " was removed from ", dir_,
                                            " while loading"));
  Touch(dir);
  // Upload names are at most 1024 bytes (ValidateUploadName).
  absl::StatusOr<std::string> main = ReadWholeFile(main_path, 4096);
  if (absl::IsResourceExhausted(main.status())) return damaged(main.status().message());
  if (!main.ok()) return WithPrefix(main.status(), absl::StrCat("scene ", scene_id, ": "));
  if (absl::Status valid = ValidateUploadName(*main); !valid.ok())
    return damaged(absl::StrCat("main: ", valid.message()));
  GltfSource source;
  source.main_file = *main;
  const fs::path root = dir + "/files";
  uint64_t total = 0;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(root, ec), end; !ec && it != end; it.increment(ec)) {
    const fs::file_status status = it->symlink_status(ec);
    if (ec) break;
    if (fs::is_directory(status)) continue;  // the iterator descends into it
    const std::string path = it->path().string();
    // Nothing but Save writes here, and it writes no links: one is tampering.
    if (!fs::is_regular_file(status)) return damaged(absl::StrCat(path, ": not a regular file"));
    const std::string name = it->path().lexically_relative(root).generic_string();
    if (absl::Status valid = ValidateUploadName(name); !valid.ok()) return damaged(valid.message());
    std::vector<uint8_t> data;
    absl::Status read = ReadFileInto(path, max_bytes - total, &data);
    if (absl::IsResourceExhausted(read))
      return absl::ResourceExhaustedError(absl::StrCat("scene ", scene_id,
                                                       ": its files exceed the limit of ",
                                                       max_bytes, " bytes (at ", name, ")"));
    if (!read.ok()) return WithPrefix(read, absl::StrCat("scene ", scene_id, ": "));
    total += data.size();
    source.files.emplace(name, std::move(data));
  }
  if (ec) {
    if (ec == std::errc::no_such_file_or_directory && !fs::exists(dir)) return not_found();
    if (ec == std::errc::not_a_directory || ec == std::errc::no_such_file_or_directory)
      return damaged(absl::StrCat(root.string(), ": ", ec.message()));
    return absl::UnavailableError(
        absl::StrCat("scene ", scene_id, ": cannot list ", root.string(), ": ", ec.message()));
  }
  if (!source.files.count(source.main_file))
    return damaged(absl::StrCat("the main file ", Quote(source.main_file), " is missing"));
  if (SceneIdOf(source) != scene_id)
    return damaged("its files do not hash to its id (changed or truncated on disk)");
  return source;
}

absl::Status SceneArchive::RemoveLocked(const std::string& scene_id) {
  return RemoveDirectoryByRename(dir_, scene_id);
}

absl::Status SceneArchive::Remove(const std::string& scene_id) {
  if (!ValidSceneId(scene_id)) return InvalidSceneId(scene_id);
  std::lock_guard<std::mutex> lock(mu_);
  return RemoveLocked(scene_id);
}

absl::Status SceneArchive::MakeRoomLocked(uint64_t incoming, const std::string& keep) {
  const uint64_t max = options_.max_bytes;
  if (incoming > max)
    return absl::ResourceExhaustedError(
        absl::StrCat("its ", incoming, " bytes exceed the store's limit of ", max, " bytes"));
  RemoveStale(dir_, /*prefix_only=*/true, options_.stale_after).IgnoreError();  // crashed writes take room too
  struct Entry {
    int64_t used_ns;
    std::string id;
    uint64_t bytes;
  };
  std::vector<Entry> scenes;
  uint64_t total = 0;
  for (const std::string& id : List()) {
    struct stat st;
    if (id == keep || stat(SceneDir(id).c_str(), &st) != 0) continue;
    const uint64_t bytes = TreeBytes(SceneDir(id) + "/files");
    total += bytes;
    scenes.push_back({int64_t{st.st_mtim.tv_sec} * 1000000000 + st.st_mtim.tv_nsec, id, bytes});
  }
  std::sort(scenes.begin(), scenes.end(),
            [](const Entry& a, const Entry& b) { return a.used_ns < b.used_ns; });
  for (const Entry& e : scenes) {
    if (total + incoming <= max) break;
    if (Loading(e.id)) continue;  // being loaded by this process
    // Read-write: an exclusive flock emulated by POSIX locks (NFS) needs a writable descriptor.
    Fd lock(OpenRetry(SceneDir(e.id) + "/main", O_RDWR | O_NOFOLLOW | O_CLOEXEC));
    if (!lock.ok()) continue;  // removed meanwhile
    if (flock(lock.get(), LOCK_EX | LOCK_NB) != 0) continue;  // being loaded: never evicted
    absl::StatusOr<std::string> doomed = RenameAway(dir_, e.id);
    // Closed before the files go: NFS keeps an open file as a ".nfs*" name, and the tree could
    // not be deleted.
    lock.Close();
    if (!doomed.ok()) continue;
    if (!doomed->empty()) RemoveAll(*doomed).IgnoreError();  // else a later sweep does
    total -= e.bytes;
    ++evictions_;
  }
  if (total + incoming > max)
    return absl::ResourceExhaustedError(absl::StrCat(
        "the store's limit of ", max, " bytes is reached (", total,
        " bytes in scenes being loaded or not removable) and its ", incoming,
        " bytes do not fit"));
  return absl::OkStatus();
}

std::vector<std::string> SceneArchive::List() const {
  std::vector<std::string> ids;
  absl::StatusOr<std::vector<std::string>> names = ListDir(dir_);
  if (!names.ok()) return ids;
  for (const std::string& name : *names) {
    if (ValidSceneId(name) && IsDirectory(SceneDir(name))) ids.push_back(name);
  }
  return ids;
}

uint64_t SceneArchive::Bytes(const std::string& scene_id) const {
  if (!ValidSceneId(scene_id)) return 0;
  return TreeBytes(SceneDir(scene_id) + "/files");
}

uint64_t SceneArchive::TotalBytes() const {
  uint64_t total = 0;
  for (const std::string& id : List()) total += Bytes(id);
  return total;
}

void SceneArchive::MarkUsed(const std::string& scene_id) const {
  if (ValidSceneId(scene_id)) Touch(SceneDir(scene_id));
}

bool SceneArchive::Loading(const std::string& scene_id) const {
  std::lock_guard<std::mutex> lock(loading_mu_);
  return loading_.count(scene_id) > 0;
}

SceneArchive::LoadingMark::LoadingMark(const SceneArchive* a, std::string id)
    : archive_(a), id_(std::move(id)) {
  std::lock_guard<std::mutex> lock(archive_->loading_mu_);
  archive_->loading_.insert(id_);
}

SceneArchive::LoadingMark::~LoadingMark() {
  std::lock_guard<std::mutex> lock(archive_->loading_mu_);
  archive_->loading_.erase(archive_->loading_.find(id_));
}

uint64_t SceneArchive::evictions() const {
  std::lock_guard<std::mutex> lock(mu_);
  return evictions_;
}

}  // namespace tessera::server
