#include "renderer/vk/pipeline.h"

#include <algorithm>
#include <string_view>

#include "absl/strings/str_cat.h"
#include "common/status_macros.h"
#include "renderer/scene/cpu_scene.h"
#include "renderer/vk/spirv_specialize.h"
#include "renderer/vk/vk_check.h"
#include "shaders/common/gpu_types.h"
#include "shaders/shader_registry.h"

namespace tessera::vk {

namespace {

// Which shaders DeviceInfo::host_specialization specializes: all but the visibility pipeline's
// shading. Specialized here, SwiftShader shaded a few of its pixels differently from one run to
// the next (VisibilityPipelineTest.ShadowedLocalLightsRenderTheSameEveryTime: 2-10 of 230,400
// pixels, by up to 10/255, where a pixel's company in its SIMD group changes with the order of
// the lists), which its own specialization does not. It is the local lights' loop (DirectLight,
// common/shading.glsl), which tests its end at the bottom: tested at its top, the pixels were the
// same in every run (three runs), but that form cost lavapipe's shading (Sponza, --lights 256:
// 68-86 ms against 73-102 in four alternating rounds), so the shading is left to the driver here.
// The forward pass's fragment shaders, whose quads do not change, are specialized here.
bool HostSpecializes(std::string_view shader) {
  return shader != "vis_shade.comp" && shader != "vis_shade_mlaa.comp";
}

// A shader module that lives only while the pipeline is created.
class ScopedShader {
 public:
  ScopedShader(VkDevice device) : device_(device) {}
  ~ScopedShader() {
    if (module_) vkDestroyShaderModule(device_, module_, nullptr);
  }
  // With `constants` and DeviceInfo::host_specialization the module is the shader specialized
  // here (specialized() then says the stage needs no VkSpecializationInfo).
  absl::Status Load(const Context& ctx, const std::string& name,
                    const std::vector<uint32_t>& constants = {}) {
    std::span<const uint32_t> code = EmbeddedShader(name);
    if (code.empty()) return absl::InternalError(absl::StrCat("shader not embedded: ", name));
    std::vector<uint32_t> specialized;
    if (ctx.info().host_specialization && !constants.empty() && HostSpecializes(name) &&
        HasSpecializationConstants(code)) {
      absl::StatusOr<std::vector<uint32_t>> made = SpecializeSpirv(code, constants);
      if (!made.ok()) return absl::InternalError(absl::StrCat(name, ": ", made.status().message()));
      specialized = std::move(*made);
      code = specialized;
      specialized_ = true;
    }
    VkShaderModuleCreateInfo ci{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
    ci.codeSize = code.size_bytes();
    ci.pCode = code.data();
    VK_RETURN_IF_ERROR(vkCreateShaderModule(device_, &ci, nullptr, &module_), name.c_str());
    return absl::OkStatus();
  }
  VkShaderModule get() const { return module_; }
  bool specialized() const { return specialized_; }

 private:
  VkDevice device_;
  VkShaderModule module_ = VK_NULL_HANDLE;
  bool specialized_ = false;
};

}  // namespace

absl::StatusOr<Pipeline> CreateGraphicsPipeline(const Context& ctx,
                                                const GraphicsPipelineDesc& desc) {
  ScopedShader vs(ctx.device()), fs(ctx.device());
  RETURN_IF_ERROR(vs.Load(ctx, desc.vertex_shader, desc.vertex_constants));
  // Constant i at offset 4i, for either stage's list.
  std::vector<VkSpecializationMapEntry> entries;
  const size_t most = std::max(desc.vertex_constants.size(), desc.fragment_constants.size());
  for (uint32_t i = 0; i < most; ++i) entries.push_back({i, i * 4, 4});
  auto specialize = [&](const std::vector<uint32_t>& constants) {
    return VkSpecializationInfo{uint32_t(constants.size()), entries.data(), constants.size() * 4,
                                constants.data()};
  };
  const VkSpecializationInfo vertex_spec = specialize(desc.vertex_constants);
  const VkSpecializationInfo fragment_spec = specialize(desc.fragment_constants);
  std::vector<VkPipelineShaderStageCreateInfo> stages;
  VkPipelineShaderStageCreateInfo stage{VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  stage.stage = VK_SHADER_STAGE_VERTEX_BIT;
  stage.module = vs.get();
  stage.pName = "main";
  if (!desc.vertex_constants.empty() && !vs.specialized()) stage.pSpecializationInfo = &vertex_spec;
  stages.push_back(stage);
  if (!desc.fragment_shader.empty()) {
    RETURN_IF_ERROR(fs.Load(ctx, desc.fragment_shader, desc.fragment_constants));
    stage.stage = VK_SHADER_STAGE_FRAGMENT_BIT;
    stage.module = fs.get();
    stage.pSpecializationInfo =
        desc.fragment_constants.empty() || fs.specialized() ? nullptr : &fragment_spec;
    stages.push_back(stage);
  }

  const VkVertexInputBindingDescription binding{0, sizeof(Vertex), VK_VERTEX_INPUT_RATE_VERTEX};
  const VkVertexInputAttributeDescription attributes[] = {
      {gpu::kAttrPosition, 0, VK_FORMAT_R32G32B32_SFLOAT, offsetof(Vertex, position)},
      {gpu::kAttrNormal, 0, VK_FORMAT_R32G32B32_SFLOAT, offsetof(Vertex, normal)},
      {gpu::kAttrTangent, 0, VK_FORMAT_R32G32B32A32_SFLOAT, offsetof(Vertex, tangent)},
      {gpu::kAttrUv0, 0, VK_FORMAT_R32G32_SFLOAT, offsetof(Vertex, uv0)},
      {gpu::kAttrUv1, 0, VK_FORMAT_R32G32_SFLOAT, offsetof(Vertex, uv1)},
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
        desc.attribute_mask ? desc.attribute_mask : (desc.fragment_shader.empty() ? 1u : 0x1fu);
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
                                               const std::vector<uint32_t>& constants) {
  ScopedShader cs(ctx.device());
  RETURN_IF_ERROR(cs.Load(ctx, shader, constants));
  VkComputePipelineCreateInfo ci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  ci.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  ci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  ci.stage.module = cs.get();
  ci.stage.pName = "main";
  std::vector<VkSpecializationMapEntry> entries;
  VkSpecializationInfo spec{};
  if (!constants.empty() && !cs.specialized()) {
    for (uint32_t i = 0; i < constants.size(); ++i) entries.push_back({i, i * 4, 4});
    spec.mapEntryCount = uint32_t(entries.size());
    spec.pMapEntries = entries.data();
    spec.dataSize = constants.size() * 4;
    spec.pData = constants.data();
    ci.stage.pSpecializationInfo = &spec;
  }
  ci.layout = layout;
  VkPipeline pipeline;
  VK_RETURN_IF_ERROR(
      vkCreateComputePipelines(ctx.device(), VK_NULL_HANDLE, 1, &ci, nullptr, &pipeline),
      name.c_str());
  ctx.SetName(pipeline, VK_OBJECT_TYPE_PIPELINE, name);
  return Pipeline(ctx.device(), pipeline);
}

}  // namespace tessera::vk
