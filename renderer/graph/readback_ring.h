#pragma once
// Where a frame's pixels are read back to when the renderer lends them (RendererOptions::
// lend_pixels): a few mapped, host-cached buffers per frame size, each either free or lent to a
// LentPixels that the caller holds while it encodes. A frame reads back into a free one and
// hands it out as it is, so no copy leaves mapped memory; the next frame takes another, so the
// device never writes into pixels someone still reads. When every buffer of the size is lent
// the frame is copied out as before (the caller's frames in flight are then more than
// kBuffersPerSize). Buffers no frame used for TargetPool::kIdleFrames are forgotten; one still
// lent then lives until its holder lets it go.
#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "renderer/renderer.h"
#include "renderer/vk/context.h"
#include "renderer/vk/resources.h"

namespace tessera {

// One readback buffer. Shared by the ring and its holder; it keeps the device alive, so a frame
// lent out may outlive the Renderer.
struct ReadbackBuffer {
  std::shared_ptr<vk::Context> ctx;  // first: destroyed after the buffer
  vk::Buffer buffer;
  // Set by the render thread when lent; cleared (release) by the holder when it lets go, so its
  // reads of the mapped bytes happen before the device writes a later frame there.
  std::atomic<bool> lent{false};
  uint64_t last_used = 0;  // the renderer's frame counter
};

class ReadbackRing {
 public:
  // Lendable buffers of one size, at most: the server's frames in flight (3) and the one being
  // rendered.
  static constexpr size_t kBuffersPerSize = 4;

  // A buffer of `bytes` that nobody holds, marked used by `frame`: one made before, else a new
  // one while the size has fewer than kBuffersPerSize; nullptr when they are all lent.
  absl::StatusOr<std::shared_ptr<ReadbackBuffer>> Acquire(std::shared_ptr<vk::Context> ctx,
                                                          uint64_t bytes, uint64_t frame);
  // Forgets the buffers unused since `frame` - TargetPool::kIdleFrames.
  void Trim(uint64_t frame);
  // Buffers the ring holds, and how many of them are lent now.
  size_t size() const { return buffers_.size(); }
  size_t lent() const;

 private:
  std::vector<std::shared_ptr<ReadbackBuffer>> buffers_;
};

}  // namespace tessera
