#include "server/job_journal.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <system_error>
#include <utility>

#include "absl/strings/escaping.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "common/scene_id.h"
#include "common/status_macros.h"
#include "server/upload.h"

namespace tessera::server {
namespace {

namespace fs = std::filesystem;

// Larger than any real job message (a CameraList of a few hundred thousand cameras); a bigger
// job.pb is damage, not a job.
constexpr uint64_t kMaxJobPbBytes = 64ull << 20;
// About 2.7 million frame lines. A longer log is not read (with a warning): its frames are
// rendered again, which costs time but loses nothing.
constexpr uint64_t kMaxFramesLogBytes = 256ull << 20;
// Malformed frames.log lines reported one by one; the rest are counted in one warning, so a
// file of garbage does not flood the log.
constexpr int kMaxLineWarnings = 5;
// Prefix of every work-in-progress name in jobs/ and scenes/ (see JobJournal in the header).
constexpr char kTmpPrefix[] = ".tmp-";

// Debian's Abseil is built with its own string_view (ABSL_OPTION_USE_STD_STRING_VIEW 0), so
// std::string_view must be converted to pass it to absl::StrCat and friends.
absl::string_view Absl(std::string_view s) { return absl::string_view(s.data(), s.size()); }

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

// Closes the descriptor on every path out of a function.
class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }
  bool ok() const { return fd_ >= 0; }
  // Closes now and reports the result: on some file systems (NFS) close is where a delayed
  // write error shows up. errno is set on failure.
  int Close() {
    const int fd = std::exchange(fd_, -1);
    return close(fd);
  }

 private:
  int fd_;
};

int OpenRetry(const std::string& path, int flags, mode_t mode = 0) {
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

// The status of a failed read, with the codes ReadWholeFile promises.
absl::Status ReadError(int err, const std::string& what) {
  const absl::Status st = absl::ErrnoToStatus(err, what);
  if (err == ENOENT) return absl::NotFoundError(st.message());
  return absl::FailedPreconditionError(st.message());
}

// ReadWholeFile into any contiguous byte container (std::string, std::vector<uint8_t>), so
// scene files are read straight into the vectors GltfSource holds, without a copy.
template <typename Bytes>
absl::Status ReadFileInto(const std::string& path, uint64_t max_bytes, Bytes* out) {
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
absl::Status RemoveStale(const std::string& dir, bool prefix_only) {
  absl::StatusOr<std::vector<std::string>> names = ListDir(dir);
  if (!names.ok()) return names.status();
  for (const std::string& name : *names) {
    const bool stale = prefix_only ? absl::StartsWith(name, kTmpPrefix)
                                   : name.front() == '.' && absl::StrContains(name, ".tmp-");
    if (!stale) continue;
    RETURN_IF_ERROR(RemoveAll(absl::StrCat(dir, "/", name)));
  }
  return absl::OkStatus();
}

template <typename T>
std::optional<T> ParseDecimal(std::string_view s) {
  T value{};
  const char* end = s.data() + s.size();
  auto [ptr, ec] = std::from_chars(s.data(), end, value);
  if (s.empty() || ec != std::errc() || ptr != end) return std::nullopt;
  return value;
}

// "<frame> <bytes> <sha256>" (without the newline). A line cut short by a crash fails here:
// the sha256 is last and must be complete.
std::optional<JobFrameRecord> ParseFrameLine(std::string_view line) {
  const size_t a = line.find(' ');
  if (a == std::string_view::npos) return std::nullopt;
  const size_t b = line.find(' ', a + 1);
  if (b == std::string_view::npos) return std::nullopt;
  const std::optional<uint32_t> frame = ParseDecimal<uint32_t>(line.substr(0, a));
  const std::optional<uint64_t> bytes = ParseDecimal<uint64_t>(line.substr(a + 1, b - a - 1));
  const std::string_view sha = line.substr(b + 1);
  if (!frame || !bytes || !IsSha256Hex(sha)) return std::nullopt;
  return JobFrameRecord{*frame, *bytes, std::string(sha)};
}

std::vector<JobFrameRecord> ParseFramesLog(const std::string& path, std::string_view text,
                                           std::vector<std::string>* warnings) {
  std::vector<JobFrameRecord> frames;
  std::map<uint32_t, size_t> index;  // frame -> position in `frames`
  int malformed = 0;
  size_t line_no = 0;
  for (size_t start = 0; start < text.size();) {
    ++line_no;
    const size_t nl = text.find('\n', start);
    if (nl == std::string_view::npos) {
      // Even a line that parses is dropped: without its newline it was not known to be
      // complete when the daemon stopped (AppendFrame ends this fragment before appending).
      warnings->push_back(absl::StrCat(path, ":", line_no,
                                       ": last line has no newline (torn by a crash "
                                       "mid-append); ignored, its frame is rendered again"));
      break;
    }
    const std::string_view line = text.substr(start, nl - start);
    start = nl + 1;
    const std::optional<JobFrameRecord> record = ParseFrameLine(line);
    if (!record) {
      if (++malformed <= kMaxLineWarnings)
        warnings->push_back(absl::StrCat(path, ":", line_no, ": malformed line ", Quote(line),
                                         " (expected \"<frame> <bytes> <sha256>\"); ignored"));
      continue;
    }
    auto [it, inserted] = index.emplace(record->frame, frames.size());
    if (inserted) {
      frames.push_back(*record);
    } else {
      frames[it->second] = *record;  // a frame rendered again: the later line wins
    }
  }
  if (malformed > kMaxLineWarnings)
    warnings->push_back(
        absl::StrCat(path, ": ", malformed - kMaxLineWarnings, " more malformed lines ignored"));
  return frames;
}

absl::Status InvalidJobId(const std::string& id) {
  return absl::InvalidArgumentError(
      absl::StrCat("job id ", Quote(id), ": must be 16 lower-case hex characters"));
}

absl::Status InvalidSceneId(const std::string& id) {
  return absl::InvalidArgumentError(
      absl::StrCat("scene id ", Quote(id), ": must be 64 lower-case hex characters"));
}

bool IsLowerHex(const std::string& s, size_t length) {
  return s.size() == length && std::all_of(s.begin(), s.end(), [](char c) {
           return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
         });
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

absl::Status WithPrefix(const absl::Status& st, std::string_view prefix) {
  return absl::Status(st.code(), absl::StrCat(Absl(prefix), st.message()));
}

}  // namespace

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

JobJournal::JobJournal(std::string dir)
    : dir_(std::move(dir)), jobs_dir_(dir_ + "/jobs"), scenes_dir_(dir_ + "/scenes") {}

absl::StatusOr<std::unique_ptr<JobJournal>> JobJournal::Open(const std::string& dir_arg) {
  std::string dir = dir_arg;
  while (dir.size() > 1 && dir.back() == '/') dir.pop_back();
  if (dir.empty()) return absl::InvalidArgumentError("state directory: the path is empty");
  const std::string prefix = absl::StrCat("state directory ", dir, ": ");
  std::unique_ptr<JobJournal> journal(new JobJournal(dir));
  for (const std::string& d : {journal->dir_, journal->jobs_dir_, journal->scenes_dir_}) {
    if (absl::Status st = MakeDirs(d); !st.ok()) return WithPrefix(st, prefix);
  }
  for (const std::string& d : {journal->jobs_dir_, journal->scenes_dir_}) {
    if (absl::Status st = CheckWritable(d); !st.ok()) return WithPrefix(st, prefix);
  }
  // What a crash left mid-way: scenes being written, jobs and scenes being deleted, and
  // temporary files of WriteFileAtomic in job directories (job.pb, and frames a caller wrote
  // with it). Nothing else runs on the directory yet, so none of it is in use.
  for (const std::string& d : {journal->jobs_dir_, journal->scenes_dir_}) {
    if (absl::Status st = RemoveStale(d, /*prefix_only=*/true); !st.ok())
      return WithPrefix(st, prefix);
  }
  absl::StatusOr<std::vector<std::string>> jobs = ListDir(journal->jobs_dir_);
  if (!jobs.ok()) return WithPrefix(jobs.status(), prefix);
  for (const std::string& id : *jobs) {
    const std::string job_dir = journal->JobDir(id);
    if (!ValidJobId(id) || !IsDirectory(job_dir)) continue;  // LoadJobs reports these
    for (const std::string& d : {job_dir, job_dir + "/frames"}) {
      if (!IsDirectory(d)) continue;
      if (absl::Status st = RemoveStale(d, /*prefix_only=*/false); !st.ok())
        return WithPrefix(st, prefix);
    }
  }
  return journal;
}

bool JobJournal::ValidJobId(const std::string& id) { return IsLowerHex(id, 16); }

bool JobJournal::ValidSceneId(const std::string& id) { return IsLowerHex(id, 64); }

std::string JobJournal::JobDir(const std::string& job_id) const {
  return absl::StrCat(jobs_dir_, "/", job_id);
}

std::string JobJournal::SceneDir(const std::string& scene_id) const {
  return absl::StrCat(scenes_dir_, "/", scene_id);
}

std::string JobJournal::FramesDir(const std::string& job_id) const {
  // An invalid id never becomes a path; "" makes any use of it fail rather than land
  // somewhere unintended.
  if (!ValidJobId(job_id)) return "";
  return JobDir(job_id) + "/frames";
}

absl::Status JobJournal::SaveJob(const v1::Job& job) {
  const std::string& id = job.job_id();
  if (!ValidJobId(id)) return InvalidJobId(id);
  std::string bytes;
  if (!job.SerializeToString(&bytes))
    return absl::InternalError(absl::StrCat("job ", id, ": cannot serialize the Job message"));
  // proto3 refuses to parse a string field that is not UTF-8 but serializes one (with a log
  // line). Such a job.pb would be skipped after a restart: better to say so now.
  v1::Job parsed;
  if (!parsed.ParseFromString(bytes))
    return absl::InvalidArgumentError(
        absl::StrCat("job ", id,
                     ": the Job message does not parse back once serialized (a string field "
                     "that is not UTF-8?); not journalled"));
  std::lock_guard<std::mutex> lock(mu_);
  const std::string job_dir = JobDir(id);
  bool created = false;
  for (const std::string& d : {job_dir, job_dir + "/frames"}) {
    if (mkdir(d.c_str(), 0700) == 0) {
      created = true;
    } else if (errno != EEXIST) {
      return absl::ErrnoToStatus(errno, absl::StrCat("job ", id, ": mkdir ", d));
    }
  }
  RETURN_IF_ERROR(WriteFileAtomic(job_dir + "/job.pb", bytes));
  // A new job's directory entry in jobs/ (WriteFileAtomic synced the job's own directory).
  if (created) return FsyncDir(jobs_dir_);
  return absl::OkStatus();
}

absl::Status JobJournal::AppendFrame(const std::string& job_id, const JobFrameRecord& record) {
  if (!ValidJobId(job_id)) return InvalidJobId(job_id);
  // Checked here so that every line written parses back.
  if (!IsSha256Hex(record.sha256))
    return absl::InvalidArgumentError(absl::StrCat("job ", job_id, " frame ", record.frame,
                                                   ": sha256 ", Quote(record.sha256),
                                                   " is not 64 lower-case hex characters"));
  std::lock_guard<std::mutex> lock(mu_);
  const std::string job_dir = JobDir(job_id);
  if (!IsDirectory(job_dir))
    return absl::FailedPreconditionError(
        absl::StrCat("job ", job_id, ": no journal directory ", job_dir, " (SaveJob first)"));
  const std::string path = job_dir + "/frames.log";
  Fd fd(OpenRetry(path, O_RDWR | O_APPEND | O_CREAT | O_CLOEXEC, 0600));
  if (!fd.ok()) return absl::ErrnoToStatus(errno, absl::StrCat("open ", path));
  struct stat st;
  if (fstat(fd.get(), &st) != 0) return absl::ErrnoToStatus(errno, absl::StrCat("stat ", path));
  // A line torn by an earlier crash would run into this one and could make a different but
  // well-formed line ("1" + "2 100 <sha>" reads as frame 12). Ending the fragment first keeps
  // it a malformed line of its own, which LoadJobs skips.
  bool torn = false;
  if (st.st_size > 0) {
    char last = '\n';
    ssize_t n;
    do {
      n = pread(fd.get(), &last, 1, st.st_size - 1);
    } while (n < 0 && errno == EINTR);
    if (n < 0) return absl::ErrnoToStatus(errno, absl::StrCat("read ", path));
    torn = n == 1 && last != '\n';
  }
  const std::string line =
      absl::StrCat(torn ? "\n" : "", record.frame, " ", record.bytes, " ", record.sha256, "\n");
  // One write: a crash can cut the line short but not interleave it with another.
  RETURN_IF_ERROR(WriteAll(fd.get(), line, path));
  if (fdatasync(fd.get()) != 0) return absl::ErrnoToStatus(errno, absl::StrCat("fdatasync ", path));
  if (fd.Close() != 0) return absl::ErrnoToStatus(errno, absl::StrCat("close ", path));
  // The first line created the file: its directory entry must be durable too.
  if (st.st_size == 0) return FsyncDir(job_dir);
  return absl::OkStatus();
}

std::vector<JobJournal::LoadedJob> JobJournal::LoadJobs(std::vector<std::string>* warnings) const {
  std::vector<std::string> ignored;
  if (warnings == nullptr) warnings = &ignored;
  std::vector<LoadedJob> jobs;
  std::lock_guard<std::mutex> lock(mu_);
  absl::StatusOr<std::vector<std::string>> names = ListDir(jobs_dir_);
  if (!names.ok()) {
    warnings->push_back(absl::StrCat(names.status().message(), "; no job is resumed"));
    return jobs;
  }
  for (const std::string& name : *names) {
    if (absl::StartsWith(name, kTmpPrefix)) continue;  // being deleted (Open removes these)
    const std::string job_dir = absl::StrCat(jobs_dir_, "/", name);
    if (!ValidJobId(name)) {
      warnings->push_back(
          absl::StrCat(job_dir,
                       ": not a job directory (the name is not 16 lower-case hex characters); "
                       "skipped"));
      continue;
    }
    if (!IsDirectory(job_dir)) {
      warnings->push_back(absl::StrCat(job_dir, ": not a directory; skipped"));
      continue;
    }
    const std::string pb_path = job_dir + "/job.pb";
    absl::StatusOr<std::string> pb = ReadWholeFile(pb_path, kMaxJobPbBytes);
    if (!pb.ok()) {
      warnings->push_back(absl::StrCat(pb.status().message(), "; job ", name, " skipped"));
      continue;
    }
    LoadedJob loaded;
    if (!loaded.job.ParseFromString(*pb)) {
      warnings->push_back(absl::StrCat(pb_path, ": does not parse as a tessera.v1.Job (",
                                       pb->size(), " bytes, corrupt); job ", name, " skipped"));
      continue;
    }
    if (loaded.job.job_id() != name) {
      warnings->push_back(absl::StrCat(pb_path, ": holds job id ", Quote(loaded.job.job_id()),
                                       ", not its directory's; job ", name, " skipped"));
      continue;
    }
    const std::string log_path = job_dir + "/frames.log";
    absl::StatusOr<std::string> log = ReadWholeFile(log_path, kMaxFramesLogBytes);
    if (log.ok()) {
      loaded.frames = ParseFramesLog(log_path, *log, warnings);
    } else if (!absl::IsNotFound(log.status())) {  // absent: no frame finished yet
      warnings->push_back(
          absl::StrCat(log.status().message(), "; job ", name, " resumes with no frame done"));
    }
    jobs.push_back(std::move(loaded));
  }
  std::stable_sort(jobs.begin(), jobs.end(), [](const LoadedJob& a, const LoadedJob& b) {
    return a.job.created_unix_s() < b.job.created_unix_s();  // ties: by id (the listing order)
  });
  return jobs;
}

absl::Status JobJournal::RemoveDirectory(const std::string& parent, const std::string& name) {
  const std::string path = absl::StrCat(parent, "/", name);
  struct stat st;
  if (lstat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return absl::OkStatus();
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
    if (err == ENOENT) return absl::OkStatus();
    return absl::ErrnoToStatus(err, absl::StrCat("delete ", path, ": rename to ", doomed));
  }
  RETURN_IF_ERROR(FsyncDir(parent));
  // Gone from the journal already; what fails to delete here is removed by the next Open.
  if (absl::Status removed = RemoveAll(doomed); !removed.ok())
    return WithPrefix(removed, absl::StrCat("delete ", path,
                                            " (removed from the journal; the next start "
                                            "retries): "));
  return absl::OkStatus();
}

absl::Status JobJournal::RemoveJob(const std::string& job_id) {
  if (!ValidJobId(job_id)) return InvalidJobId(job_id);
  std::lock_guard<std::mutex> lock(mu_);
  return RemoveDirectory(jobs_dir_, job_id);
}

absl::Status JobJournal::SaveScene(const std::string& scene_id, const GltfSource& source) {
  if (!ValidSceneId(scene_id)) return InvalidSceneId(scene_id);
  const std::string prefix = absl::StrCat("scene ", scene_id, ": ");
  for (const auto& entry : source.files) {
    if (absl::Status st = ValidateUploadName(entry.first); !st.ok())
      return absl::InvalidArgumentError(absl::StrCat(prefix, st.message()));
  }
  if (!source.files.count(source.main_file))
    return absl::InvalidArgumentError(absl::StrCat(
        prefix, "the main file ", Quote(source.main_file), " is not one of its files"));
  if (HasScene(scene_id)) return absl::OkStatus();
  // Written outside the mutex (it can be a gigabyte, with an fsync per file) under a name of
  // its own; only the rename that publishes it is serialized.
  std::string tmp = absl::StrCat(scenes_dir_, "/", kTmpPrefix, "new-", scene_id, "-XXXXXX");
  if (mkdtemp(tmp.data()) == nullptr)
    return absl::ErrnoToStatus(errno, absl::StrCat(prefix, "mkdtemp ", tmp));
  absl::Status st = WriteSceneTree(tmp, source);
  if (st.ok()) {
    std::lock_guard<std::mutex> lock(mu_);
    const std::string final_dir = SceneDir(scene_id);
    if (rename(tmp.c_str(), final_dir.c_str()) == 0) return FsyncDir(scenes_dir_);
    // A complete archive is never an empty directory, so the rename cannot replace one; it
    // fails when another call archived the same scene meanwhile, which is success.
    if (errno != EEXIST && errno != ENOTEMPTY)
      st = absl::ErrnoToStatus(errno, absl::StrCat("rename ", tmp, " to ", final_dir));
  }
  RemoveAll(tmp).IgnoreError();  // if this fails too, Open removes it
  return st.ok() ? st : WithPrefix(st, prefix);
}

bool JobJournal::HasScene(const std::string& scene_id) const {
  if (!ValidSceneId(scene_id)) return false;
  std::lock_guard<std::mutex> lock(mu_);
  return IsDirectory(SceneDir(scene_id));
}

absl::StatusOr<GltfSource> JobJournal::LoadScene(const std::string& scene_id,
                                                 uint64_t max_bytes) const {
  if (!ValidSceneId(scene_id)) return InvalidSceneId(scene_id);
  // Not under the mutex, like SaveScene's writing: a scene directory is complete from the
  // moment it has its name, and a RemoveScene meanwhile makes this fail, not read a mix.
  const std::string dir = SceneDir(scene_id);
  struct stat st;
  if (lstat(dir.c_str(), &st) != 0) {
    if (errno == ENOENT)
      return absl::NotFoundError(
          absl::StrCat("scene ", scene_id, " is not archived (no ", dir, ")"));
    return absl::ErrnoToStatus(errno, absl::StrCat("scene ", scene_id, ": stat ", dir));
  }
  const auto damaged = [&](absl::string_view what) {
    return absl::DataLossError(
        absl::StrCat("scene ", scene_id, ": the archive ", dir, " is damaged: ", what));
  };
  if (!S_ISDIR(st.st_mode)) return damaged("not a directory");
  // Upload names are at most 1024 bytes (ValidateUploadName).
  absl::StatusOr<std::string> main = ReadWholeFile(dir + "/main", 4096);
  if (!main.ok()) return damaged(main.status().message());
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
    // Nothing but SaveScene writes here, and it writes no links: one is tampering.
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
    if (ec == std::errc::no_such_file_or_directory && !fs::exists(dir))
      return absl::NotFoundError(absl::StrCat("scene ", scene_id, " was removed while loading"));
    return damaged(absl::StrCat("cannot list ", root.string(), ": ", ec.message()));
  }
  if (!source.files.count(source.main_file))
    return damaged(absl::StrCat("the main file ", Quote(source.main_file), " is missing"));
  return source;
}

absl::Status JobJournal::RemoveScene(const std::string& scene_id) {
  if (!ValidSceneId(scene_id)) return InvalidSceneId(scene_id);
  std::lock_guard<std::mutex> lock(mu_);
  return RemoveDirectory(scenes_dir_, scene_id);
}

std::vector<std::string> JobJournal::ListScenes() const {
  std::vector<std::string> ids;
  std::lock_guard<std::mutex> lock(mu_);
  absl::StatusOr<std::vector<std::string>> names = ListDir(scenes_dir_);
  if (!names.ok()) return ids;
  for (const std::string& name : *names) {
    if (ValidSceneId(name) && IsDirectory(SceneDir(name))) ids.push_back(name);
  }
  return ids;
}

uint64_t JobJournal::SceneBytes(const std::string& scene_id) const {
  if (!ValidSceneId(scene_id)) return 0;
  std::lock_guard<std::mutex> lock(mu_);
  uint64_t total = 0;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(SceneDir(scene_id) + "/files", ec), end;
       !ec && it != end; it.increment(ec)) {
    std::error_code size_ec;
    if (!it->is_symlink(size_ec) && it->is_regular_file(size_ec)) {
      const uintmax_t size = it->file_size(size_ec);
      if (!size_ec) total += size;
    }
  }
  return total;
}

}  // namespace tessera::server
