#pragma once
// Facts about the Vulkan device, without Vulkan headers (the server reports them).
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"

namespace tessera {

// An optional Vulkan feature the device lacks (or a test disabled), and the path Tessera takes
// instead. GetServerInfo lists them.
struct DeviceFallback {
  std::string missing;  // e.g. "drawIndirectCount"
  std::string path;     // e.g. "indirect draws over fixed-size lists ..."
};

// Optional features a test or user may turn off to exercise their fallbacks on a device that has
// them (RendererOptions::disable_features, TESSERA_DISABLE_FEATURES=a,b): draw_indirect_count,
// multi_draw_indirect, subgroup_arithmetic, subgroup_ballot, sampler_minmax, visibility_buffer,
// pipeline_statistics, sampler_indexing; and material_variants, texel_buffers, vertex_pulling and
// host_specialization, which are Tessera's own (DeviceInfo below).
const std::vector<std::string>& DisableableFeatures();

// How the visibility classification and vis_mlaa's resolve add pixels to the materials' lists
// where compute shaders have ballots (DeviceInfo::subgroup_appends): kAuto, the way measured
// faster on the kind of device, or one way forced, so that tests run both on one device.
enum class AppendMode { kAuto, kSubgroup, kPixel };

// How the visibility shading dispatches where the device indexes sampler arrays
// (DeviceInfo::shade_all_materials): kAuto, the way measured faster on the kind of device, or one
// way forced (RendererOptions::shading, $TESSERA_SHADE_DISPATCH = all_materials or per_material),
// so that tests run both on one device.
enum class ShadeDispatch { kAuto, kAllMaterials, kPerMaterial };

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
  // vis_mlaa can run: the device uses the standard sample locations the resolve pass assumes, and
  // the visibility pass either reads gl_PrimitiveID or pulls its vertices (vertex_pulling).
  bool visibility_buffer = false;
  // Fragment shaders read gl_PrimitiveID (geometryShader). Without it the visibility pass always
  // pulls its vertices, passing each triangle's id on from the vertex shader.
  bool primitive_id = false;
  bool standard_sample_locations = false;  // VkPhysicalDeviceLimits::standardSampleLocations
  bool depth_resolve_min = false;  // multisampled depth resolves to its farthest sample (MIN)
  uint32_t max_image_dimension = 0;  // maxImageDimension2D
  uint32_t max_array_layers = 0;
  float timestamp_period_ns = 1.0f;
  uint32_t timestamp_valid_bits = 0;
  float max_anisotropy = 1.0f;  // 1 = anisotropic filtering off
  bool validation = false;      // validation layers active
  bool sampler_minmax = false;  // min/max reduction samplers on R32F (the depth pyramid)
  bool pipeline_statistics = false;  // pipelineStatisticsQuery
  // R16G16_SFLOAT storage images (one of Vulkan's optional storage formats): the IBL's
  // split-sum table is written as RG16F; else as RGBA16F (two channels used).
  bool storage_rg16f = false;
  // Not a device feature: the shading passes build a pipeline per set of texture slots the
  // scene's materials use (GpuScene::texture_sets). Disabled, every material is shaded by the
  // general pipeline, the reference the variants are tested against.
  bool material_variants = true;
  // The visibility passes read the scene's vertices, indices and drawables, and the shading the
  // local lights and tile light lists, through uniform texel buffers (R32_UINT, R32G32_UINT,
  // R32G32B32A32_UINT, formats every device has) where they fit max_texel_buffer_elements, else
  // through storage buffers (gpu_types.h, kVisBindingIndexTexels, kBindingLocalLightTexels). Not
  // a device feature: false only where turned off, to test the storage-buffer path.
  bool texel_buffers = false;
  uint32_t max_texel_buffer_elements = 0;  // maxTexelBufferElements
  // The visibility pass pulls its vertices (common/vis_pull.glsl): non-indexed draws whose vertex
  // shader reads each index and position from the scene's buffers (vis.glsl's) and passes the
  // id on, instead of indexed draws with gl_PrimitiveID in the fragment shader. On CPU devices:
  // llvmpipe numbers primitives by assembling them again on its single-threaded front end
  // (Sponza 1280x720, the visibility pass at 4 samples 101-110 -> 91-99 ms). Not on GPUs, whose
  // post-transform cache shades a shared vertex once, unless they lack gl_PrimitiveID
  // (primitive_id). Not a device feature: off where it would be on only when turned off, to
  // test the indexed path (a device without gl_PrimitiveID then has no visibility buffer).
  bool vertex_pulling = false;
  // Specialization constants are applied, and the code they leave unreachable removed, on the
  // host (vk/spirv_specialize.h) before the driver sees a shader with constants: on SwiftShader,
  // which does not fold them, so it ran that code under an empty lane mask (every mode of
  // vis_resolve's shader in each of its dispatches) and ran every workgroup of a shader holding a
  // barrier anywhere as coroutines. Elsewhere the driver folds them. Not a device feature: off
  // only where turned off (the driver then specializes, as on other devices).
  bool host_specialization = false;
  // Compute shaders index an array of samplers with a value that differs between invocations
  // (shaderSampledImageArrayDynamicIndexing and shaderSampledImageArrayNonUniformIndexing).
  bool sampler_indexing = false;
  // The visibility shading is one dispatch over every pixel, each reading its material from the
  // scene's material buffer and its textures from the array of buckets (common/textures.glsl,
  // SHADE_ALL_MATERIALS), with no classification; else one dispatch per material over the pixel
  // lists the classification made. Needs sampler_indexing and subgroup ballots (the shading
  // counts its pixels per subgroup). ShadeDispatch::kAuto: on GPUs only. CPU devices run the
  // code of both sides of a branch for every lane, so sky pixels cost a surface's shading, and
  // SwiftShader, which indexes samplers one lane at a time, shaded Sponza's atrium (480x270,
  // visibility pipeline) in 291 ms this way against 133 ms classified per material.
  bool shade_all_materials = false;
  // Not empty: a layout of the visibility pipeline's passes exceeds the device's descriptor
  // limits (this names it, the stage and the limit), so visibility_buffer is false.
  std::string visibility_limit;
  // Not empty: the one-dispatch shading's layouts exceed the device's descriptor limits (this
  // names the layout, the stage and the limit), so shade_all_materials is false.
  std::string shade_all_limit;
  uint32_t subgroup_size = 1;
  // Compute shaders have subgroup basic and ballot operations.
  bool subgroup_ballot = false;
  // The visibility classification and vis_mlaa's resolve add each subgroup's pixels of one
  // material to its list with one atomic (ballots), else each pixel with its own. Per subgroup
  // where the device has ballots and is not a CPU device (AppendMode::kAuto): on lavapipe the
  // ballots' lane loops cost more than the atomics they save (Sponza 1280x720: classification
  // 18.0 -> 13.6 ms per pixel, vis_mlaa's resolve 57-64 -> 53-55 ms).
  bool subgroup_appends = false;
  // Compute shaders have subgroup arithmetic (the culling's prefix sum; else shared memory).
  bool subgroup_arithmetic = false;
  // vkCmdDrawIndexedIndirectCount (drawIndirectCount); else every indirect draw runs its list's
  // whole capacity, and the commands past the count draw nothing.
  bool draw_indirect_count = false;
  // More than one command per indirect call (multiDrawIndirect, up to maxDrawIndirectCount);
  // else one call per command.
  bool multi_draw_indirect = false;
  uint32_t max_draw_indirect_count = 1;
  // What the device lacks and the path taken instead, in a fixed order.
  std::vector<DeviceFallback> fallbacks;
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
