#include "renderer/graph/readback_ring.h"

#include <algorithm>

#include "renderer/graph/target_pool.h"
#include "renderer/log.h"

namespace tessera {

std::shared_ptr<ReadbackBuffer> ReadbackRing::Acquire(std::shared_ptr<vk::Context> ctx,
                                                      uint64_t bytes, uint64_t frame) {
  if (unusable_ || per_size_ == 0) return nullptr;
  size_t of_size = 0;
  std::shared_ptr<ReadbackBuffer> free;
  for (const std::shared_ptr<ReadbackBuffer>& b : buffers_) {
    if (b->buffer.size() != bytes) continue;
    ++of_size;
    b->last_used = frame;  // the size is in use: its buffers, lent or not, are kept
    if (!free && !b->lent.load(std::memory_order_acquire)) free = b;
  }
  if (free) return free;
  if (of_size >= per_size_) return nullptr;
  if (auto failed = failed_.find(bytes); failed != failed_.end()) {
    if (failed->second + TargetPool::kIdleFrames >= frame) return nullptr;
    failed_.erase(failed);  // memory may have been freed since: try again
  }
  auto b = std::make_shared<ReadbackBuffer>();
  absl::StatusOr<vk::Buffer> made = vk::Buffer::Create(
      *ctx, bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryUsage::kReadback, "lent_readback");
  if (!made.ok()) {
    // The copy's pool buffer is one buffer; this would have been one more per frame held.
    Log().warn("readback: frames of {} bytes are copied out for the next {} frames ({})", bytes,
               TargetPool::kIdleFrames, made.status().ToString());
    failed_[bytes] = frame;
    return nullptr;
  }
  if ((made->memory_flags() & VK_MEMORY_PROPERTY_HOST_CACHED_BIT) == 0) {
    Log().info("readback: no host-cached memory type; frames are copied out, not lent");
    unusable_ = true;
    return nullptr;
  }
  b->buffer = *std::move(made);
  b->ctx = std::move(ctx);
  b->last_used = frame;
  buffers_.push_back(b);
  ++created_;
  return b;
}

void ReadbackRing::Trim(uint64_t frame) {
  std::erase_if(buffers_, [&](const std::shared_ptr<ReadbackBuffer>& b) {
    return b->last_used + TargetPool::kIdleFrames < frame;
  });
}

size_t ReadbackRing::lent() const {
  return size_t(std::count_if(buffers_.begin(), buffers_.end(), [](const auto& b) {
    return b->lent.load(std::memory_order_relaxed);
  }));
}

}  // namespace tessera
