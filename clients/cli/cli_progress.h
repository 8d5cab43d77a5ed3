#pragma once
// The progress bar of the long commands (upload, stream, job, bench): one line on stderr,
// redrawn in place.
#include <chrono>
#include <cstdint>
#include <string>

namespace tessera::cli {

// One line on stderr, redrawn at most ten times a second:
//   "job 3f2a9c0e 45/120 [#########---------------]  37%  ETA 1m 05s  146 ms/frame"  (counts)
//   "Sponza.gltf [#########---------------]  37%  19.2 MiB / 52.0 MiB  4.1 MiB/s  ETA 8.0 s"
// Silent when stderr is not a terminal (logs and pipes get no carriage returns) or when made
// hidden; it never writes to stdout, so --json output stays one clean document. Not
// thread-safe: callers on several threads hold their own lock around it.
class ProgressBar {
 public:
  enum class Unit { kCount, kBytes };

  // `show` false: a bar that draws nothing (e.g. while a live table owns the terminal).
  ProgressBar(std::string label, uint64_t total, Unit unit = Unit::kCount, bool show = true);
  ~ProgressBar();  // Clear()
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;

  // `done` of the total so far; redrawn when the last redraw is 100 ms old, or `force`.
  void Update(uint64_t done, bool force = false);
  void set_total(uint64_t total) { total_ = total; }
  // The ETA to show (e.g. the server's estimate); 0 or less: estimated from the rate so far.
  void set_eta(double seconds) { eta_s_ = seconds; }
  // Free text after the figures ("146 ms/frame", "aa msaa"); "" for none.
  void set_note(std::string note) { note_ = std::move(note); }
  // Replaces the bar with `text` until the next Update (e.g. while the server loads a scene).
  void Say(const std::string& text);
  // Erases the line; call before printing anything else to the terminal.
  void Clear();

 private:
  using Clock = std::chrono::steady_clock;
  void Draw(const std::string& text);

  std::string label_;
  uint64_t total_;
  Unit unit_;
  bool enabled_;
  bool drawn_ = false;
  double eta_s_ = 0;
  std::string note_;
  Clock::time_point start_;
  Clock::time_point last_draw_{};
};

}  // namespace tessera::cli
