#include "renderer/vk/resources.h"

#include <algorithm>
#include <atomic>

#include "absl/strings/str_cat.h"
#include "common/status_macros.h"
#include "renderer/vk/vk_check.h"

namespace tessera::vk {

namespace {

std::atomic<uint64_t> g_allocated_bytes{0};

absl::StatusOr<VkDeviceMemory> Allocate(const Context& ctx, const VkMemoryRequirements& req,
                                        VkMemoryPropertyFlags required,
                                        VkMemoryPropertyFlags preferred, const std::string& name,
                                        VkMemoryPropertyFlags* flags_out,
                                        VkMemoryPropertyFlags avoid = 0) {
  uint32_t type = ctx.FindMemoryType(req.memoryTypeBits, required, preferred, avoid);
  if (type == UINT32_MAX) {
    return absl::ResourceExhaustedError(absl::StrCat(name, ": no suitable memory type"));
  }
  if (flags_out) *flags_out = ctx.memory_properties().memoryTypes[type].propertyFlags;
  VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  ai.allocationSize = req.size;
  ai.memoryTypeIndex = type;
  VkDeviceMemory memory;
  VkResult r = vkAllocateMemory(ctx.device(), &ai, nullptr, &memory);
  if (r != VK_SUCCESS) {
    return VkStatus(r, absl::StrCat(name, ": allocating ", req.size, " bytes").c_str());
  }
  g_allocated_bytes += req.size;
  return memory;
}

}  // namespace

uint64_t AllocatedDeviceBytes() { return g_allocated_bytes.load(); }

absl::StatusOr<Buffer> Buffer::Create(const Context& ctx, VkDeviceSize size,
                                      VkBufferUsageFlags usage, MemoryUsage memory,
                                      const std::string& name) {
  Buffer b;
  b.device_ = ctx.device();
  b.size_ = size;
  VkBufferCreateInfo bi{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  bi.size = size == 0 ? 4 : size;  // zero-sized buffers are invalid; keep a stub
  bi.usage = usage;
  bi.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  VK_RETURN_IF_ERROR(vkCreateBuffer(b.device_, &bi, nullptr, &b.buffer_), name.c_str());
  ctx.SetName(b.buffer_, VK_OBJECT_TYPE_BUFFER, name);
  VkMemoryRequirements req;
  vkGetBufferMemoryRequirements(b.device_, b.buffer_, &req);
  VkMemoryPropertyFlags required = 0, preferred = 0;
  switch (memory) {
    case MemoryUsage::kDeviceLocal:
      preferred = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
      break;
    case MemoryUsage::kUpload:
      required = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
      break;
    case MemoryUsage::kDynamic:
      required = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
      preferred = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
      break;
    case MemoryUsage::kReadback:
      required = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT;
      preferred = VK_MEMORY_PROPERTY_HOST_CACHED_BIT;
      break;
  }
  VkMemoryPropertyFlags flags = 0;
  absl::StatusOr<VkDeviceMemory> allocated = Allocate(ctx, req, required, preferred, name, &flags);
  if (!allocated.ok() && memory == MemoryUsage::kDynamic &&
      (flags & VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT) != 0) {
    // The mapped device-local heap is full (a 256 MiB BAR without ReBAR): system memory.
    allocated = Allocate(ctx, req, required, 0, name, &flags, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  }
  ASSIGN_OR_RETURN(VkDeviceMemory mem, std::move(allocated));
  b.memory_ = mem;
  b.memory_bytes_ = req.size;
  b.memory_flags_ = flags;
  VK_CHECK(vkBindBufferMemory(b.device_, b.buffer_, b.memory_, 0));
  if (memory != MemoryUsage::kDeviceLocal) {
    VK_CHECK(vkMapMemory(b.device_, b.memory_, 0, VK_WHOLE_SIZE, 0, &b.mapped_));
    b.coherent_ = flags & VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  }
  return b;
}

Buffer& Buffer::operator=(Buffer&& o) noexcept {
  if (this != &o) {
    Reset();
    device_ = std::exchange(o.device_, VK_NULL_HANDLE);
    buffer_ = std::exchange(o.buffer_, VK_NULL_HANDLE);
    memory_ = std::exchange(o.memory_, VK_NULL_HANDLE);
    memory_bytes_ = std::exchange(o.memory_bytes_, 0);
    size_ = std::exchange(o.size_, 0);
    mapped_ = std::exchange(o.mapped_, nullptr);
    coherent_ = o.coherent_;
    memory_flags_ = o.memory_flags_;
  }
  return *this;
}

void Buffer::InvalidateForRead() const {
  if (coherent_ || !mapped_) return;
  VkMappedMemoryRange range{VK_STRUCTURE_TYPE_MAPPED_MEMORY_RANGE};
  range.memory = memory_;
  range.size = VK_WHOLE_SIZE;
  VK_CHECK(vkInvalidateMappedMemoryRanges(device_, 1, &range));
}

void Buffer::Reset() {
  if (device_ == VK_NULL_HANDLE) return;
  if (buffer_) vkDestroyBuffer(device_, buffer_, nullptr);
  if (memory_) vkFreeMemory(device_, memory_, nullptr);  // unmaps implicitly
  g_allocated_bytes -= std::exchange(memory_bytes_, 0);
  buffer_ = VK_NULL_HANDLE;
  memory_ = VK_NULL_HANDLE;
  mapped_ = nullptr;
  device_ = VK_NULL_HANDLE;
}

bool IsDepthFormat(VkFormat f) {
  return f == VK_FORMAT_D32_SFLOAT || f == VK_FORMAT_D16_UNORM ||
         f == VK_FORMAT_D24_UNORM_S8_UINT || f == VK_FORMAT_D32_SFLOAT_S8_UINT;
}

VkImageAspectFlags Image::aspect() const {
  return IsDepthFormat(desc_.format) ? VK_IMAGE_ASPECT_DEPTH_BIT : VK_IMAGE_ASPECT_COLOR_BIT;
}

absl::StatusOr<Image> Image::Create(const Context& ctx, const ImageDesc& desc,
                                    const std::string& name) {
  Image img;
  img.device_ = ctx.device();
  img.desc_ = desc;
  VkImageCreateInfo ii{VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO};
  ii.imageType = VK_IMAGE_TYPE_2D;
  if (desc.view_type == VK_IMAGE_VIEW_TYPE_CUBE) ii.flags = VK_IMAGE_CREATE_CUBE_COMPATIBLE_BIT;
  // The two formats its views use, listed so drivers can keep compression (e.g. AMD's DCC).
  const VkFormat view_formats[2] = {desc.format, desc.sampled_view_format};
  VkImageFormatListCreateInfo format_list{VK_STRUCTURE_TYPE_IMAGE_FORMAT_LIST_CREATE_INFO};
  if (desc.sampled_view_format != VK_FORMAT_UNDEFINED) {
    ii.flags |= VK_IMAGE_CREATE_MUTABLE_FORMAT_BIT;
    format_list.viewFormatCount = 2;
    format_list.pViewFormats = view_formats;
    ii.pNext = &format_list;
  }
  ii.format = desc.format;
  ii.extent = {desc.width, desc.height, 1};
  ii.mipLevels = desc.mip_levels;
  ii.arrayLayers = desc.array_layers;
  ii.samples = desc.samples;
  ii.tiling = VK_IMAGE_TILING_OPTIMAL;
  ii.usage = desc.usage;
  ii.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  ii.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  VK_RETURN_IF_ERROR(vkCreateImage(img.device_, &ii, nullptr, &img.image_), name.c_str());
  ctx.SetName(img.image_, VK_OBJECT_TYPE_IMAGE, name);
  VkMemoryRequirements req;
  vkGetImageMemoryRequirements(img.device_, img.image_, &req);
  ASSIGN_OR_RETURN(VkDeviceMemory mem,
                   Allocate(ctx, req, 0, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, name, nullptr));
  img.memory_ = mem;
  img.memory_bytes_ = req.size;
  VK_CHECK(vkBindImageMemory(img.device_, img.image_, img.memory_, 0));

  VkImageViewCreateInfo vi{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
  vi.image = img.image_;
  vi.viewType = desc.view_type;
  vi.format = desc.format;
  vi.subresourceRange = {img.aspect(), 0, desc.mip_levels, 0, desc.array_layers};
  VK_RETURN_IF_ERROR(vkCreateImageView(img.device_, &vi, nullptr, &img.view_), name.c_str());
  ctx.SetName(img.view_, VK_OBJECT_TYPE_IMAGE_VIEW, name + ".view");
  if (desc.sampled_view_format != VK_FORMAT_UNDEFINED) {
    // Sampling only: the image's other usages (storage) need not hold for this format.
    VkImageViewUsageCreateInfo usage{VK_STRUCTURE_TYPE_IMAGE_VIEW_USAGE_CREATE_INFO};
    usage.usage = VK_IMAGE_USAGE_SAMPLED_BIT;
    vi.pNext = &usage;
    vi.format = desc.sampled_view_format;
    VK_RETURN_IF_ERROR(vkCreateImageView(img.device_, &vi, nullptr, &img.sampled_view_),
                       name.c_str());
    ctx.SetName(img.sampled_view_, VK_OBJECT_TYPE_IMAGE_VIEW, name + ".sampled_view");
  }
  return img;
}

Image& Image::operator=(Image&& o) noexcept {
  if (this != &o) {
    Reset();
    device_ = std::exchange(o.device_, VK_NULL_HANDLE);
    image_ = std::exchange(o.image_, VK_NULL_HANDLE);
    view_ = std::exchange(o.view_, VK_NULL_HANDLE);
    sampled_view_ = std::exchange(o.sampled_view_, VK_NULL_HANDLE);
    memory_ = std::exchange(o.memory_, VK_NULL_HANDLE);
    memory_bytes_ = std::exchange(o.memory_bytes_, 0);
    desc_ = o.desc_;
  }
  return *this;
}

void Image::Reset() {
  if (device_ == VK_NULL_HANDLE) return;
  if (view_) vkDestroyImageView(device_, view_, nullptr);
  if (sampled_view_) vkDestroyImageView(device_, sampled_view_, nullptr);
  if (image_) vkDestroyImage(device_, image_, nullptr);
  if (memory_) vkFreeMemory(device_, memory_, nullptr);
  g_allocated_bytes -= std::exchange(memory_bytes_, 0);
  view_ = VK_NULL_HANDLE;
  sampled_view_ = VK_NULL_HANDLE;
  image_ = VK_NULL_HANDLE;
  memory_ = VK_NULL_HANDLE;
  device_ = VK_NULL_HANDLE;
}

absl::StatusOr<Sampler> Sampler::Create(const Context& ctx, const VkSamplerCreateInfo& info,
                                        const std::string& name) {
  Sampler s;
  s.device_ = ctx.device();
  VK_RETURN_IF_ERROR(vkCreateSampler(s.device_, &info, nullptr, &s.sampler_), name.c_str());
  ctx.SetName(s.sampler_, VK_OBJECT_TYPE_SAMPLER, name);
  return s;
}

Sampler& Sampler::operator=(Sampler&& o) noexcept {
  if (this != &o) {
    Reset();
    device_ = std::exchange(o.device_, VK_NULL_HANDLE);
    sampler_ = std::exchange(o.sampler_, VK_NULL_HANDLE);
  }
  return *this;
}

void Sampler::Reset() {
  if (device_ && sampler_) vkDestroySampler(device_, sampler_, nullptr);
  device_ = VK_NULL_HANDLE;
  sampler_ = VK_NULL_HANDLE;
}

VkImageMemoryBarrier2 MakeImageBarrier(const Image& image, const ImageTransition& t,
                                       uint32_t base_mip, uint32_t mip_count) {
  VkImageMemoryBarrier2 b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER_2};
  b.srcStageMask = t.src_stage;
  b.srcAccessMask = t.src_access;
  b.dstStageMask = t.dst_stage;
  b.dstAccessMask = t.dst_access;
  b.oldLayout = t.old_layout;
  b.newLayout = t.new_layout;
  b.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.image = image.handle();
  b.subresourceRange = {image.aspect(), base_mip, mip_count, 0, VK_REMAINING_ARRAY_LAYERS};
  return b;
}

void CmdBarrier(VkCommandBuffer cmd, const VkImageMemoryBarrier2* images, uint32_t image_count,
                const VkBufferMemoryBarrier2* buffers, uint32_t buffer_count) {
  if (image_count == 0 && buffer_count == 0) return;
  VkDependencyInfo di{VK_STRUCTURE_TYPE_DEPENDENCY_INFO};
  di.imageMemoryBarrierCount = image_count;
  di.pImageMemoryBarriers = images;
  di.bufferMemoryBarrierCount = buffer_count;
  di.pBufferMemoryBarriers = buffers;
  vkCmdPipelineBarrier2(cmd, &di);
}

VkMemoryBarrier2 MakeMemoryBarrier(VkPipelineStageFlags2 src_stage, VkAccessFlags2 src_access,
                                   VkPipelineStageFlags2 dst_stage, VkAccessFlags2 dst_access) {
  VkMemoryBarrier2 b{VK_STRUCTURE_TYPE_MEMORY_BARRIER_2};
  b.srcStageMask = src_stage;
  b.srcAccessMask = src_access;
  b.dstStageMask = dst_stage;
  b.dstAccessMask = dst_access;
  return b;
}

VkBufferMemoryBarrier2 MakeBufferBarrier(VkBuffer buffer, VkPipelineStageFlags2 src_stage,
                                         VkAccessFlags2 src_access, VkPipelineStageFlags2 dst_stage,
                                         VkAccessFlags2 dst_access) {
  VkBufferMemoryBarrier2 b{VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER_2};
  b.srcStageMask = src_stage;
  b.srcAccessMask = src_access;
  b.dstStageMask = dst_stage;
  b.dstAccessMask = dst_access;
  b.srcQueueFamilyIndex = b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.buffer = buffer;
  b.size = VK_WHOLE_SIZE;
  return b;
}

void CmdMemoryBarrier(VkCommandBuffer cmd, VkPipelineStageFlags2 src_stage,
                      VkAccessFlags2 src_access, VkPipelineStageFlags2 dst_stage,
                      VkAccessFlags2 dst_access) {
  const VkMemoryBarrier2 b = MakeMemoryBarrier(src_stage, src_access, dst_stage, dst_access);
  VkDependencyInfo di{VK_STRUCTURE_TYPE_DEPENDENCY_INFO};
  di.memoryBarrierCount = 1;
  di.pMemoryBarriers = &b;
  vkCmdPipelineBarrier2(cmd, &di);
}

absl::StatusOr<MipViews> MipViews::Create(const Context& ctx, const Image& image,
                                          const std::string& name) {
  MipViews out;
  for (uint32_t level = 0; level < image.desc().mip_levels; ++level) {
    VkImageViewCreateInfo vi{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
    vi.image = image.handle();
    vi.viewType = VK_IMAGE_VIEW_TYPE_2D;
    vi.format = image.desc().format;
    vi.subresourceRange = {image.aspect(), level, 1, 0, 1};
    UniqueImageView view;
    if (vkCreateImageView(ctx.device(), &vi, nullptr, view.Replace(ctx.device())) != VK_SUCCESS)
      return absl::ResourceExhaustedError(name + " level view");
    out.views_.push_back(std::move(view));
  }
  return out;
}

absl::StatusOr<UniqueBufferView> CreateTexelView(const Context& ctx, const Buffer& buffer,
                                                 VkFormat format, VkDeviceSize texel_bytes,
                                                 const std::string& name, bool* whole) {
  // Buffer::Create keeps a 4-byte stub for an empty buffer.
  const VkDeviceSize texels = std::max<VkDeviceSize>(buffer.size(), 4) / texel_bytes;
  if (texels == 0) return absl::InternalError(absl::StrCat(name, ": smaller than one texel"));
  const VkDeviceSize max = ctx.limits().maxTexelBufferElements;
  if (whole) *whole = texels <= max;
  VkBufferViewCreateInfo vi{VK_STRUCTURE_TYPE_BUFFER_VIEW_CREATE_INFO};
  vi.buffer = buffer.handle();
  vi.format = format;
  vi.offset = 0;
  vi.range = std::min(texels, max) * texel_bytes;
  UniqueBufferView view;
  VK_RETURN_IF_ERROR(vkCreateBufferView(ctx.device(), &vi, nullptr, view.Replace(ctx.device())),
                     name.c_str());
  ctx.SetName(view.get(), VK_OBJECT_TYPE_BUFFER_VIEW, name);
  return view;
}

}  // namespace tessera::vk
