#include "renderer/vk/pipeline.h"

#include "absl/strings/str_cat.h"
#include "common/status_macros.h"
#include "renderer/scene/cpu_scene.h"
#include "renderer/vk/spirv_specialize.h"
#include "renderer/vk/vk_check.h"
#include "shaders/common/gpu_types.h"
#include "shaders/shader_registry.h"

namespace tessera::vk {

namespace {

// One stage's shader module, which lives only while the pipeline is created, with its
// specialization: `constants` (constant_id i = constants[i], 32 bits each) go to the driver as
// VkSpecializationInfo, or are applied here (DeviceInfo::host_specialization, unless `by` says
// the driver), and then the stage needs none.
class ScopedShader {
 public:
  ScopedShader(VkDevice device) : device_(device) {}
  ~ScopedShader() {
    if (module_) vkDestroyShaderModule(device_, module_, nullptr);
  }
  ScopedShader(const ScopedShader&) = delete;  // stage() points into it
  ScopedShader& operator=(const ScopedShader&) = delete;

  absl::Status Load(const Context& ctx, const std::string& name,
                    const std::vector<uint32_t>& constants, Specialize by) {
    std::span<const uint32_t> code = EmbeddedShader(name);
    if (code.empty()) return absl::InternalError(absl::StrCat("shader not embedded: ", name));
    std::vector<uint32_t> specialized;
    const bool here = ctx.info().host_specialization && by == Specialize::kDeviceDefault;
    if (here && !constants.empty() && HasSpecializationConstants(code)) {
      absl::StatusOr<std::vector<uint32_t>> made = SpecializeSpirv(code, constants);
      if (!made.ok()) return absl::InternalError(absl::StrCat(name, ": ", made.status().message()));
      specialized = std::move(*made);
      code = specialized;
    } else if (!constants.empty()) {
      constants_ = constants;
      for (uint32_t i = 0; i < constants_.size(); ++i) entries_.push_back({i, i * 4, 4});
      info_ = {uint32_t(entries_.size()), entries_.data(), constants_.size() * 4,
               constants_.data()};
    }
    VkShaderModuleCreateInfo ci{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
    ci.codeSize = code.size_bytes();
    ci.pCode = code.data();
    VK_RETURN_IF_ERROR(vkCreateShaderModule(device_, &ci, nullptr, &module_), name.c_str());
    return absl::OkStatus();
  }
  // The pipeline's stage info for this module (valid while this object lives).
  VkPipelineShaderStageCreateInfo stage(VkShaderStageFlagBits which) const {
    VkPipelineShaderStageCreateInfo s{VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    s.stage = which;
    s.module = module_;
    s.pName = "main";
    s.pSpecializationInfo = constants_.empty() ? nullptr : &info_;
    return s;
  }

 private:
  VkDevice device_;
  VkShaderModule module_ = VK_NULL_HANDLE;
  std::vector<uint32_t> constants_;  // for the driver
  std::vector<VkSpecializationMapEntry> entries_;
  VkSpecializationInfo info_{};
};

}  // namespace

absl::StatusOr<Pipeline> CreateGraphicsPipeline(const Context& ctx,
                                                const GraphicsPipelineDesc& desc) {
  ScopedShader vs(ctx.device()), fs(ctx.device());
  RETURN_IF_ERROR(
      vs.Load(ctx, desc.vertex_shader, desc.vertex_constants, Specialize::kDeviceDefault));
  std::vector<VkPipelineShaderStageCreateInfo> stages = {vs.stage(VK_SHADER_STAGE_VERTEX_BIT)};
  if (!desc.fragment_shader.empty()) {
    RETURN_IF_ERROR(
        fs.Load(ctx, desc.fragment_shader, desc.fragment_constants, Specialize::kDeviceDefault));
    stages.push_back(fs.stage(VK_SHADER_STAGE_FRAGMENT_BIT));
  }

  const VkVertexInputBindingDescription binding{0, sizeof(Vertex), VK_VERTEX_INPUT_RATE_VERTEX};
  const VkVertexInputAttributeDescription attributes[] = {
      {gpu::kAttrPosition, 0, VK_FORMAT_R32G32B32_SFLOAT, offsetof(Vertex, position)},
      {gpu::kAttrNormal, 0, VK_FORMAT_R32G32B32_SFLOAT, offsetof(Vertex, normal)},
      {gpu::kAttrTangent, 0, VK_FORMAT_R32G32B32A32_SFLOAT, offsetof(Vertex, tangent)},
      {gpu::kAttrUv0, 0, VK_FORMAT_R32G32_SFLOAT, offsetof(Vertex, uv0)},
      {gpu::kAttrUv1, 0, VK_FORMAT_R32G32_SFLOAT, offsetof(Vertex, uv1)},
      {gpu::kAttrColor, 0, VK_FORMAT_R32G32_UINT, offsetof(Vertex, color)},
  };
  std::vector<VkVertexInputAttributeDescription> used_attributes;
  VkPipelineVertexInputStateCreateInfo vertex_input{
      VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
  const VkVertexInputBindingDescription drawables{gpu::kDrawableInputBinding,
                                                  sizeof(gpu::GpuDrawable),
                                                  VK_VERTEX_INPUT_RATE_INSTANCE};
  if (desc.drawable_instance_input) {
    vertex_input.vertexBindingDescriptionCount = 1;
    vertex_input.pVertexBindingDescriptions = &drawables;
    for (uint32_t c = 0; c < 4; ++c)
      used_attributes.push_back({gpu::kAttrDrawableWorld + c, gpu::kDrawableInputBinding,
                                 VK_FORMAT_R32G32B32A32_SFLOAT,
                                 uint32_t(offsetof(gpu::GpuDrawable, world) + 16 * c)});
    used_attributes.push_back({gpu::kAttrDrawableIds, gpu::kDrawableInputBinding,
                               VK_FORMAT_R32G32B32A32_UINT,
                               uint32_t(offsetof(gpu::GpuDrawable, ids))});
    vertex_input.vertexAttributeDescriptionCount = uint32_t(used_attributes.size());
    vertex_input.pVertexAttributeDescriptions = used_attributes.data();
  } else if (desc.scene_vertex_input) {
    vertex_input.vertexBindingDescriptionCount = 1;
    vertex_input.pVertexBindingDescriptions = &binding;
    // A depth-only pipeline reads positions alone: fewer attributes fetched per vertex.
    const uint32_t mask =
        desc.attribute_mask ? desc.attribute_mask : (desc.fragment_shader.empty() ? 1u : 0x3fu);
    for (const VkVertexInputAttributeDescription& a : attributes)
      if (mask & (1u << a.location)) used_attributes.push_back(a);
    vertex_input.vertexAttributeDescriptionCount = uint32_t(used_attributes.size());
    vertex_input.pVertexAttributeDescriptions = used_attributes.data();
  }

  VkPipelineInputAssemblyStateCreateInfo input_assembly{
      VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO};
  input_assembly.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
  VkPipelineViewportStateCreateInfo viewport{VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO};
  viewport.viewportCount = 1;
  viewport.scissorCount = 1;
  VkPipelineRasterizationStateCreateInfo raster{
      VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO};
  raster.polygonMode = VK_POLYGON_MODE_FILL;
  raster.cullMode = VK_CULL_MODE_NONE;                 // dynamic
  raster.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE;  // glTF winding; projection flips Y
  raster.lineWidth = 1.0f;
  if (desc.depth_bias_constant != 0.0f || desc.depth_bias_slope != 0.0f) {
    raster.depthBiasEnable = VK_TRUE;
    raster.depthBiasConstantFactor = desc.depth_bias_constant;
    raster.depthBiasSlopeFactor = desc.depth_bias_slope;
  }
  VkPipelineMultisampleStateCreateInfo multisample{
      VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO};
  multisample.rasterizationSamples = desc.samples;
  VkPipelineDepthStencilStateCreateInfo depth{
      VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO};
  depth.depthTestEnable = desc.depth_test;
  depth.depthWriteEnable = desc.depth_write;
  depth.depthCompareOp = desc.depth_compare;

  std::vector<VkPipelineColorBlendAttachmentState> blend_states(desc.color_formats.size());
  for (auto& b : blend_states) {
    b.colorWriteMask = VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT |
                       VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT;
    if (desc.blend == BlendMode::kAlpha) {
      b.blendEnable = VK_TRUE;
      b.srcColorBlendFactor = VK_BLEND_FACTOR_SRC_ALPHA;
      b.dstColorBlendFactor = VK_BLEND_FACTOR_ONE_MINUS_SRC_ALPHA;
      b.colorBlendOp = VK_BLEND_OP_ADD;
      b.srcAlphaBlendFactor = VK_BLEND_FACTOR_ONE;
      b.dstAlphaBlendFactor = VK_BLEND_FACTOR_ONE_MINUS_SRC_ALPHA;
      b.alphaBlendOp = VK_BLEND_OP_ADD;
    }
  }
  VkPipelineColorBlendStateCreateInfo blend{
      VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO};
  blend.attachmentCount = static_cast<uint32_t>(blend_states.size());
  blend.pAttachments = blend_states.data();

  const VkDynamicState dynamic_states[] = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR,
                                           VK_DYNAMIC_STATE_CULL_MODE};
  VkPipelineDynamicStateCreateInfo dynamic{VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO};
  dynamic.dynamicStateCount = 3;
  dynamic.pDynamicStates = dynamic_states;

  VkPipelineRenderingCreateInfo rendering{VK_STRUCTURE_TYPE_PIPELINE_RENDERING_CREATE_INFO};
  rendering.colorAttachmentCount = static_cast<uint32_t>(desc.color_formats.size());
  rendering.pColorAttachmentFormats = desc.color_formats.data();
  rendering.depthAttachmentFormat = desc.depth_format;

  VkGraphicsPipelineCreateInfo pi{VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO};
  pi.pNext = &rendering;
  pi.stageCount = static_cast<uint32_t>(stages.size());
  pi.pStages = stages.data();
  pi.pVertexInputState = &vertex_input;
  pi.pInputAssemblyState = &input_assembly;
  pi.pViewportState = &viewport;
  pi.pRasterizationState = &raster;
  pi.pMultisampleState = &multisample;
  pi.pDepthStencilState = &depth;
  pi.pColorBlendState = &blend;
  pi.pDynamicState = &dynamic;
  pi.layout = desc.layout;
  VkPipeline pipeline;
  VK_RETURN_IF_ERROR(
      vkCreateGraphicsPipelines(ctx.device(), VK_NULL_HANDLE, 1, &pi, nullptr, &pipeline),
      desc.name.c_str());
  ctx.SetName(pipeline, VK_OBJECT_TYPE_PIPELINE, desc.name);
  return Pipeline(ctx.device(), pipeline);
}

absl::StatusOr<Pipeline> CreateComputePipeline(const Context& ctx, const std::string& name,
                                               const std::string& shader, VkPipelineLayout layout,
                                               const std::vector<uint32_t>& constants,
                                               Specialize by) {
  ScopedShader cs(ctx.device());
  RETURN_IF_ERROR(cs.Load(ctx, shader, constants, by));
  VkComputePipelineCreateInfo ci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  ci.stage = cs.stage(VK_SHADER_STAGE_COMPUTE_BIT);
  ci.layout = layout;
  VkPipeline pipeline;
  VK_RETURN_IF_ERROR(
      vkCreateComputePipelines(ctx.device(), VK_NULL_HANDLE, 1, &ci, nullptr, &pipeline),
      name.c_str());
  ctx.SetName(pipeline, VK_OBJECT_TYPE_PIPELINE, name);
  return Pipeline(ctx.device(), pipeline);
}

}  // namespace tessera::vk
