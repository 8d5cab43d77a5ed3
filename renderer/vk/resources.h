#pragma once
// Move-only RAII owners of Vulkan buffers, images and samplers, each with a debug name.
// Lifetime rule: the renderer waits for each frame's fence before returning it, so an object
// that outlives the Render() call that used it can be destroyed at once. When frames overlap
// (the streaming issue), destruction moves to a per-frame deferred queue.
#include <vulkan/vulkan.h>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "renderer/vk/context.h"
#include "renderer/vk/handle.h"

namespace tessera::vk {

enum class MemoryUsage {
  kDeviceLocal,  // GPU-only
  kUpload,       // host-visible, coherent: staging
  // Written by the host every frame, read by the GPU many times (uniforms, lights, light
  // lists): host-visible and coherent, in device-local memory where the device maps some
  // (ReBAR / the 256 MiB BAR on discrete GPUs, all memory on integrated and CPU devices);
  // system memory when it has none or that heap is full.
  kDynamic,
  kReadback,     // host-visible, cached when possible: GPU -> CPU copies
};

class Buffer {
 public:
  Buffer() = default;
  // Creates a buffer with its own memory. Host-visible buffers stay mapped.
  static absl::StatusOr<Buffer> Create(const Context& ctx, VkDeviceSize size,
                                       VkBufferUsageFlags usage, MemoryUsage memory,
                                       const std::string& name);
  ~Buffer() { Reset(); }
  Buffer(Buffer&& o) noexcept { *this = std::move(o); }
  Buffer& operator=(Buffer&& o) noexcept;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;

  VkBuffer handle() const { return buffer_; }
  VkDeviceSize size() const { return size_; }
  void* mapped() const { return mapped_; }
  VkMemoryPropertyFlags memory_flags() const { return memory_flags_; }  // of its memory type
  // Makes GPU writes visible to the host for non-coherent memory.
  void InvalidateForRead() const;
  explicit operator bool() const { return buffer_ != VK_NULL_HANDLE; }

 private:
  void Reset();
  VkDevice device_ = VK_NULL_HANDLE;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkDeviceSize size_ = 0;
  VkDeviceSize memory_bytes_ = 0;  // what the allocation holds (>= size_)
  void* mapped_ = nullptr;
  bool coherent_ = true;
  VkMemoryPropertyFlags memory_flags_ = 0;
};

struct ImageDesc {
  VkFormat format = VK_FORMAT_R8G8B8A8_UNORM;
  uint32_t width = 1;
  uint32_t height = 1;
  uint32_t mip_levels = 1;
  uint32_t array_layers = 1;
  VkSampleCountFlagBits samples = VK_SAMPLE_COUNT_1_BIT;
  VkImageUsageFlags usage = 0;
  VkImageViewType view_type = VK_IMAGE_VIEW_TYPE_2D;
  // Not VK_FORMAT_UNDEFINED: the image is made mutable-format and gets a second view in this
  // format for sampling only (e.g. an sRGB view of a UNORM image written as storage, so that
  // filtering decodes sRGB before it blends).
  VkFormat sampled_view_format = VK_FORMAT_UNDEFINED;
};

class Image {
 public:
  Image() = default;
  static absl::StatusOr<Image> Create(const Context& ctx, const ImageDesc& desc,
                                      const std::string& name);
  ~Image() { Reset(); }
  Image(Image&& o) noexcept { *this = std::move(o); }
  Image& operator=(Image&& o) noexcept;
  Image(const Image&) = delete;
  Image& operator=(const Image&) = delete;

  VkImage handle() const { return image_; }
  VkImageView view() const { return view_; }
  // The view to sample through: desc().sampled_view_format's when there is one, else view().
  VkImageView sampled_view() const { return sampled_view_ ? sampled_view_ : view_; }
  const ImageDesc& desc() const { return desc_; }
  VkImageAspectFlags aspect() const;
  explicit operator bool() const { return image_ != VK_NULL_HANDLE; }

 private:
  void Reset();
  VkDevice device_ = VK_NULL_HANDLE;
  VkImage image_ = VK_NULL_HANDLE;
  VkImageView view_ = VK_NULL_HANDLE;
  VkImageView sampled_view_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkDeviceSize memory_bytes_ = 0;
  ImageDesc desc_;
};

class Sampler {
 public:
  Sampler() = default;
  static absl::StatusOr<Sampler> Create(const Context& ctx, const VkSamplerCreateInfo& info,
                                        const std::string& name);
  ~Sampler() { Reset(); }
  Sampler(Sampler&& o) noexcept { *this = std::move(o); }
  Sampler& operator=(Sampler&& o) noexcept;
  Sampler(const Sampler&) = delete;
  Sampler& operator=(const Sampler&) = delete;
  VkSampler handle() const { return sampler_; }

 private:
  void Reset();
  VkDevice device_ = VK_NULL_HANDLE;
  VkSampler sampler_ = VK_NULL_HANDLE;
};

// A non-owning reference to an Image (a pooled frame target) that reads like the image.
class ImageRef {
 public:
  ImageRef() = default;
  ImageRef(const Image& image) : image_(&image) {}   // NOLINT: implicit by design
  operator const Image&() const { return *image_; }  // NOLINT
  const Image& get() const { return *image_; }
  VkImage handle() const { return image_ ? image_->handle() : VK_NULL_HANDLE; }
  VkImageView view() const { return image_ ? image_->view() : VK_NULL_HANDLE; }
  VkImageView sampled_view() const { return image_ ? image_->sampled_view() : VK_NULL_HANDLE; }
  const ImageDesc& desc() const { return image_->desc(); }
  explicit operator bool() const { return image_ != nullptr && bool(*image_); }

 private:
  const Image* image_ = nullptr;
};

// One 2D view of each mip of an image (for passes that write one mip and read another).
class MipViews {
 public:
  MipViews() = default;
  static absl::StatusOr<MipViews> Create(const Context& ctx, const Image& image,
                                         const std::string& name);
  VkImageView operator[](size_t level) const { return views_[level].get(); }
  size_t size() const { return views_.size(); }

 private:
  std::vector<UniqueImageView> views_;
};

// A non-owning reference to MipViews (empty: no views).
class MipViewsRef {
 public:
  MipViewsRef() = default;
  MipViewsRef(const MipViews& views) : views_(&views) {}  // NOLINT: implicit by design
  VkImageView operator[](size_t level) const { return (*views_)[level]; }
  size_t size() const { return views_ ? views_->size() : 0; }

 private:
  const MipViews* views_ = nullptr;
};

bool IsDepthFormat(VkFormat format);

// Device memory held by every Buffer and Image of this process now, in bytes (all devices).
uint64_t AllocatedDeviceBytes();

// A whole-image layout transition with synchronization2 scopes.
struct ImageTransition {
  VkPipelineStageFlags2 src_stage = VK_PIPELINE_STAGE_2_NONE;
  VkAccessFlags2 src_access = VK_ACCESS_2_NONE;
  VkImageLayout old_layout = VK_IMAGE_LAYOUT_UNDEFINED;
  VkPipelineStageFlags2 dst_stage = VK_PIPELINE_STAGE_2_NONE;
  VkAccessFlags2 dst_access = VK_ACCESS_2_NONE;
  VkImageLayout new_layout = VK_IMAGE_LAYOUT_UNDEFINED;
};
VkImageMemoryBarrier2 MakeImageBarrier(const Image& image, const ImageTransition& t,
                                       uint32_t base_mip = 0,
                                       uint32_t mip_count = VK_REMAINING_MIP_LEVELS);
void CmdBarrier(VkCommandBuffer cmd, const VkImageMemoryBarrier2* images, uint32_t image_count,
                const VkBufferMemoryBarrier2* buffers = nullptr, uint32_t buffer_count = 0);

// A global memory barrier, and one on a whole buffer, with synchronization2 scopes.
VkMemoryBarrier2 MakeMemoryBarrier(VkPipelineStageFlags2 src_stage, VkAccessFlags2 src_access,
                                   VkPipelineStageFlags2 dst_stage, VkAccessFlags2 dst_access);
VkBufferMemoryBarrier2 MakeBufferBarrier(VkBuffer buffer, VkPipelineStageFlags2 src_stage,
                                         VkAccessFlags2 src_access, VkPipelineStageFlags2 dst_stage,
                                         VkAccessFlags2 dst_access);

// A global memory dependency (for buffers: one barrier covers them all).
void CmdMemoryBarrier(VkCommandBuffer cmd, VkPipelineStageFlags2 src_stage,
                      VkAccessFlags2 src_access, VkPipelineStageFlags2 dst_stage,
                      VkAccessFlags2 dst_access);

// A uniform texel buffer view of `buffer` from its start, as `format` texels of `texel_bytes`:
// over as many whole texels as the buffer holds, at most maxTexelBufferElements (`whole`, when
// given, says whether that is all of them). INTERNAL when the buffer is smaller than one texel.
absl::StatusOr<UniqueBufferView> CreateTexelView(const Context& ctx, const Buffer& buffer,
                                                 VkFormat format, VkDeviceSize texel_bytes,
                                                 const std::string& name, bool* whole = nullptr);

}  // namespace tessera::vk
