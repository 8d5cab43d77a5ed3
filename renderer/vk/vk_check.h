#pragma once
// VK_CHECK never compiles out: a failed Vulkan call is reported with file:line and the
// VkResult name. Use it only where failure means a broken device or driver; everything a
// client can cause is handled with absl::Status before it reaches Vulkan.
#include <vulkan/vulkan.h>

#include "absl/status/status.h"

namespace tessera::vk {

const char* ResultName(VkResult result);

[[noreturn]] void FatalVkError(VkResult result, const char* expr, const char* file, int line);

// Status for a failed Vulkan call that can fail for reasons outside our control: out of memory
// is RESOURCE_EXHAUSTED, device lost UNAVAILABLE (tessera::IsDeviceLost), anything else
// INTERNAL, each with the result name.
absl::Status VkStatus(VkResult result, const char* what);
// A VK_CHECK that fails with VK_ERROR_DEVICE_LOST exits the process with this status (75,
// EX_TEMPFAIL: try again) instead of aborting.
inline constexpr int kDeviceLostExitCode = 75;

}  // namespace tessera::vk

#define VK_CHECK(expr)                                                          \
  do {                                                                          \
    VkResult vk_check_result_ = (expr);                                         \
    if (vk_check_result_ != VK_SUCCESS)                                         \
      ::tessera::vk::FatalVkError(vk_check_result_, #expr, __FILE__, __LINE__); \
  } while (0)

// Returns a Status from the enclosing function when a Vulkan call fails.
#define VK_RETURN_IF_ERROR(expr, what)                                                          \
  do {                                                                                          \
    VkResult vk_check_result_ = (expr);                                                         \
    if (vk_check_result_ != VK_SUCCESS) return ::tessera::vk::VkStatus(vk_check_result_, what); \
  } while (0)
