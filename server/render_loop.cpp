#include "server/render_loop.h"

#include <pthread.h>

#include "absl/strings/str_cat.h"
#include "renderer/log.h"
#include "server/convert.h"

namespace tessera::server {
namespace {

double MsBetween(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
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

RenderLoop::RenderLoop(Renderer* renderer, uint32_t encoder_threads)
    : renderer_(renderer), encoders_(std::make_unique<ThreadPool>("encode", encoder_threads)) {
  thread_ = std::thread([this] { Run(); });
  pthread_setname_np(thread_.native_handle(), "render");
}

RenderLoop::~RenderLoop() { Stop(); }

void RenderLoop::Enqueue(std::shared_ptr<RenderClient> client) {
  {
    std::lock_guard lock(mu_);
    if (!stopping_) {
      ready_.push_back(std::move(client));
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
  return static_cast<uint32_t>(ready_.size());
}

uint64_t RenderLoop::frames_rendered() const {
  std::lock_guard lock(mu_);
  return frames_rendered_;
}

void RenderLoop::Stop() {
  std::lock_guard stop_lock(stop_mu_);  // one Stop at a time: join once
  std::deque<std::shared_ptr<RenderClient>> abandoned;
  {
    std::lock_guard lock(mu_);
    if (stopping_ && !thread_.joinable()) return;
    stopping_ = true;
    abandoned.swap(ready_);
    while (!timers_.empty()) {
      abandoned.push_back(timers_.top().second);
      timers_.pop();
    }
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  for (auto& c : abandoned)
    c->Deliver(RenderWork{}, absl::UnavailableError("server is shutting down"));
  encoders_.reset();  // drains: frames already rendered are still encoded and delivered
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
    if (ready_.empty()) {
      if (timers_.empty())
        cv_.wait(lock);
      else
        cv_.wait_until(lock, timers_.top().first);
      continue;
    }
    std::shared_ptr<RenderClient> client = std::move(ready_.front());
    ready_.pop_front();
    lock.unlock();
    RenderOne(client);
    lock.lock();
  }
}

void RenderLoop::RenderOne(const std::shared_ptr<RenderClient>& client) {
  std::optional<RenderWork> work = client->TakeWork();
  if (!work) return;
  const Clock::time_point start = Clock::now();
  absl::StatusOr<Frame> frame = renderer_->Render(*work->scene, work->camera, work->settings, work->view);
  if (!frame.ok()) {
    Log().warn("render: scene {} seq {}: {}", work->scene_id, work->sequence,
               frame.status().ToString());
    client->Deliver(*work, frame.status());
    return;
  }
  {
    std::lock_guard lock(mu_);
    ++frames_rendered_;
  }
  const double queue_wait_ms = MsBetween(work->requested, start);
  // The encoder owns the pixels from here; the render thread goes on to the next client.
  auto shared_frame = std::make_shared<Frame>(*std::move(frame));
  encoders_->Submit([client, work = std::move(*work), shared_frame, queue_wait_ms] {
    absl::StatusOr<std::vector<uint8_t>> bytes = EncodeFrame(*shared_frame, work.format);
    if (!bytes.ok()) {
      client->Deliver(work, bytes.status());
      return;
    }
    v1::Frame out;
    FrameToProto(*shared_frame, &out);
    CameraToProto(work.camera, &out);
    out.set_sequence(work.sequence);
    out.set_event_id(work.event_id);
    out.set_scene_id(work.scene_id);
    out.set_encoding(work.format == ImageFormat::kPng ? v1::IMAGE_PNG : v1::IMAGE_JPEG);
    out.set_data(bytes->data(), bytes->size());
    out.mutable_cpu()->set_queue_wait_ms(queue_wait_ms);
    out.mutable_cpu()->set_total_ms(MsBetween(work.requested, Clock::now()));
    client->Deliver(work, std::move(out));
  });
}

}  // namespace tessera::server
