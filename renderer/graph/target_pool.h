#pragma once
// The frame's transient targets, pooled: one image (with a view per mip where asked) per
// (resource, size, samples, mips), made the first time a frame needs it and kept while frames
// keep using it. Viewers of different sizes or AA modes each find their own targets instead of
// re-creating one shared set every time consecutive frames differ. A target no frame used for
// kIdleFrames frames is dropped, so a viewer that changes size stops paying for the old one.
// Frames are synchronous (Render waits for its fence), so nothing in flight uses what is dropped.
#include <cstdint>
#include <map>
#include <string>
#include <tuple>

#include "absl/status/statusor.h"
#include "renderer/graph/frame_graph.h"
#include "renderer/vk/context.h"
#include "renderer/vk/resources.h"

namespace tessera {

class TargetPool {
 public:
  // Frames a target may go unused before it is dropped.
  static constexpr uint64_t kIdleFrames = 32;

  struct Target {
    vk::Image image;
    vk::MipViews mips;  // with `mip_views`: a view per level
    uint64_t last_used = 0;
  };

  // The target for `resource` with `desc` (its size, format, samples, mips and usage), made
  // when the pool has none; marked used in `frame`.
  absl::StatusOr<const Target*> Acquire(const vk::Context& ctx, Resource resource,
                                        const vk::ImageDesc& desc, const std::string& name,
                                        bool mip_views, uint64_t frame);
  // A host-visible readback buffer of `bytes`, pooled the same way.
  absl::StatusOr<const vk::Buffer*> AcquireBuffer(const vk::Context& ctx, uint64_t bytes,
                                                  const std::string& name, uint64_t frame);
  // Drops the targets unused since `frame` - kIdleFrames.
  void Trim(uint64_t frame);

  // Targets and buffers made so far.
  uint64_t created() const { return created_; }

 private:
  using Key = std::tuple<Resource, uint32_t, uint32_t, uint32_t, uint32_t, VkFormat, VkFormat>;
  std::map<Key, Target> targets_;
  struct Buffer {
    vk::Buffer buffer;
    uint64_t last_used = 0;
  };
  std::map<uint64_t, Buffer> buffers_;
  uint64_t created_ = 0;
};

}  // namespace tessera
