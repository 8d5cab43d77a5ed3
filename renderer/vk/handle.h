#pragma once
// Unique<T, Destroy>: a move-only owner of one device-level Vulkan handle, destroyed with
// Destroy(device, handle, nullptr). For the handles that need nothing more than that (command
// pools, fences, query pools, descriptor pools and layouts, pipeline layouts, image and buffer
// views);
// buffers, images and samplers have their own owners in resources.h.
#include <vulkan/vulkan.h>

#include <utility>

namespace tessera::vk {

template <typename T, void (*Destroy)(VkDevice, T, const VkAllocationCallbacks*)>
class Unique {
 public:
  Unique() = default;
  Unique(VkDevice device, T handle) : device_(device), handle_(handle) {}
  ~Unique() { Reset(); }
  Unique(Unique&& o) noexcept
      : device_(std::exchange(o.device_, VK_NULL_HANDLE)),
        handle_(std::exchange(o.handle_, VK_NULL_HANDLE)) {}
  Unique& operator=(Unique&& o) noexcept {
    if (this != &o) {
      Reset();
      device_ = std::exchange(o.device_, VK_NULL_HANDLE);
      handle_ = std::exchange(o.handle_, VK_NULL_HANDLE);
    }
    return *this;
  }
  Unique(const Unique&) = delete;
  Unique& operator=(const Unique&) = delete;

  T get() const { return handle_; }
  // For vkCreate*(..., &out): releases the current handle and gives its slot.
  T* Replace(VkDevice device) {
    Reset();
    device_ = device;
    return &handle_;
  }
  explicit operator bool() const { return handle_ != VK_NULL_HANDLE; }
  void Reset() {
    if (handle_ != VK_NULL_HANDLE) Destroy(device_, handle_, nullptr);
    handle_ = VK_NULL_HANDLE;
  }

 private:
  VkDevice device_ = VK_NULL_HANDLE;
  T handle_ = VK_NULL_HANDLE;
};

using UniqueCommandPool = Unique<VkCommandPool, vkDestroyCommandPool>;
using UniqueFence = Unique<VkFence, vkDestroyFence>;
using UniqueQueryPool = Unique<VkQueryPool, vkDestroyQueryPool>;
using UniqueDescriptorPool = Unique<VkDescriptorPool, vkDestroyDescriptorPool>;
using UniqueDescriptorSetLayout = Unique<VkDescriptorSetLayout, vkDestroyDescriptorSetLayout>;
using UniquePipelineLayout = Unique<VkPipelineLayout, vkDestroyPipelineLayout>;
using UniqueImageView = Unique<VkImageView, vkDestroyImageView>;
using UniqueBufferView = Unique<VkBufferView, vkDestroyBufferView>;

}  // namespace tessera::vk
