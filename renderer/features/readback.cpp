// Readback: copies the RGBA8 frame into a host-visible buffer and makes the copy visible to
// the host, so the CPU can encode it once the frame's fence signals.
#include "renderer/features/pass.h"
#include "renderer/features/features.h"

namespace tessera {

namespace {

class ReadbackPass final : public Pass {
 public:
  PassId id() const override { return PassId::kReadback; }

  void Record(PassContext& ctx) override {
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {ctx.targets->width, ctx.targets->height, 1};
    const vk::Image& image =
        ctx.settings->aa == AaMode::kFxaa ? ctx.targets->fxaa : ctx.targets->ldr;
    vkCmdCopyImageToBuffer(ctx.cmd, image.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                           ctx.targets->readback, 1, &region);
    const VkBufferMemoryBarrier2 b = vk::MakeBufferBarrier(
        ctx.targets->readback, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
        VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_READ_BIT);
    vk::CmdBarrier(ctx.cmd, nullptr, 0, &b, 1);
  }
};

}  // namespace

absl::StatusOr<std::unique_ptr<Pass>> CreateReadbackPass() {
  return std::make_unique<ReadbackPass>();
}

void SetupReadback(GraphBuilder& b) {
  const Resource image = b.Written(Resource::kFxaaColor) ? Resource::kFxaaColor
                                                         : Resource::kLdrColor;
  b.Pass(PassId::kReadback).Use(image, Access::kTransferSrc);
}

}  // namespace tessera
