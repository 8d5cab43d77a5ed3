#include "renderer/graph/target_pool.h"

#include "common/status_macros.h"

namespace tessera {

absl::StatusOr<const TargetPool::Target*> TargetPool::Acquire(const vk::Context& ctx,
                                                              Resource resource,
                                                              const vk::ImageDesc& desc,
                                                              const std::string& name,
                                                              bool mip_views, uint64_t frame) {
  const Key key{resource,        desc.width,  desc.height, uint32_t(desc.samples),
                desc.mip_levels, desc.format, desc.sampled_view_format};
  auto it = targets_.find(key);
  if (it == targets_.end()) {
    Target t;
    ASSIGN_OR_RETURN(t.image, vk::Image::Create(ctx, desc, name));
    if (mip_views) {
      ASSIGN_OR_RETURN(t.mips, vk::MipViews::Create(ctx, t.image, name));
    }
    it = targets_.emplace(key, std::move(t)).first;
    ++created_;
  }
  it->second.last_used = frame;
  return &it->second;
}

absl::StatusOr<const vk::Buffer*> TargetPool::AcquireBuffer(const vk::Context& ctx, uint64_t bytes,
                                                            const std::string& name,
                                                            uint64_t frame) {
  auto it = buffers_.find(bytes);
  if (it == buffers_.end()) {
    Buffer b;
    ASSIGN_OR_RETURN(b.buffer, vk::Buffer::Create(ctx, bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                                  vk::MemoryUsage::kReadback, name));
    it = buffers_.emplace(bytes, std::move(b)).first;
    ++created_;
  }
  it->second.last_used = frame;
  return &it->second.buffer;
}

namespace {
template <typename Map>
void DropIdle(Map& map, uint64_t frame, uint64_t idle_frames) {
  for (auto it = map.begin(); it != map.end();) {
    if (it->second.last_used + idle_frames < frame) {
      it = map.erase(it);
    } else {
      ++it;
    }
  }
}
}  // namespace

void TargetPool::Trim(uint64_t frame) {
  DropIdle(targets_, frame, kIdleFrames);
  DropIdle(buffers_, frame, kIdleFrames);
}

}  // namespace tessera
