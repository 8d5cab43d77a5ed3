#pragma once
// File-system helpers for the server's on-disk state (the --state_dir job journal and the scene
// archives): crash-safe writes, bounded reads, and errors that name the path and strerror.
#include <sys/types.h>

#include <chrono>
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace tessera::server {

// Writes `data` to `path` atomically: a temporary file in the same directory, fsync, rename,
// fsync of the directory. Errors name the path and strerror. The file gets mode 0666 less the
// umask, as a plain open(O_CREAT) would; a temporary file left by a crash is named
// ".<name>.tmp-*" (JobJournal::Open removes those in the journal).
absl::Status WriteFileAtomic(const std::string& path, std::string_view data);
// Reads a whole file; FAILED_PRECONDITION/NOT_FOUND naming the path; RESOURCE_EXHAUSTED when it is
// larger than max_bytes.
absl::StatusOr<std::string> ReadWholeFile(const std::string& path, uint64_t max_bytes);

namespace files {

// Prefix of every work-in-progress name in the journal's and the archives' directories.
inline constexpr char kTmpPrefix[] = ".tmp-";

// Debian's Abseil is built with its own string_view (ABSL_OPTION_USE_STD_STRING_VIEW 0), so
// std::string_view must be converted to pass it to absl::StrCat and friends.
inline absl::string_view Absl(std::string_view s) { return absl::string_view(s.data(), s.size()); }

// A quoted, escaped, length-capped rendering of an untrusted id or name for error messages.
std::string Quote(std::string_view s);

// Unique within the process; with the pid, unique among live processes. Used for temporary
// names that must not collide with a concurrent call.
std::string UniqueSuffix();

// Closes the descriptor on every path out of a function.
class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd();
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }
  bool ok() const { return fd_ >= 0; }
  // Closes now and reports the result: on some file systems (NFS) close is where a delayed
  // write error shows up. errno is set on failure.
  int Close();

 private:
  int fd_;
};

int OpenRetry(const std::string& path, int flags, mode_t mode = 0);
absl::Status WriteAll(int fd, std::string_view data, const std::string& path);
// Makes a rename or a new directory entry in `dir` durable: without it, a power loss after
// the rename may bring back the old name (or none).
absl::Status FsyncDir(const std::string& dir);
// "a/b/c" -> {"a/b", "c"}; "c" -> {".", "c"}; "/c" -> {"/", "c"}.
std::pair<std::string, std::string> SplitPath(const std::string& path);
// ReadWholeFile into the byte containers scene files and messages are read into, without a
// copy: NOT_FOUND / FAILED_PRECONDITION naming the path, RESOURCE_EXHAUSTED past max_bytes.
absl::Status ReadFileInto(const std::string& path, uint64_t max_bytes, std::string* out);
absl::Status ReadFileInto(const std::string& path, uint64_t max_bytes, std::vector<uint8_t>* out);
// mkdir -p, creating missing directories with mode 0700 (existing ones are left as they are).
absl::Status MakeDirs(const std::string& path);
// Creates and deletes a file in `dir`: the only sure test of writability (access(2) asks
// about the real uid and misses a full disk's inode table, for one).
absl::Status CheckWritable(const std::string& dir);
// Names (sorted) in `dir`, without "." and "..".
absl::StatusOr<std::vector<std::string>> ListDir(const std::string& dir);
bool IsDirectory(const std::string& path);  // not following a symbolic link
absl::Status RemoveAll(const std::string& path);
// In `dir`, deletes what a crash left mid-way: with `prefix_only`, every name starting with
// kTmpPrefix (whole trees); otherwise the WriteFileAtomic leftovers ".<name>.tmp-*". With
// `min_age`, only names last modified at least that long ago (a directory other processes
// write in: younger ones may be their work in progress).
absl::Status RemoveStale(const std::string& dir, bool prefix_only,
                         std::chrono::seconds min_age = std::chrono::seconds(0));
// Removes the directory `name` in `parent` so that no reader sees it half-deleted: renamed to a
// fresh ".tmp-del-*" name first (fsync'd), then deleted; a crash between leaves a name that
// RemoveStale removes. OK when it does not exist (or another process removed it first).
absl::Status RemoveDirectoryByRename(const std::string& parent, const std::string& name);
// Its first half: the directory renamed to a fresh ".tmp-del-*" name in `parent` (fsync'd),
// returned for the caller to delete; "" when it did not exist.
absl::StatusOr<std::string> RenameAway(const std::string& parent, const std::string& name);
bool IsLowerHex(const std::string& s, size_t length);
absl::Status WithPrefix(const absl::Status& st, std::string_view prefix);

}  // namespace files
}  // namespace tessera::server
