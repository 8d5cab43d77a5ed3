#include "clients/cli/cli_progress.h"

#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "clients/cli/cli_common.h"

namespace tessera::cli {

namespace {

// The terminal's width, or 0 when unknown.
size_t TerminalColumns() {
  winsize ws{};
  if (ioctl(STDERR_FILENO, TIOCGWINSZ, &ws) != 0) return 0;
  return ws.ws_col;
}

}  // namespace

ProgressBar::ProgressBar(std::string label, uint64_t total, Unit unit, bool show)
    : label_(std::move(label)),
      total_(total),
      unit_(unit),
      enabled_(show && StderrIsTty()),
      start_(Clock::now()) {
  constexpr size_t kMaxLabel = 32;
  if (label_.size() > kMaxLabel) label_ = "..." + label_.substr(label_.size() - kMaxLabel + 3);
}

ProgressBar::~ProgressBar() { Clear(); }

void ProgressBar::Update(uint64_t done, bool force) {
  if (!enabled_) return;
  const Clock::time_point now = Clock::now();
  if (!force && now - last_draw_ < std::chrono::milliseconds(100)) return;
  last_draw_ = now;

  constexpr int kWidth = 24;
  const double fraction = total_ ? std::min(1.0, double(done) / double(total_)) : 1.0;
  const int filled = static_cast<int>(fraction * kWidth);
  const double seconds = std::max(1e-6, std::chrono::duration<double>(now - start_).count());
  std::string line = label_;
  if (unit_ == Unit::kCount) absl::StrAppend(&line, " ", done, "/", total_);
  absl::StrAppendFormat(&line, " [%s%s] %3.0f%%", std::string(filled, '#'),
                        std::string(kWidth - filled, '-'), fraction * 100);
  if (unit_ == Unit::kBytes) {
    absl::StrAppendFormat(&line, "  %s / %s  %.1f MiB/s", HumanBytes(done), HumanBytes(total_),
                          done / seconds / (1024.0 * 1024.0));
  }
  // The rate so far predicts the rest, unless the caller knows better.
  double eta = eta_s_;
  if (eta <= 0 && done > 0 && done < total_) eta = seconds / double(done) * double(total_ - done);
  if (eta > 0) absl::StrAppend(&line, "  ETA ", HumanDuration(eta));
  if (!note_.empty()) absl::StrAppend(&line, "  ", note_);
  Draw(line);
}

void ProgressBar::Say(const std::string& text) {
  if (enabled_) Draw(absl::StrCat(label_, " ", text));
}

void ProgressBar::Draw(const std::string& text) {
  // A line longer than the terminal would wrap, and every redraw would start a new line.
  const size_t columns = TerminalColumns();
  const std::string line =
      columns > 1 && text.size() >= columns ? text.substr(0, columns - 1) : text;
  std::fprintf(stderr, "\r\033[K%s", line.c_str());
  std::fflush(stderr);
  drawn_ = true;
}

void ProgressBar::Clear() {
  if (drawn_) std::fputs("\r\033[K", stderr);
  drawn_ = false;
}

}  // namespace tessera::cli
