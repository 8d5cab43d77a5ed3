#pragma once
// Child processes of the benchmark and soak programs (tessera-job-bench, tessera-soak): spawning
// a program with PR_SET_PDEATHSIG (no orphans, even when the parent is killed), running a
// command to its end with its stdout captured, and a set of tesserad daemons on 127.0.0.1:0
// that tell their ports through --port_file and are stopped with SIGTERM (SIGKILL past a grace).
// Plus a private temporary directory for the port files.
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace tessera::bench {

using Clock = std::chrono::steady_clock;  // as in bench_stream.h (the same alias may repeat)

inline constexpr auto kDaemonStartTimeout = std::chrono::seconds(120);
// A daemon's SIGTERM shutdown: its 3 s grace for open calls plus the device teardown.
inline constexpr auto kStopGrace = std::chrono::seconds(15);
inline constexpr auto kPoll = std::chrono::milliseconds(20);

inline double Seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

inline std::string DescribeExit(std::optional<int> status) {
  if (!status) return "still running";
  if (*status < 0) return "lost (not our child)";
  if (WIFEXITED(*status)) return absl::StrCat("exit status ", WEXITSTATUS(*status));
  if (WIFSIGNALED(*status)) return absl::StrCat("killed by signal ", WTERMSIG(*status));
  return absl::StrCat("wait status ", *status);
}

inline bool ExitedOk(std::optional<int> status) {
  return status && *status >= 0 && WIFEXITED(*status) && WEXITSTATUS(*status) == 0;
}

// Reaps `pid` when it has exited by `deadline`: its wait status (-1 when it is not our child);
// nullopt while it still runs.
inline std::optional<int> WaitExit(pid_t pid, Clock::time_point deadline) {
  for (;;) {
    int status = 0;
    const pid_t r = waitpid(pid, &status, WNOHANG);
    if (r == pid) return status;
    if (r < 0 && errno != EINTR) return -1;
    if (Clock::now() >= deadline) return std::nullopt;
    std::this_thread::sleep_for(kPoll);
  }
}

// Forks and execs argv[0] (a path) with `argv`, its stdout on `stdout_fd`, stderr shared with
// ours. The child gets SIGTERM when this process dies (PR_SET_PDEATHSIG: even a crash or a
// kill -9 of the benchmark leaves no daemon behind). Called from the main thread only: the
// signal follows the death of the thread that forked.
inline absl::StatusOr<pid_t> Spawn(const std::vector<std::string>& argv, int stdout_fd) {
  // Everything the child needs is made before the fork: between fork and exec only
  // async-signal-safe calls are allowed (gRPC's threads may hold malloc's locks).
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  sigset_t none;
  sigemptyset(&none);
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid < 0) return absl::InternalError(absl::StrCat("fork: ", std::strerror(errno)));
  if (pid == 0) {
    sigprocmask(SIG_SETMASK, &none, nullptr);
    if (prctl(PR_SET_PDEATHSIG, SIGTERM) != 0 || getppid() != parent) _exit(127);
    if (stdout_fd != STDOUT_FILENO && dup2(stdout_fd, STDOUT_FILENO) < 0) _exit(127);
    execv(args[0], args.data());
    _exit(127);
  }
  return pid;
}

// Runs a command (the CLI) to its end and returns its stdout; an error naming the command for a
// non-zero exit, or when it runs past `timeout` (then it is ended).
inline absl::StatusOr<std::string> RunCaptured(const std::vector<std::string>& argv,
                                               Clock::duration timeout, double* wall_s = nullptr) {
  const std::string command = absl::StrJoin(argv, " ");
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0)
    return absl::InternalError(absl::StrCat("pipe: ", std::strerror(errno)));
  const Clock::time_point start = Clock::now();
  const Clock::time_point deadline = start + timeout;
  absl::StatusOr<pid_t> pid = Spawn(argv, fds[1]);
  close(fds[1]);
  if (!pid.ok()) {
    close(fds[0]);
    return pid.status();
  }
  std::string out;
  bool timed_out = false;
  char buf[1 << 16];
  for (;;) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
    if (left.count() <= 0) {
      timed_out = true;
      break;
    }
    pollfd p{fds[0], POLLIN, 0};
    const int r = poll(&p, 1, int(std::min<int64_t>(left.count(), 1000)));
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) break;
    if (r == 0) continue;
    const ssize_t n = read(fds[0], buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;  // EOF: the child has closed its stdout (exited)
    out.append(buf, size_t(n));
  }
  close(fds[0]);
  if (timed_out) kill(*pid, SIGTERM);
  std::optional<int> status = WaitExit(*pid, Clock::now() + kStopGrace);
  if (!status) {
    kill(*pid, SIGKILL);
    status = WaitExit(*pid, Clock::now() + kStopGrace);
  }
  if (wall_s) *wall_s = Seconds(Clock::now() - start);
  if (timed_out)
    return absl::DeadlineExceededError(
        absl::StrCat(command, ": no result within ", Seconds(timeout), " s (ended)"));
  if (!ExitedOk(status)) {
    if (status && *status >= 0 && WIFEXITED(*status) && WEXITSTATUS(*status) == 127)
      return absl::NotFoundError(absl::StrCat(command, ": cannot run ", argv[0]));
    return absl::InternalError(absl::StrCat(command, ": ", DescribeExit(status),
                                            out.empty() ? "" : ": ", out.substr(0, 2000)));
  }
  return out;
}

// The port tesserad wrote (--port_file): "PORT\n", written in one go once it serves.
inline std::optional<int> ReadPortFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) return std::nullopt;
  std::stringstream text;
  text << in.rdbuf();
  const std::string s = text.str();
  int port = 0;
  // The newline ends the write: without it the file may be caught half-written.
  if (s.empty() || s.back() != '\n' || !absl::SimpleAtoi(absl::StripAsciiWhitespace(s), &port) ||
      port <= 0 || port > 65535)
    return std::nullopt;
  return port;
}

struct Daemon {
  pid_t pid = -1;  // -1 once reaped
  int port = 0;
  std::string port_file;
  std::string address() const { return absl::StrCat("127.0.0.1:", port); }
};

// tesserad processes of one run. Stop() ends them (SIGTERM, SIGKILL past kStopGrace) and says
// whether each exited cleanly; on every other path the destructor does the same.
class DaemonSet {
 public:
  DaemonSet() = default;
  ~DaemonSet() { (void)Stop(); }
  DaemonSet(const DaemonSet&) = delete;
  DaemonSet& operator=(const DaemonSet&) = delete;

  // Starts `n` daemons (`tesserad`, the program's path) and waits until each has written its
  // port file in `dir`. Each runs with --listen=127.0.0.1:0 --port_file=... --log_level=warn,
  // --device=`device` when not empty, then `extra_args` (which may override the ones before:
  // for absl flags the last one wins). Called from the main thread only (see Spawn).
  absl::Status Start(const std::string& tesserad, const std::string& device, uint32_t n,
                     const std::string& dir, const std::vector<std::string>& extra_args = {}) {
    // All at once: they open the device and load the demo scene side by side.
    for (uint32_t i = 0; i < n; ++i) {
      Daemon d;
      d.port_file = absl::StrCat(dir, "/tesserad-", i, ".port");
      std::vector<std::string> argv = {tesserad, "--listen=127.0.0.1:0",
                                       "--port_file=" + d.port_file, "--log_level=warn"};
      if (!device.empty()) argv.push_back("--device=" + device);
      argv.insert(argv.end(), extra_args.begin(), extra_args.end());
      // Its stdout on our stderr: our stdout carries nothing but the JSON.
      absl::StatusOr<pid_t> pid = Spawn(argv, STDERR_FILENO);
      if (!pid.ok()) return pid.status();
      d.pid = *pid;
      daemons_.push_back(d);
    }
    const Clock::time_point deadline = Clock::now() + kDaemonStartTimeout;
    for (Daemon& d : daemons_) {
      for (;;) {
        if (std::optional<int> port = ReadPortFile(d.port_file)) {
          d.port = *port;
          break;
        }
        if (std::optional<int> status = WaitExit(d.pid, Clock::now()); status) {
          d.pid = -1;
          return absl::UnavailableError(
              absl::StrCat(tesserad, " ended before serving: ", DescribeExit(status)));
        }
        if (Clock::now() >= deadline)
          return absl::DeadlineExceededError(
              absl::StrCat(tesserad, " (pid ", d.pid, ") wrote no port to ", d.port_file,
                           " within ", Seconds(kDaemonStartTimeout), " s"));
        std::this_thread::sleep_for(kPoll);
      }
    }
    return absl::OkStatus();
  }

  absl::Status Stop() {
    for (const Daemon& d : daemons_)
      if (d.pid > 0) kill(d.pid, SIGTERM);
    const Clock::time_point deadline = Clock::now() + kStopGrace;
    std::vector<std::string> problems;
    for (Daemon& d : daemons_) {
      if (d.pid <= 0) continue;
      std::optional<int> status = WaitExit(d.pid, deadline);
      if (!status) {
        kill(d.pid, SIGKILL);
        WaitExit(d.pid, Clock::now() + kStopGrace);
        problems.push_back(absl::StrCat("tesserad on port ", d.port, " was still running ",
                                        Seconds(kStopGrace), " s after SIGTERM (killed)"));
      } else if (!ExitedOk(status)) {
        problems.push_back(
            absl::StrCat("tesserad on port ", d.port, " ended with ", DescribeExit(status)));
      }
      d.pid = -1;
    }
    daemons_.clear();
    if (!problems.empty()) return absl::InternalError(absl::StrJoin(problems, "; "));
    return absl::OkStatus();
  }

  const std::vector<Daemon>& daemons() const { return daemons_; }

 private:
  std::vector<Daemon> daemons_;
};

// A private directory under $TMPDIR named PREFIX-XXXXXX, removed with everything in it at the
// end; path() is empty when it could not be made (errno says why).
class TempDir {
 public:
  explicit TempDir(const std::string& prefix) {
    namespace fs = std::filesystem;
    std::error_code ec;
    const fs::path base = fs::temp_directory_path(ec);
    std::string templ = ((ec ? fs::path("/tmp") : base) / (prefix + "-XXXXXX")).string();
    if (mkdtemp(templ.data())) path_ = templ;
  }
  ~TempDir() {
    std::error_code ec;
    if (!path_.empty()) std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

}  // namespace tessera::bench
