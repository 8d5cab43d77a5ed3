#pragma once
// The Vulkan instance, the chosen physical device, its logical device and its queue.
#include <vulkan/vulkan.h>

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "renderer/device_info.h"
#include "renderer/vk/handle.h"

namespace tessera::vk {

using tessera::DeviceInfo;

struct ContextOptions {
  // Case-insensitive substring of the device name to use instead of the automatic choice
  // (discrete > integrated > virtual > CPU). Empty: $TESSERA_DEVICE, else automatic.
  std::string device_name;
  // Enable VK_LAYER_KHRONOS_validation. Also enabled by TESSERA_VALIDATION=1.
  bool validation = false;
  // Optional features to treat as absent (DisableableFeatures(); also
  // $TESSERA_DISABLE_FEATURES, comma-separated), so that their fallbacks can be tested on a
  // device that has them. An unknown name is INVALID_ARGUMENT.
  std::vector<std::string> disable_features;
  // Treat the device's maxStorageBufferRange as at most this many bytes (0: the device's own), so
  // that the paths for scenes larger than a device's storage buffers can be tested on a device
  // whose range is larger. Only what reads limits() sees it: the validation layers check the
  // device's own range, and buffers sized below Vulkan's minimum range (128 MiB) are not checked
  // against it.
  uint64_t max_storage_buffer_range = 0;
  // Treat these descriptor limits of the device, named as the spec spells them
  // ("maxPerStageDescriptorStorageBuffers"; CapDescriptorLimit), as at most these values (also
  // $TESSERA_DESCRIPTOR_LIMITS, "name=value,..."), so that what a device with smaller limits
  // gets can be tested on any device. Only CreatePipelineLayout's check (and what else reads
  // limits()) sees them: they apply once the device is made. An unknown name is INVALID_ARGUMENT.
  std::vector<std::pair<std::string, uint32_t>> descriptor_limit_caps;
  // How the visibility passes append pixels to lists (DeviceInfo::subgroup_appends); kAuto: by
  // the kind of device.
  AppendMode appends = AppendMode::kAuto;
  // How the visibility shading dispatches (DeviceInfo::shade_all_materials); kAuto: by the kind
  // of device, or $TESSERA_SHADE_DISPATCH.
  ShadeDispatch shading = ShadeDispatch::kAuto;
};

class Context {
 public:
  // Creates instance + device. Fails with a one-line reason (no Vulkan, no matching device,
  // validation requested but not installed).
  static absl::StatusOr<std::unique_ptr<Context>> Create(const ContextOptions& options);
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  VkInstance instance() const { return instance_; }
  VkPhysicalDevice physical_device() const { return physical_; }
  VkDevice device() const { return device_; }
  VkQueue queue() const { return queue_; }
  uint32_t queue_family() const { return queue_family_; }
  const DeviceInfo& info() const { return info_; }
  const VkPhysicalDeviceLimits& limits() const { return limits_; }
  const VkPhysicalDeviceMemoryProperties& memory_properties() const { return memory_; }

  // A memory type index in `type_bits` with all `required` flags and none of `avoid`,
  // preferring `preferred`. UINT32_MAX when none.
  uint32_t FindMemoryType(uint32_t type_bits, VkMemoryPropertyFlags required,
                          VkMemoryPropertyFlags preferred = 0,
                          VkMemoryPropertyFlags avoid = 0) const;

  // Gives a Vulkan object a debug name (shown by validation messages); no-op without
  // debug utils.
  void SetName(VkObjectType type, uint64_t handle, const std::string& name) const;
  template <typename T>
  void SetName(T handle, VkObjectType type, const std::string& name) const {
    SetName(type, reinterpret_cast<uint64_t>(handle), name);
  }

  // Creates a descriptor set layout of `bindings` and keeps them, so that a pipeline layout
  // made of it can be checked against the device's descriptor limits. `name` names it in errors.
  absl::Status CreateSetLayout(const std::vector<VkDescriptorSetLayoutBinding>& bindings,
                               const std::string& name, UniqueDescriptorSetLayout* out) const;
  // Creates a pipeline layout of `sets` (each made by CreateSetLayout) and `push`, once it is
  // checked to fit the device's descriptor limits (CheckDescriptorLimits): FAILED_PRECONDITION
  // naming `name`, the stage, the count and the limit when it does not.
  absl::Status CreatePipelineLayout(const std::vector<VkDescriptorSetLayout>& sets,
                                    const std::vector<VkPushConstantRange>& push,
                                    const std::string& name, UniquePipelineLayout* out) const;

  // Where a layout of the visibility pipeline's passes exceeds the device's descriptor limits
  // (`why`, CheckDescriptorLimits' message): the device renders without the visibility buffer,
  // as one that lacks its features (DeviceInfo::visibility_buffer, visibility_limit, fallbacks).
  void DisableVisibilityBuffer(const std::string& why);
  // Where the one-dispatch visibility shading's layouts (the largest) exceed them: the shading
  // runs one dispatch per material (DeviceInfo::shade_all_materials, shade_all_limit).
  void DisableShadeAllMaterials(const std::string& why);

  // Records `record` into a one-time command buffer, submits it and waits. For uploads.
  absl::Status SubmitOnce(const std::function<void(VkCommandBuffer)>& record);

  // Validation messages (warnings and errors) since creation; tests assert there are none.
  uint64_t validation_message_count() const { return validation_count_.load(); }
  std::vector<std::string> validation_messages() const;

 private:
  // Create's steps: the instance (with validation and its messenger), the physical device and
  // its queue family, then the device with the features Tessera uses (and DeviceInfo).
  absl::Status InitInstance(bool validation);
  absl::Status PickDevice(const std::string& wanted);
  absl::Status InitDevice(bool validation, const std::vector<std::string>& disabled,
                          AppendMode appends, ShadeDispatch shading);
  void DescribeDevice(const VkPhysicalDeviceProperties& p,
                      const VkPhysicalDeviceDriverProperties& driver,
                      const VkPhysicalDeviceFeatures& supported, bool validation);
  Context() = default;
  static VKAPI_ATTR VkBool32 VKAPI_CALL DebugCallback(
      VkDebugUtilsMessageSeverityFlagBitsEXT severity, VkDebugUtilsMessageTypeFlagsEXT types,
      const VkDebugUtilsMessengerCallbackDataEXT* data, void* user);

  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  uint32_t queue_family_ = 0;
  VkCommandPool upload_pool_ = VK_NULL_HANDLE;
  VkFence upload_fence_ = VK_NULL_HANDLE;
  VkPhysicalDeviceMemoryProperties memory_{};
  VkPhysicalDeviceLimits limits_{};
  DeviceInfo info_;
  PFN_vkSetDebugUtilsObjectNameEXT set_name_ = nullptr;
  std::atomic<uint64_t> validation_count_{0};
  // The bindings of each set layout CreateSetLayout made. A layout replaced in its holder takes
  // its entry with it; one destroyed with its holder leaves its entry until the handle is reused
  // (never looked up: the renderer makes its layouts once, the IBL bake's again only after a
  // failed bake).
  mutable std::mutex set_layouts_mutex_;
  mutable std::unordered_map<VkDescriptorSetLayout, std::vector<VkDescriptorSetLayoutBinding>>
      set_layouts_;
  mutable std::mutex messages_mutex_;
  std::vector<std::string> messages_;  // the first few, for test failure output
};

}  // namespace tessera::vk
