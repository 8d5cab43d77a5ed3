#include "server/render_loop.h"

#include <pthread.h>

#include "absl/strings/str_cat.h"
#include "common/status_macros.h"
#include "renderer/image_resize.h"
#include "renderer/log.h"
#include "server/metrics.h"

namespace tessera::server {
namespace {

double MsBetween(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

// Upscales an interactive frame to the work's output size and encodes it, reading the pixels
// where the renderer lent them (or from the frame's own memory); `frame` is consumed, its pixel
// memory given back to `renderer` for the next frames' readback. kRgba keeps the pixels in the
// frame for the video session.
absl::StatusOr<EncodedFrame> Encode(const RenderWork& work, Frame& frame, double queue_wait_ms,
                                    Renderer& renderer) {
  EncodedFrame out;
  out.render_width = frame.image.width;
  out.render_height = frame.image.height;
  double upscale_ms = 0.0;
  if (work.output_width != 0 && work.output_height != 0 &&
      (work.output_width != out.render_width || work.output_height != out.render_height)) {
    const Clock::time_point t0 = Clock::now();
    ASSIGN_OR_RETURN(RgbaImage upscaled,
                     ResizeBicubic(frame.view(), work.output_width, work.output_height));
    renderer.ReleasePixels(frame);
    frame.image = std::move(upscaled);
    upscale_ms = MsBetween(t0, Clock::now());
  }
  if (work.format == ImageFormat::kRgba) {
    frame.cpu.encode_ms = upscale_ms;  // the client's video encoder adds its own time
  } else {
    ASSIGN_OR_RETURN(out.data, EncodeFrame(frame, work.format));
    frame.cpu.encode_ms += upscale_ms;  // the upscale is part of encoding
    renderer.ReleasePixels(frame);      // the bytes are what goes on
  }
  out.frame = std::move(frame);
  out.format = work.format;
  out.camera = work.camera;
  out.sequence = work.sequence;
  out.event_id = work.event_id;
  out.scene_id = work.scene_id;
  out.profile = work.profile;
  out.queue_wait_ms = queue_wait_ms;
  out.total_ms = MsBetween(work.requested, Clock::now());
  return out;
}

}  // namespace

ThreadPool::ThreadPool(const char* name, uint32_t threads) {
  if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
  for (uint32_t i = 0; i < threads; ++i) {
    threads_.emplace_back([this] { Run(); });
    pthread_setname_np(threads_.back().native_handle(),
                       absl::StrCat(name, i).substr(0, 15).c_str());
  }
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  for (std::thread& t : threads_) t.join();
}

void ThreadPool::Submit(std::function<void()> task) {
  {
    std::lock_guard lock(mu_);
    tasks_.push_back(std::move(task));
  }
  cv_.notify_one();
}

size_t ThreadPool::pending() const {
  std::lock_guard lock(mu_);
  return tasks_.size();
}

void ThreadPool::Run() {
  for (;;) {
    std::function<void()> task;
    {
      std::unique_lock lock(mu_);
      cv_.wait(lock, [this] { return stop_ || !tasks_.empty(); });
      if (tasks_.empty()) return;  // stop_ and drained
      task = std::move(tasks_.front());
      tasks_.pop_front();
    }
    task();
  }
}

RenderLoop::RenderLoop(Renderer* renderer, const RenderLoopOptions& options)
    : renderer_(renderer),
      options_(options),
      encoders_(std::make_unique<ThreadPool>("encode", options.encoder_threads)) {
  thread_ = std::thread([this] { Run(); });
  pthread_setname_np(thread_.native_handle(), "render");
}

RenderLoop::~RenderLoop() { Stop(); }

void RenderLoop::Enqueue(std::shared_ptr<RenderClient> client, Priority priority) {
  {
    std::lock_guard lock(mu_);
    if (!stopping_) {
      (priority == Priority::kBackground ? background_ : ready_).push_back(std::move(client));
      cv_.notify_one();
      return;
    }
  }
  client->Deliver(RenderWork{}, absl::UnavailableError("server is shutting down"));
}

void RenderLoop::EnqueueAt(std::shared_ptr<RenderClient> client, Clock::time_point when) {
  {
    std::lock_guard lock(mu_);
    if (!stopping_) {
      timers_.emplace(when, std::move(client));
      cv_.notify_one();
      return;
    }
  }
  client->Deliver(RenderWork{}, absl::UnavailableError("server is shutting down"));
}

uint32_t RenderLoop::queue_depth() const {
  std::lock_guard lock(mu_);
  return static_cast<uint32_t>(ready_.size() + background_.size());
}

uint32_t RenderLoop::background_queue_depth() const {
  std::lock_guard lock(mu_);
  return static_cast<uint32_t>(background_.size());
}

uint32_t RenderLoop::frames_in_flight() const {
  std::lock_guard lock(mu_);
  return frames_in_flight_;
}

uint64_t RenderLoop::frames_rendered() const {
  std::lock_guard lock(mu_);
  return frames_rendered_;
}

double RenderLoop::busy_seconds() const {
  const int64_t since = busy_since_ns_.load();
  if (since == 0) return 0.0;
  return std::chrono::duration<double>(Clock::now().time_since_epoch() -
                                       Clock::duration(since))
      .count();
}

void RenderLoop::Stop() {
  std::lock_guard stop_lock(stop_mu_);  // one Stop at a time: join once
  std::deque<std::shared_ptr<RenderClient>> abandoned;
  std::optional<Accumulation> half;  // a frame half accumulated: its work fails
  {
    std::lock_guard lock(mu_);
    if (stopping_ && !thread_.joinable()) return;
    stopping_ = true;
    abandoned.swap(ready_);
    for (auto& c : background_) abandoned.push_back(std::move(c));
    half.swap(accumulating_);
    background_.clear();
    while (!timers_.empty()) {
      abandoned.push_back(timers_.top().second);
      timers_.pop();
    }
  }
  cv_.notify_all();
  encoded_cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  for (auto& c : abandoned)
    c->Deliver(RenderWork{}, absl::UnavailableError("server is shutting down"));
  if (half) half->client->Deliver(half->work, absl::UnavailableError("server is shutting down"));
  std::unique_ptr<ThreadPool> encoders;
  {
    std::lock_guard lock(mu_);
    encoders = std::move(encoders_);
  }
  encoders.reset();  // drains: frames already rendered are still encoded and delivered
}

void RenderLoop::SubmitEncode(std::function<void()> task) {
  {
    std::lock_guard lock(mu_);
    if (encoders_) {
      encoders_->Submit(std::move(task));
      return;
    }
  }
  task();  // the loop has stopped: the caller's thread does it
}

void RenderLoop::Run() {
  std::unique_lock lock(mu_);
  for (;;) {
    // Timers that are due join the back of the ready queue.
    const Clock::time_point now = Clock::now();
    while (!timers_.empty() && timers_.top().first <= now) {
      ready_.push_back(timers_.top().second);
      timers_.pop();
    }
    if (stopping_) return;
    if (ready_.empty() && background_.empty() && !accumulating_) {
      if (timers_.empty()) {
        cv_.wait(lock);
      } else {
        // A copy: wait_until keeps reading its deadline while the lock is released, and an
        // EnqueueAt meanwhile may move the queue's storage (ASan caught the reference).
        const Clock::time_point due = timers_.top().first;
        cv_.wait_until(lock, due);
      }
      continue;
    }
    // Back-pressure from the encoders: a frame rendered now would only wait in their queue.
    if (frames_in_flight_ >= std::max(1u, options_.max_frames_in_flight)) {
      encoded_cv_.wait(lock, [this] {
        return stopping_ || frames_in_flight_ < std::max(1u, options_.max_frames_in_flight);
      });
      continue;
    }
    // Background work keeps to its share of the render thread while viewers are active: when
    // no normal client waits it may go only once its share allows, and when viewers keep the
    // thread busy (a render-bound stream is always waiting) it still gets its share, so a job
    // beside a busy viewer progresses instead of starving. A viewer waits at most for the one
    // background render already under way.
    const bool background_waiting = !background_.empty() || accumulating_.has_value();
    const bool share_due = options_.background_share < 1.0 && now >= background_not_before_;
    const bool background = ready_.empty() || (background_waiting && share_due);
    if (background && ready_.empty() && now < background_not_before_ &&
        now - last_normal_ < std::chrono::milliseconds(500)) {
      Clock::time_point until = background_not_before_;
      if (!timers_.empty()) until = std::min(until, timers_.top().first);
      cv_.wait_until(lock, until);
      continue;
    }
    std::optional<Accumulation> resume;
    std::shared_ptr<RenderClient> client;
    if (background && accumulating_) {
      resume = std::move(accumulating_);
      accumulating_.reset();
    } else {
      auto& queue = background ? background_ : ready_;
      client = std::move(queue.front());
      queue.pop_front();
    }
    lock.unlock();
    const Clock::time_point start = Clock::now();
    bool rendered = true;
    if (resume) {
      Accumulate(*std::move(resume), true);
    } else {
      rendered = RenderOne(client, background);
    }
    const Clock::time_point end = Clock::now();
    lock.lock();
    if (!rendered) continue;
    if (!background) {
      last_normal_ = end;
    } else if (options_.background_share > 0.0 && options_.background_share < 1.0) {
      const double rest = (1.0 - options_.background_share) / options_.background_share;
      background_not_before_ =
          end + std::chrono::duration_cast<Clock::duration>((end - start) * rest);
    }
  }
}

bool RenderLoop::RenderOne(const std::shared_ptr<RenderClient>& client, bool background) {
  std::optional<RenderWork> work = client->TakeWork();
  if (!work) return false;
  if (work->fresh_view) renderer_->ForgetView(*work->scene, work->view);
  Accumulate(Accumulation{client, *std::move(work), 0, Clock::now()}, background);
  return true;
}

void RenderLoop::Accumulate(Accumulation acc, bool background) {
  const std::shared_ptr<RenderClient>& client = acc.client;
  const RenderWork* work = &acc.work;
  const uint32_t total = std::max(1u, work->accumulate);
  absl::StatusOr<Frame> frame;
  for (;;) {
    busy_since_ns_ = Clock::now().time_since_epoch().count();
    frame = renderer_->Render(*work->scene, work->camera, work->settings, work->view);
    busy_since_ns_ = 0;
    ++acc.rendered;
    if (!frame.ok() && IsDeviceLost(frame.status()) && !device_lost_reported_.exchange(true) &&
        options_.on_device_lost)
      options_.on_device_lost();
    if (!frame.ok() || acc.rendered >= total) break;
    // A viewer's frame does not wait behind a whole accumulation: the rest of it waits.
    if (background) {
      std::lock_guard lock(mu_);
      if (!ready_.empty() && !stopping_) {
        accumulating_ = std::move(acc);
        return;
      }
    }
  }
  const Clock::time_point start = acc.started;
  if (work->fresh_view) renderer_->ForgetView(*work->scene, work->view);
  if (!frame.ok()) {
    Log().warn("render: scene {} seq {}: {}", work->scene_id, work->sequence,
               frame.status().ToString());
    client->Deliver(*work, frame.status());
    return;
  }
  {
    std::lock_guard lock(mu_);
    ++frames_rendered_;
    ++frames_in_flight_;
  }
  const double queue_wait_ms = MsBetween(work->requested, start);
  if (!options_.pipelined) {
    EncodeAndDeliver(client, *work, *frame, queue_wait_ms);
    return;
  }
  // The encoder owns the pixels from here; the render thread goes on to the next client.
  auto shared_frame = std::make_shared<Frame>(*std::move(frame));
  encoders_->Submit([this, client, work = acc.work, shared_frame, queue_wait_ms] {
    EncodeAndDeliver(client, work, *shared_frame, queue_wait_ms);
  });
}

void RenderLoop::EncodeAndDeliver(const std::shared_ptr<RenderClient>& client,
                                  const RenderWork& work, Frame& frame, double queue_wait_ms) {
  absl::StatusOr<EncodedFrame> encoded = Encode(work, frame, queue_wait_ms, *renderer_);
  if (encoded.ok() && options_.metrics) {
    std::vector<std::pair<std::string, double>> passes;
    passes.reserve(encoded->frame.passes.size());
    for (const PassTiming& p : encoded->frame.passes) passes.emplace_back(p.pass, p.gpu_ms);
    options_.metrics->FrameDone(work.kind, work.profile[0] ? work.profile : "full", passes,
                                encoded->frame.gpu_total_ms, encoded->frame.cpu.encode_ms,
                                encoded->total_ms);
  }
  {
    std::lock_guard lock(mu_);
    --frames_in_flight_;
  }
  encoded_cv_.notify_one();
  client->Deliver(work, std::move(encoded));
}

}  // namespace tessera::server
