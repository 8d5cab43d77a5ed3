#include "server/fs_util.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <filesystem>
#include <system_error>

#include "absl/strings/escaping.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "common/status_macros.h"

namespace tessera::server {
namespace files {

namespace fs = std::filesystem;

// A quoted, escaped, length-capped rendering of an untrusted id or name for error messages.
std::string Quote(std::string_view s) {
  return absl::StrCat("\"", absl::CHexEscape(Absl(s.substr(0, 100))), s.size() > 100 ? "…" : "",
                      "\"");
}

// Unique within the process; with the pid, unique among live processes. Used for temporary
// names that must not collide with a concurrent call.
std::string UniqueSuffix() {
  static std::atomic<uint64_t> counter{0};
  return absl::StrCat(getpid(), "-", counter.fetch_add(1));
}

Fd::~Fd() {
  if (fd_ >= 0) close(fd_);
}

int Fd::Close() {
  const int fd = std::exchange(fd_, -1);
  return close(fd);
}

int OpenRetry(const std::string& path, int flags, mode_t mode) {
  int fd;
  do {
    fd = open(path.c_str(), flags, mode);
  } while (fd < 0 && errno == EINTR);
  return fd;
}

absl::Status WriteAll(int fd, std::string_view data, const std::string& path) {
  while (!data.empty()) {
    const ssize_t n = write(fd, data.data(), data.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      return absl::ErrnoToStatus(errno, absl::StrCat("write ", path));
    }
    data.remove_prefix(static_cast<size_t>(n));
  }
  return absl::OkStatus();
}

// Makes a rename or a new directory entry in `dir` durable: without it, a power loss after
// the rename may bring back the old name (or none).
absl::Status FsyncDir(const std::string& dir) {
  Fd fd(OpenRetry(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (!fd.ok()) return absl::ErrnoToStatus(errno, absl::StrCat("open directory ", dir));
  if (fsync(fd.get()) != 0) return absl::ErrnoToStatus(errno, absl::StrCat("fsync ", dir));
  return absl::OkStatus();
}

// "a/b/c" -> {"a/b", "c"}; "c" -> {".", "c"}; "/c" -> {"/", "c"}.
std::pair<std::string, std::string> SplitPath(const std::string& path) {
  const size_t slash = path.rfind('/');
  if (slash == std::string::npos) return {".", path};
  return {slash == 0 ? "/" : path.substr(0, slash), path.substr(slash + 1)};
}

namespace {

// The status of a failed read, with the codes ReadWholeFile promises.
absl::Status ReadError(int err, const std::string& what) {
  const absl::Status st = absl::ErrnoToStatus(err, what);
  if (err == ENOENT) return absl::NotFoundError(st.message());
  return absl::FailedPreconditionError(st.message());
}

}  // namespace

// ReadWholeFile into any contiguous byte container (std::string, std::vector<uint8_t>), so
// scene files are read straight into the vectors GltfSource holds, without a copy.
namespace {

template <typename Bytes>
absl::Status ReadInto(const std::string& path, uint64_t max_bytes, Bytes* out) {
  Fd fd(OpenRetry(path, O_RDONLY | O_CLOEXEC));
  if (!fd.ok()) return ReadError(errno, absl::StrCat("open ", path));
  struct stat st;
  if (fstat(fd.get(), &st) != 0) return ReadError(errno, absl::StrCat("stat ", path));
  if (!S_ISREG(st.st_mode))
    return absl::FailedPreconditionError(absl::StrCat(path, ": not a regular file"));
  const auto too_large = [&](uint64_t size) {
    return absl::ResourceExhaustedError(absl::StrCat(
        path, ": ", size, " bytes", size > static_cast<uint64_t>(st.st_size) ? " or more" : "",
        " exceed the limit of ", max_bytes, " bytes"));
  };
  const uint64_t size = static_cast<uint64_t>(st.st_size);
  if (size > max_bytes) return too_large(size);
  out->clear();
  out->resize(static_cast<size_t>(size));
  // The size from fstat is only a hint: the file may grow or shrink while it is read, so read
  // to end of file and keep the limit on what is actually read.
  uint64_t got = 0;
  for (;;) {
    if (got == out->size()) {
      if (got >= max_bytes) {
        char probe;
        ssize_t n;
        do {
          n = read(fd.get(), &probe, 1);
        } while (n < 0 && errno == EINTR);
        if (n < 0) return ReadError(errno, absl::StrCat("read ", path));
        if (n == 0) break;
        return too_large(got + 1);
      }
      const uint64_t grow = std::min<uint64_t>(max_bytes - got, std::max<uint64_t>(got, 64 << 10));
      out->resize(static_cast<size_t>(got + grow));
    }
    const ssize_t n = read(fd.get(), out->data() + got, out->size() - got);
    if (n < 0) {
      if (errno == EINTR) continue;
      return ReadError(errno, absl::StrCat("read ", path));
    }
    if (n == 0) break;
    got += static_cast<uint64_t>(n);
  }
  out->resize(static_cast<size_t>(got));
  return absl::OkStatus();
}

}  // namespace

absl::Status ReadFileInto(const std::string& path, uint64_t max_bytes, std::string* out) {
  return ReadInto(path, max_bytes, out);
}

absl::Status ReadFileInto(const std::string& path, uint64_t max_bytes, std::vector<uint8_t>* out) {
  return ReadInto(path, max_bytes, out);
}

// mkdir -p, creating missing directories with mode 0700 (existing ones are left as they are).
absl::Status MakeDirs(const std::string& path) {
  if (mkdir(path.c_str(), 0700) == 0) return absl::OkStatus();
  int err = errno;
  if (err == ENOENT) {
    const std::string parent = SplitPath(path).first;
    if (parent != path) {
      RETURN_IF_ERROR(MakeDirs(parent));
      if (mkdir(path.c_str(), 0700) == 0) return absl::OkStatus();
      err = errno;
    }
  }
  if (err == EEXIST) {
    struct stat st;
    if (stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) return absl::OkStatus();
    return absl::FailedPreconditionError(absl::StrCat(path, ": exists and is not a directory"));
  }
  return absl::ErrnoToStatus(err, absl::StrCat("mkdir ", path));
}

// Creates and deletes a file in `dir`: the only sure test of writability (access(2) asks
// about the real uid and misses a full disk's inode table, for one).
absl::Status CheckWritable(const std::string& dir) {
  const std::string probe = absl::StrCat(dir, "/", kTmpPrefix, "probe-", UniqueSuffix());
  Fd fd(OpenRetry(probe, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600));
  if (!fd.ok()) return absl::ErrnoToStatus(errno, absl::StrCat("cannot create a file in ", dir));
  fd.Close();
  if (unlink(probe.c_str()) != 0)
    return absl::ErrnoToStatus(errno, absl::StrCat("cannot delete ", probe));
  return absl::OkStatus();
}

// Names (sorted) in `dir`, without "." and "..".
absl::StatusOr<std::vector<std::string>> ListDir(const std::string& dir) {
  std::vector<std::string> names;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
    names.push_back(it->path().filename().string());
  if (ec) return absl::ErrnoToStatus(ec.value(), absl::StrCat("cannot list ", dir));
  std::sort(names.begin(), names.end());
  return names;
}

bool IsDirectory(const std::string& path) {  // not following a symbolic link
  struct stat st;
  return lstat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

absl::Status RemoveAll(const std::string& path) {
  std::error_code ec;
  fs::remove_all(path, ec);
  if (ec) return absl::ErrnoToStatus(ec.value(), absl::StrCat("cannot delete ", path));
  return absl::OkStatus();
}

// In `dir`, deletes what a crash left mid-way: with `prefix_only`, every name starting with
// kTmpPrefix (whole trees); otherwise the WriteFileAtomic leftovers ".<name>.tmp-*".
absl::Status RemoveStale(const std::string& dir, bool prefix_only, std::chrono::seconds min_age) {
  absl::StatusOr<std::vector<std::string>> names = ListDir(dir);
  if (!names.ok()) return names.status();
  const auto now = std::chrono::system_clock::now();
  for (const std::string& name : *names) {
    const bool stale = prefix_only ? absl::StartsWith(name, kTmpPrefix)
                                   : name.front() == '.' && absl::StrContains(name, ".tmp-");
    if (!stale) continue;
    const std::string path = absl::StrCat(dir, "/", name);
    struct stat st;
    if (min_age.count() > 0 &&
        (lstat(path.c_str(), &st) != 0 ||
         now - std::chrono::system_clock::from_time_t(st.st_mtime) < min_age))
      continue;
    RETURN_IF_ERROR(RemoveAll(path));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::string> RenameAway(const std::string& parent, const std::string& name) {
  const std::string path = absl::StrCat(parent, "/", name);
  struct stat st;
  if (lstat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return std::string();
    return absl::ErrnoToStatus(errno, absl::StrCat("stat ", path));
  }
  // An empty directory of a unique name that the rename replaces (POSIX allows renaming a
  // directory onto an empty one), so no leftover from an earlier failure is in the way.
  std::string doomed = absl::StrCat(parent, "/", kTmpPrefix, "del-", name, "-XXXXXX");
  if (mkdtemp(doomed.data()) == nullptr)
    return absl::ErrnoToStatus(errno, absl::StrCat("delete ", path, ": mkdtemp ", doomed));
  if (rename(path.c_str(), doomed.c_str()) != 0) {
    const int err = errno;
    rmdir(doomed.c_str());
    if (err == ENOENT) return std::string();  // another process removed it
    return absl::ErrnoToStatus(err, absl::StrCat("delete ", path, ": rename to ", doomed));
  }
  RETURN_IF_ERROR(FsyncDir(parent));
  return doomed;
}

absl::Status RemoveDirectoryByRename(const std::string& parent, const std::string& name) {
  ASSIGN_OR_RETURN(const std::string doomed, RenameAway(parent, name));
  if (doomed.empty()) return absl::OkStatus();
  // Gone already; what fails to delete here is removed at the next start.
  if (absl::Status removed = RemoveAll(doomed); !removed.ok())
    return WithPrefix(removed, absl::StrCat("delete ", parent, "/", name,
                                            " (gone; the next start retries): "));
  return absl::OkStatus();
}

bool IsLowerHex(const std::string& s, size_t length) {
  return s.size() == length && std::all_of(s.begin(), s.end(), [](char c) {
           return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
         });
}

absl::Status WithPrefix(const absl::Status& st, std::string_view prefix) {
  return absl::Status(st.code(), absl::StrCat(Absl(prefix), st.message()));
}

}  // namespace files

using namespace files;  // NOLINT: the helpers above, in this file only

absl::Status WriteFileAtomic(const std::string& path, std::string_view data) {
  const auto [dir, base] = SplitPath(path);
  if (base.empty())
    return absl::InvalidArgumentError(absl::StrCat("write ", path, ": names no file"));
  // O_EXCL on a name of our own (not mkstemp) so that the file gets 0666 less the umask, as
  // the file it replaces would have; mkstemp's are always 0600.
  std::string tmp;
  int raw = -1;
  for (int attempt = 0; raw < 0 && attempt < 100; ++attempt) {
    tmp = absl::StrCat(dir, "/.", base, ".tmp-", UniqueSuffix());
    raw = OpenRetry(tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (raw < 0 && errno != EEXIST) break;  // EEXIST: a crashed process's file, same pid
  }
  if (raw < 0)
    return absl::ErrnoToStatus(errno, absl::StrCat("write ", path, ": cannot create ", tmp));
  Fd fd(raw);
  absl::Status st = WriteAll(fd.get(), data, tmp);
  if (st.ok() && fsync(fd.get()) != 0)
    st = absl::ErrnoToStatus(errno, absl::StrCat("write ", path, ": fsync ", tmp));
  if (st.ok() && fd.Close() != 0)
    st = absl::ErrnoToStatus(errno, absl::StrCat("write ", path, ": close ", tmp));
  if (st.ok() && rename(tmp.c_str(), path.c_str()) != 0)
    st = absl::ErrnoToStatus(errno, absl::StrCat("write ", path, ": rename ", tmp));
  if (!st.ok()) {
    unlink(tmp.c_str());
    return st;
  }
  if (absl::Status synced = FsyncDir(dir); !synced.ok())
    return WithPrefix(synced, absl::StrCat("write ", path, ": "));
  return absl::OkStatus();
}

absl::StatusOr<std::string> ReadWholeFile(const std::string& path, uint64_t max_bytes) {
  std::string text;
  RETURN_IF_ERROR(ReadFileInto(path, max_bytes, &text));
  return text;
}

}  // namespace tessera::server
