#pragma once
// Facts about the Vulkan device, without Vulkan headers (the server reports them).
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"

namespace tessera {

// What the server and clients need to know about the device.
struct DeviceInfo {
  std::string name;                  // VkPhysicalDeviceProperties::deviceName
  std::string type;                  // "discrete", "integrated", "virtual", "cpu", "other"
  std::string driver_name;           // VkPhysicalDeviceDriverProperties::driverName
  std::string driver_info;           // e.g. "Mesa 22.3.6 (LLVM 15.0.6)"
  std::string api_version;           // "1.3.230"
  uint32_t max_samples = 1;          // largest MSAA count for colour + depth attachments
  // Sample counts (bit n = 2^n samples) usable for every multisampled target: float and integer
  // colour attachments, depth, and sampling them (lavapipe: 1 and 4).
  uint32_t sample_counts = 1;
  // vis_mlaa can run: fragment shaders read gl_PrimitiveID (geometryShader) and the device uses
  // the standard sample locations the resolve pass assumes.
  bool visibility_buffer = false;
  bool depth_resolve_min = false;  // multisampled depth resolves to its farthest sample (MIN)
  uint32_t max_image_dimension = 0;  // maxImageDimension2D
  uint32_t max_array_layers = 0;
  float timestamp_period_ns = 1.0f;
  uint32_t timestamp_valid_bits = 0;
  float max_anisotropy = 1.0f;  // 1 = anisotropic filtering off
  bool validation = false;      // validation layers active
  bool sampler_minmax = false;  // min/max reduction samplers on R32F (the depth pyramid)
  bool pipeline_statistics = false;  // pipelineStatisticsQuery
  uint32_t subgroup_size = 1;
  // Compute shaders have subgroup basic and ballot operations (the visibility pipeline's
  // classification aggregates its atomics per subgroup with them).
  bool subgroup_ballot = false;
};

// A physical device as the chooser sees it.
struct DeviceCandidate {
  std::string name;
  std::string type;     // as DeviceInfo::type
  bool usable = false;  // Vulkan 1.3 and a graphics+compute queue with timestamps
};

// The device to use: among usable devices whose name contains `wanted` (case-insensitive; empty
// matches all), the first of the best type: discrete > integrated > virtual > cpu > other.
// NOT_FOUND naming every device when none qualifies.
absl::StatusOr<size_t> ChooseDevice(const std::vector<DeviceCandidate>& devices,
                                    std::string_view wanted);

}  // namespace tessera
