#pragma once
// Graphics pipelines from embedded SPIR-V, for dynamic rendering (no render passes).
#include <vulkan/vulkan.h>

#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "renderer/vk/context.h"

namespace tessera::vk {

// Owner of a VkPipeline (move-only).
class Pipeline {
 public:
  Pipeline() = default;
  Pipeline(VkDevice device, VkPipeline pipeline) : device_(device), pipeline_(pipeline) {}
  ~Pipeline() { Reset(); }
  Pipeline(Pipeline&& o) noexcept { *this = std::move(o); }
  Pipeline& operator=(Pipeline&& o) noexcept {
    if (this != &o) {
      Reset();
      device_ = std::exchange(o.device_, VK_NULL_HANDLE);
      pipeline_ = std::exchange(o.pipeline_, VK_NULL_HANDLE);
    }
    return *this;
  }
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;
  VkPipeline handle() const { return pipeline_; }

 private:
  void Reset() {
    if (device_ && pipeline_) vkDestroyPipeline(device_, pipeline_, nullptr);
    pipeline_ = VK_NULL_HANDLE;
  }
  VkDevice device_ = VK_NULL_HANDLE;
  VkPipeline pipeline_ = VK_NULL_HANDLE;
};

enum class BlendMode { kNone, kAlpha };

struct GraphicsPipelineDesc {
  std::string name;
  std::string vertex_shader;    // file name in shaders/, e.g. "forward.vert"
  std::string fragment_shader;  // empty: depth-only pipeline
  VkPipelineLayout layout = VK_NULL_HANDLE;
  bool scene_vertex_input = true;  // bind the scene vertex layout (else no vertex input)
  // Instead: the drawables buffer per instance at binding gpu::kDrawableInputBinding, each
  // drawable's world matrix and ids as attributes (gpu::kAttrDrawableWorld, kAttrDrawableIds).
  bool drawable_instance_input = false;
  // Attributes bound, a bit per location (gpu::kAttr*); 0: all, or position alone for a
  // depth-only pipeline.
  uint32_t attribute_mask = 0;
  std::vector<VkFormat> color_formats;
  VkFormat depth_format = VK_FORMAT_UNDEFINED;
  bool depth_test = false;
  bool depth_write = false;
  VkCompareOp depth_compare = VK_COMPARE_OP_GREATER_OR_EQUAL;  // reverse-Z
  BlendMode blend = BlendMode::kNone;
  // The fragment shader's specialization constants, constant_id i = fragment_constants[i]; the
  // vertex shader's likewise.
  std::vector<uint32_t> fragment_constants;
  std::vector<uint32_t> vertex_constants;
  // Rasterizer depth bias (shadow maps): constant in depth units, slope-scaled.
  float depth_bias_constant = 0.0f;
  float depth_bias_slope = 0.0f;
  VkSampleCountFlagBits samples = VK_SAMPLE_COUNT_1_BIT;
};

// Builds a pipeline with dynamic viewport, scissor and cull mode.
absl::StatusOr<Pipeline> CreateGraphicsPipeline(const Context& ctx,
                                                const GraphicsPipelineDesc& desc);

// Who applies a pipeline's specialization constants: the device's way (on the host where
// DeviceInfo::host_specialization says so, else the driver), or the driver whatever the device.
enum class Specialize { kDeviceDefault, kByDriver };

// A compute pipeline from an embedded shader (e.g. "light_cull.comp"); `constants` are its
// specialization constants 0, 1, ... (32-bit each).
absl::StatusOr<Pipeline> CreateComputePipeline(const Context& ctx, const std::string& name,
                                               const std::string& shader, VkPipelineLayout layout,
                                               const std::vector<uint32_t>& constants = {},
                                               Specialize by = Specialize::kDeviceDefault);

}  // namespace tessera::vk
