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
#include "server/fs_util.h"
#include "server/upload.h"

namespace tessera::server {
namespace {

namespace fs = std::filesystem;
using namespace files;  // NOLINT

// Larger than any real job message (a CameraList of a few hundred thousand cameras); a bigger
// job.pb is damage, not a job.
constexpr uint64_t kMaxJobPbBytes = 64ull << 20;
// About 2.7 million frame lines. A longer log is not read (with a warning): its frames are
// rendered again, which costs time but loses nothing.
constexpr uint64_t kMaxFramesLogBytes = 256ull << 20;
// Malformed frames.log lines reported one by one; the rest are counted in one warning, so a
// file of garbage does not flood the log.
constexpr int kMaxLineWarnings = 5;

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

}  // namespace

JobJournal::JobJournal(std::string dir)
    : dir_(std::move(dir)), jobs_dir_(dir_ + "/jobs") {}

absl::StatusOr<std::unique_ptr<JobJournal>> JobJournal::Open(const std::string& dir_arg) {
  std::string dir = dir_arg;
  while (dir.size() > 1 && dir.back() == '/') dir.pop_back();
  if (dir.empty()) return absl::InvalidArgumentError("state directory: the path is empty");
  const std::string prefix = absl::StrCat("state directory ", dir, ": ");
  std::unique_ptr<JobJournal> journal(new JobJournal(dir));
  for (const std::string& d : {journal->dir_, journal->jobs_dir_}) {
    if (absl::Status st = MakeDirs(d); !st.ok()) return WithPrefix(st, prefix);
  }
  if (absl::Status st = CheckWritable(journal->jobs_dir_); !st.ok()) return WithPrefix(st, prefix);
  // What a crash left mid-way: jobs being deleted, and temporary files of WriteFileAtomic in
  // job directories (job.pb, and frames a caller wrote with it); the scene archive removes its
  // own (scenes being written or deleted). Nothing else runs on the directory yet, so none of
  // it is in use.
  if (absl::Status st = RemoveStale(journal->jobs_dir_, /*prefix_only=*/true); !st.ok())
    return WithPrefix(st, prefix);
  absl::StatusOr<std::unique_ptr<SceneArchive>> scenes =
      SceneArchive::Open(dir + "/scenes", SceneArchiveOptions{}, "state directory");
  if (!scenes.ok()) return scenes.status();
  journal->scenes_ = *std::move(scenes);
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

std::string JobJournal::JobDir(const std::string& job_id) const {
  return absl::StrCat(jobs_dir_, "/", job_id);
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

absl::Status JobJournal::RemoveJob(const std::string& job_id) {
  if (!ValidJobId(job_id)) return InvalidJobId(job_id);
  std::lock_guard<std::mutex> lock(mu_);
  return RemoveDirectoryByRename(jobs_dir_, job_id);
}

}  // namespace tessera::server
