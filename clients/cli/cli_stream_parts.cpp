#include "clients/cli/cli_stream_parts.h"

#include <algorithm>
#include <cmath>
#include <csignal>

namespace tessera::cli {

// ---------------------------------------------------------------------------------------------
// Orbit

Orbit Orbit::FromBounds(const v1::Aabb& bounds, float yfov, float aspect) {
  Orbit o;
  const float mn[3] = {bounds.min().x(), bounds.min().y(), bounds.min().z()};
  const float mx[3] = {bounds.max().x(), bounds.max().y(), bounds.max().z()};
  float radius2 = 0;
  bool valid = true;
  for (int i = 0; i < 3; ++i) {
    if (!(mx[i] >= mn[i]) || !std::isfinite(mn[i]) || !std::isfinite(mx[i])) valid = false;
    o.centre_[i] = valid ? 0.5f * (mn[i] + mx[i]) : 0.0f;
    radius2 += 0.25f * (mx[i] - mn[i]) * (mx[i] - mn[i]);
  }
  // An empty scene has an inverted box; any small orbit around the origin will do.
  float radius = valid ? std::sqrt(radius2) : 1.0f;
  if (!(radius > 1e-6f)) radius = 1.0f;
  // The sphere around the box fits the narrower of the two fields of view from any angle, so
  // the scene stays in view all the way round.
  const float hfov = 2.0f * std::atan(std::tan(0.5f * yfov) * aspect);
  const float half_fov = 0.5f * std::min(yfov, hfov);
  o.distance_ = 1.05f * radius / std::sin(half_fov);
  // The server's default framing direction (FrameBounds in scene.proto), so the first frame
  // looks like `tessera render` without a camera.
  const float d[3] = {0.55f, 0.45f, 0.70f};
  const float len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  o.elevation_ = std::asin(d[1] / len);
  o.azimuth_ = std::atan2(d[0], d[2]);
  return o;
}

Orbit Orbit::FromLookAt(const v1::LookAt& look_at) {
  Orbit o;
  const v1::Vec3& t = look_at.target();
  const v1::Vec3& e = look_at.eye();
  o.centre_[0] = t.x();
  o.centre_[1] = t.y();
  o.centre_[2] = t.z();
  const float d[3] = {e.x() - t.x(), e.y() - t.y(), e.z() - t.z()};
  const float len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  o.distance_ = len > 1e-6f ? len : 1.0f;
  // Straight above or below, "up" would be parallel to the view direction.
  constexpr float kMaxElevation = 1.48f;  // ~85 degrees
  o.elevation_ =
      std::clamp(len > 1e-6f ? std::asin(d[1] / len) : 0.0f, -kMaxElevation, kMaxElevation);
  o.azimuth_ = std::atan2(d[0], d[2]);
  return o;
}

v1::Camera Orbit::CameraAt(uint64_t step, uint64_t steps_per_turn, const v1::Camera& base) const {
  const double turn = double(step % std::max<uint64_t>(1, steps_per_turn)) /
                      double(std::max<uint64_t>(1, steps_per_turn));
  const float azimuth = azimuth_ + static_cast<float>(2 * M_PI * turn);
  v1::Camera camera;
  if (base.has_yfov()) camera.set_yfov(base.yfov());
  if (base.has_znear()) camera.set_znear(base.znear());
  if (base.has_zfar()) camera.set_zfar(base.zfar());
  v1::LookAt* l = camera.mutable_look_at();
  l->mutable_eye()->set_x(centre_[0] + distance_ * std::cos(elevation_) * std::sin(azimuth));
  l->mutable_eye()->set_y(centre_[1] + distance_ * std::sin(elevation_));
  l->mutable_eye()->set_z(centre_[2] + distance_ * std::cos(elevation_) * std::cos(azimuth));
  l->mutable_target()->set_x(centre_[0]);
  l->mutable_target()->set_y(centre_[1]);
  l->mutable_target()->set_z(centre_[2]);
  l->mutable_up()->set_y(1);
  return camera;
}

// ---------------------------------------------------------------------------------------------
// LatencyTracker

void LatencyTracker::Sent(uint64_t event_id, Clock::time_point when) {
  std::lock_guard<std::mutex> lock(mu_);
  pending_[event_id] = when;
}

std::vector<std::pair<uint64_t, double>> LatencyTracker::Answered(uint64_t event_id,
                                                                  Clock::time_point now) {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<std::pair<uint64_t, double>> out;
  auto it = pending_.begin();
  for (; it != pending_.end() && it->first <= event_id; ++it) {
    out.emplace_back(it->first,
                     std::chrono::duration<double, std::milli>(now - it->second).count());
  }
  pending_.erase(pending_.begin(), it);
  return out;
}

// ---------------------------------------------------------------------------------------------
// EventWriter

namespace {
constexpr std::chrono::milliseconds kPoll{100};  // how often Ctrl-C and the close guard are seen
}  // namespace

EventWriter::EventWriter(grpc::ClientContext* context,
                         grpc::ClientReaderWriter<v1::ClientEvent, v1::Frame>* stream,
                         LatencyTracker* latency, EventSource next_event,
                         std::optional<std::chrono::duration<double>> period)
    : context_(context), stream_(stream), latency_(latency), next_event_(std::move(next_event)) {
  if (period) period_ = std::chrono::duration_cast<Clock::duration>(*period);
}

EventWriter::~EventWriter() { Join(); }

bool EventWriter::Send(const v1::ClientEvent& event) {
  // Stamped before the write: the latency includes the time the event spends on the wire.
  latency_->Sent(event.event_id(), Clock::now());
  if (stream_->Write(event)) return true;
  write_failed_ = true;
  return false;
}

bool EventWriter::WriteNow(const v1::ClientEvent& event) { return Send(event); }

void EventWriter::Start() {
  next_tick_ = period_ ? Clock::now() + *period_ : Clock::now();
  thread_ = std::thread([this] { Loop(); });
}

void EventWriter::RequestEvent() {
  std::lock_guard<std::mutex> lock(mu_);
  ++requested_;
  cv_.notify_all();
}

void EventWriter::Close() {
  std::lock_guard<std::mutex> lock(mu_);
  closing_ = true;
  cv_.notify_all();
}

void EventWriter::Join() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    closing_ = true;
    joined_ = true;
    cv_.notify_all();
  }
  if (thread_.joinable()) thread_.join();
}

bool EventWriter::WaitForWork(std::unique_lock<std::mutex>& lock) {
  while (true) {
    if (closing_) return false;
    if (InterruptHandler::interrupted()) {
      context_->TryCancel();
      return false;
    }
    if (requested_ > 0) {
      --requested_;
      return true;
    }
    const Clock::time_point now = Clock::now();
    if (period_ && now >= next_tick_) {
      // Behind schedule (a slow write): skip the missed ticks instead of bursting.
      next_tick_ = std::max(next_tick_ + *period_, now);
      return true;
    }
    cv_.wait_until(lock, period_ ? std::min(next_tick_, now + kPoll) : now + kPoll);
  }
}

void EventWriter::GuardClose(std::unique_lock<std::mutex>& lock) {
  const Clock::time_point give_up = Clock::now() + kCloseGrace;
  bool cancelled = false;
  while (!joined_) {
    // The server should end the call soon after the half-close; if it does not (or on
    // Ctrl-C), cancel so the reading thread is not stuck in Read forever.
    if (!cancelled && (InterruptHandler::interrupted() || Clock::now() >= give_up)) {
      context_->TryCancel();
      cancelled = true;
    }
    cv_.wait_for(lock, kPoll);
  }
}

void EventWriter::Loop() {
  std::unique_lock<std::mutex> lock(mu_);
  while (WaitForWork(lock)) {
    lock.unlock();
    std::optional<v1::ClientEvent> event = next_event_();
    const bool ok = !event || Send(*event);
    lock.lock();
    if (!ok) break;  // the call is over; the reader's Read/Finish say why
  }
  // Wait for Close() if the loop ended on a failed write, so the half-close comes only when
  // the reader is done.
  while (!closing_) cv_.wait_for(lock, kPoll);
  lock.unlock();
  if (!write_failed_) stream_->WritesDone();
  lock.lock();
  GuardClose(lock);
}

// ---------------------------------------------------------------------------------------------
// InterruptHandler

namespace {
std::atomic<bool> g_interrupted{false};
void OnInterrupt(int) { g_interrupted = true; }
}  // namespace

InterruptHandler::InterruptHandler() {
  g_interrupted = false;
  previous_ = std::signal(SIGINT, OnInterrupt);
}

InterruptHandler::~InterruptHandler() { std::signal(SIGINT, previous_); }

bool InterruptHandler::interrupted() { return g_interrupted; }

}  // namespace tessera::cli
