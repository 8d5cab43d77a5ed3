#include "renderer/graph/readback_ring.h"

#include <algorithm>

#include "common/status_macros.h"
#include "renderer/graph/target_pool.h"

namespace tessera {

absl::StatusOr<std::shared_ptr<ReadbackBuffer>> ReadbackRing::Acquire(
    std::shared_ptr<vk::Context> ctx, uint64_t bytes, uint64_t frame) {
  size_t of_size = 0;
  for (const std::shared_ptr<ReadbackBuffer>& b : buffers_) {
    if (b->buffer.size() != bytes) continue;
    ++of_size;
    if (b->lent.load(std::memory_order_acquire)) continue;
    b->last_used = frame;
    return b;
  }
  if (of_size >= kBuffersPerSize) return nullptr;
  auto b = std::make_shared<ReadbackBuffer>();
  ASSIGN_OR_RETURN(b->buffer, vk::Buffer::Create(*ctx, bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                                 vk::MemoryUsage::kReadback, "lent_readback"));
  b->ctx = std::move(ctx);
  b->last_used = frame;
  buffers_.push_back(b);
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
