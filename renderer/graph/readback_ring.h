#pragma once
// Where a frame's pixels are read back to when the renderer lends them (RendererOptions::
// lent_buffers): a few mapped, host-cached buffers per frame size, each either free or lent to a
// LentPixels that the caller holds while it encodes. A frame reads back into a free one and
// hands it out as it is, so no copy leaves mapped memory; the next frame takes another, so the
// device never writes into pixels someone still reads. The renderer copies the frame out as
// before when Acquire has none: every buffer of the size lent (more frames held than
// RendererOptions::lent_buffers), no host-cached memory type (encoders reading uncached or
// write-combined memory row by row would be far slower than one copy), or no memory left for
// one more of the size (tried again after TargetPool::kIdleFrames frames).
// The buffers of a size no frame used for TargetPool::kIdleFrames are forgotten; one still lent
// then lives until its holder lets it go, uncounted.
#include <atomic>
#include <cstdint>
#include <map>
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
  // Lends from at most `per_size` buffers of each size (0: none; Acquire returns nullptr).
  explicit ReadbackRing(uint32_t per_size = 0) : per_size_(per_size) {}

  // A buffer of `bytes` that nobody holds, marked used by `frame`: one made before, else a new
  // one while the size has fewer than per_size; nullptr when the frame must be copied out (see
  // above).
  std::shared_ptr<ReadbackBuffer> Acquire(std::shared_ptr<vk::Context> ctx, uint64_t bytes,
                                          uint64_t frame);
  // Forgets the buffers of the sizes unused since `frame` - TargetPool::kIdleFrames.
  void Trim(uint64_t frame);
  // Buffers the ring holds, and how many of them are lent now.
  size_t size() const { return buffers_.size(); }
  size_t lent() const;
  // Buffers made so far (FrameStats::targets_created counts them with the pool's).
  uint64_t created() const { return created_; }

 private:
  uint32_t per_size_;
  uint64_t created_ = 0;
  bool unusable_ = false;                // no host-cached memory type: every frame is copied out
  std::map<uint64_t, uint64_t> failed_;  // sizes whose allocation failed -> the frame it did
  std::vector<std::shared_ptr<ReadbackBuffer>> buffers_;
};

}  // namespace tessera
