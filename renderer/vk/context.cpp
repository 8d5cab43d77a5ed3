#include "renderer/vk/context.h"

#include <dlfcn.h>
#include <link.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <utility>

#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "common/status_macros.h"
#include "renderer/log.h"
#include "renderer/settings.h"
#include "renderer/vk/descriptor_limits.h"
#include "renderer/vk/format_support.h"
#include "renderer/vk/vk_check.h"

namespace tessera::vk {

const char* ResultName(VkResult result) {
  switch (result) {
#define TS_CASE(r) \
  case r:          \
    return #r;
    TS_CASE(VK_SUCCESS)
    TS_CASE(VK_NOT_READY)
    TS_CASE(VK_TIMEOUT)
    TS_CASE(VK_INCOMPLETE)
    TS_CASE(VK_ERROR_OUT_OF_HOST_MEMORY)
    TS_CASE(VK_ERROR_OUT_OF_DEVICE_MEMORY)
    TS_CASE(VK_ERROR_INITIALIZATION_FAILED)
    TS_CASE(VK_ERROR_DEVICE_LOST)
    TS_CASE(VK_ERROR_MEMORY_MAP_FAILED)
    TS_CASE(VK_ERROR_LAYER_NOT_PRESENT)
    TS_CASE(VK_ERROR_EXTENSION_NOT_PRESENT)
    TS_CASE(VK_ERROR_FEATURE_NOT_PRESENT)
    TS_CASE(VK_ERROR_INCOMPATIBLE_DRIVER)
    TS_CASE(VK_ERROR_TOO_MANY_OBJECTS)
    TS_CASE(VK_ERROR_FORMAT_NOT_SUPPORTED)
    TS_CASE(VK_ERROR_FRAGMENTED_POOL)
    TS_CASE(VK_ERROR_OUT_OF_POOL_MEMORY)
#undef TS_CASE
    default:
      return "VK_ERROR_(unknown)";
  }
}

void FatalVkError(VkResult result, const char* expr, const char* file, int line) {
  Log().critical("{}:{}: {} failed: {}", file, line, expr, ResultName(result));
  if (result == VK_ERROR_DEVICE_LOST) {
    // Not a bug of ours to debug from a core dump: the GPU was reset or its driver failed. Exit
    // non-zero so that the supervisor (systemd, Kubernetes) starts a fresh process.
    Log().critical("the GPU device was lost: exiting with status {}", kDeviceLostExitCode);
    std::_Exit(kDeviceLostExitCode);
  }
  std::abort();
}

absl::Status VkStatus(VkResult result, const char* what) {
  const std::string msg = absl::StrCat(what, ": ", ResultName(result));
  if (result == VK_ERROR_DEVICE_LOST) {
    return absl::UnavailableError(
        absl::StrCat(msg, " (the GPU device was lost; the renderer cannot go on)"));
  }
  if (result == VK_ERROR_OUT_OF_DEVICE_MEMORY || result == VK_ERROR_OUT_OF_HOST_MEMORY ||
      result == VK_ERROR_TOO_MANY_OBJECTS || result == VK_ERROR_OUT_OF_POOL_MEMORY) {
    return absl::ResourceExhaustedError(msg);
  }
  return absl::InternalError(msg);
}

namespace {

// LeakSanitizer reports at exit, after the Vulkan loader has unloaded the driver and the layers
// (and with lavapipe, LLVM): what they keep until exit then shows as "<unknown module>" and
// cannot be told from a leak of ours. Under ASan they stay loaded (RTLD_NODELETE), so
// tests/lsan.supp can name them. The handles are deliberately never closed.
void PinDriverModulesForLeakSanitizer() {
#if defined(__SANITIZE_ADDRESS__)
  dl_iterate_phdr(
      [](dl_phdr_info* info, size_t, void*) {
        const char* name = info->dlpi_name;
        if (name != nullptr && (std::strstr(name, "vulkan") || std::strstr(name, "VkLayer") ||
                                std::strstr(name, "LLVM"))) {
          dlopen(name, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
        }
        return 0;
      },
      nullptr);
#endif
}

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

const char* TypeName(VkPhysicalDeviceType type) {
  switch (type) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
      return "discrete";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
      return "integrated";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU:
      return "virtual";
    case VK_PHYSICAL_DEVICE_TYPE_CPU:
      return "cpu";
    default:
      return "other";
  }
}

bool EnvFlag(const char* name) {
  const char* v = std::getenv(name);
  return v != nullptr && (std::strcmp(v, "1") == 0 || Lower(v) == "true" || Lower(v) == "on");
}

bool HasLayer(const char* name) {
  uint32_t count = 0;
  vkEnumerateInstanceLayerProperties(&count, nullptr);
  std::vector<VkLayerProperties> layers(count);
  vkEnumerateInstanceLayerProperties(&count, layers.data());
  for (const auto& l : layers)
    if (std::strcmp(l.layerName, name) == 0) return true;
  return false;
}

bool HasInstanceExtension(const char* name, const char* layer = nullptr) {
  uint32_t count = 0;
  vkEnumerateInstanceExtensionProperties(layer, &count, nullptr);
  std::vector<VkExtensionProperties> exts(count);
  vkEnumerateInstanceExtensionProperties(layer, &count, exts.data());
  for (const auto& e : exts)
    if (std::strcmp(e.extensionName, name) == 0) return true;
  return false;
}

uint32_t MaxSamples(VkSampleCountFlags flags) {
  for (uint32_t s = 64; s > 1; s >>= 1)
    if (flags & s) return s;
  return 1;
}

}  // namespace

VKAPI_ATTR VkBool32 VKAPI_CALL Context::DebugCallback(
    VkDebugUtilsMessageSeverityFlagBitsEXT severity, VkDebugUtilsMessageTypeFlagsEXT,
    const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
  auto* self = static_cast<Context*>(user);
  const bool error = severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  const char* text = data && data->pMessage ? data->pMessage : "(no message)";
  if (error) {
    Log().error("vulkan validation: {}", text);
  } else {
    Log().warn("vulkan validation: {}", text);
  }
  self->validation_count_.fetch_add(1);
  std::lock_guard lock(self->messages_mutex_);
  if (self->messages_.size() < 32) self->messages_.emplace_back(text);
  return VK_FALSE;
}

absl::StatusOr<std::unique_ptr<Context>> Context::Create(const ContextOptions& options) {
  std::unique_ptr<Context> ctx(new Context());
  const bool validation = options.validation || EnvFlag("TESSERA_VALIDATION");
  std::string wanted = options.device_name;
  if (wanted.empty() && std::getenv("TESSERA_DEVICE")) wanted = std::getenv("TESSERA_DEVICE");
  std::vector<std::string> disabled = options.disable_features;
  if (const char* env = std::getenv("TESSERA_DISABLE_FEATURES"))
    for (absl::string_view name : absl::StrSplit(env, ',', absl::SkipWhitespace()))
      disabled.emplace_back(std::string(absl::StripAsciiWhitespace(name)));
  for (const std::string& name : disabled) {
    const auto& known = DisableableFeatures();
    if (std::find(known.begin(), known.end(), name) == known.end())
      return absl::InvalidArgumentError(
          absl::StrCat("disable_features: unknown feature \"", name, "\" (known: ",
                       absl::StrJoin(known, ", "), ")"));
  }
  ShadeDispatch shading = options.shading;
  if (const char* env = std::getenv("TESSERA_SHADE_DISPATCH");
      env && *env && shading == ShadeDispatch::kAuto) {
    const std::string v = env;
    if (v == "all_materials") {
      shading = ShadeDispatch::kAllMaterials;
    } else if (v == "per_material") {
      shading = ShadeDispatch::kPerMaterial;
    } else if (v != "auto") {
      return absl::InvalidArgumentError(absl::StrCat(
          "TESSERA_SHADE_DISPATCH: \"", v, "\" is not auto, all_materials or per_material"));
    }
  }
  RETURN_IF_ERROR(ctx->InitInstance(validation));
  RETURN_IF_ERROR(ctx->PickDevice(wanted));
  RETURN_IF_ERROR(ctx->InitDevice(validation, disabled, options.appends, shading));
  // Descriptor limits taken as smaller (read by CreatePipelineLayout's check alone).
  std::vector<std::pair<std::string, uint32_t>> caps = options.descriptor_limit_caps;
  if (const char* env = std::getenv("TESSERA_DESCRIPTOR_LIMITS")) {
    for (absl::string_view item : absl::StrSplit(env, ',', absl::SkipWhitespace())) {
      const std::pair<absl::string_view, absl::string_view> kv = absl::StrSplit(item, '=');
      uint32_t cap = 0;
      if (!absl::SimpleAtoi(kv.second, &cap)) {
        return absl::InvalidArgumentError(absl::StrCat(
            "TESSERA_DESCRIPTOR_LIMITS: \"", item, "\" is not name=value (a limit and a count)"));
      }
      caps.emplace_back(std::string(absl::StripAsciiWhitespace(kv.first)), cap);
    }
  }
  for (const auto& [name, cap] : caps) {
    RETURN_IF_ERROR(CapDescriptorLimit(ctx->limits_, name, cap));
    Log().warn(
        "descriptor limit {} taken as at most {} (descriptor_limit_caps, "
        "$TESSERA_DESCRIPTOR_LIMITS)",
        name, cap);
  }
  if (options.max_storage_buffer_range != 0) {
    uint32_t& range = ctx->limits_.maxStorageBufferRange;
    range = uint32_t(std::min<uint64_t>(range, options.max_storage_buffer_range));
    Log().info("storage buffer range taken as {} bytes (max_storage_buffer_range)", range);
  }
  const DeviceInfo& info = ctx->info_;
  Log().info("vulkan device: {} ({}, {} {}), max samples {}, validation {}", info.name, info.type,
             info.driver_name, info.driver_info, info.max_samples, validation ? "on" : "off");
  for (const DeviceFallback& f : info.fallbacks)
    Log().info("vulkan device lacks {}: {}", f.missing, f.path);
  if (info.host_specialization) {
    Log().info("specialization constants applied on the host (the driver keeps the code they "
               "leave unreachable)");
  }
  return ctx;
}

absl::Status Context::InitInstance(bool validation) {
  uint32_t loader_version = 0;
  if (vkEnumerateInstanceVersion(&loader_version) != VK_SUCCESS ||
      loader_version < VK_API_VERSION_1_3) {
    return absl::FailedPreconditionError(
        "the Vulkan loader does not offer Vulkan 1.3 (install libvulkan1 >= 1.3)");
  }

  std::vector<const char*> layers;
  std::vector<const char*> extensions;
  if (validation) {
    if (!HasLayer("VK_LAYER_KHRONOS_validation")) {
      return absl::FailedPreconditionError(
          "validation requested (TESSERA_VALIDATION=1) but VK_LAYER_KHRONOS_validation is not "
          "installed (apt-get install vulkan-validationlayers)");
    }
    layers.push_back("VK_LAYER_KHRONOS_validation");
  }
  const bool validation_features =
      validation && HasInstanceExtension(VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME,
                                         "VK_LAYER_KHRONOS_validation");
  if (validation_features) extensions.push_back(VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME);
  const bool debug_utils = HasInstanceExtension(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
  if (debug_utils) extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);

  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "tessera";
  app.pEngineName = "tessera";
  app.apiVersion = VK_API_VERSION_1_3;

  VkDebugUtilsMessengerCreateInfoEXT messenger_info{
      VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
  messenger_info.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT |
                                   VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  messenger_info.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                               VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                               VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  messenger_info.pfnUserCallback = &Context::DebugCallback;
  messenger_info.pUserData = this;

  VkInstanceCreateInfo ici{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  ici.pApplicationInfo = &app;
  ici.enabledLayerCount = static_cast<uint32_t>(layers.size());
  ici.ppEnabledLayerNames = layers.data();
  ici.enabledExtensionCount = static_cast<uint32_t>(extensions.size());
  ici.ppEnabledExtensionNames = extensions.data();
  // Validation includes synchronization validation: a missing or wrong barrier between passes
  // is as much a bug as a wrong parameter.
  const VkValidationFeatureEnableEXT enables[] = {
      VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT};
  VkValidationFeaturesEXT features{VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT};
  features.enabledValidationFeatureCount = 1;
  features.pEnabledValidationFeatures = enables;
  if (validation && debug_utils) ici.pNext = &messenger_info;  // also covers instance creation
  if (validation_features) {
    features.pNext = ici.pNext;
    ici.pNext = &features;
  }
  VK_RETURN_IF_ERROR(vkCreateInstance(&ici, nullptr, &instance_), "vkCreateInstance");

  if (validation && debug_utils) {
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance_, "vkCreateDebugUtilsMessengerEXT"));
    if (create) VK_CHECK(create(instance_, &messenger_info, nullptr, &messenger_));
  }
  if (debug_utils) {
    set_name_ = reinterpret_cast<PFN_vkSetDebugUtilsObjectNameEXT>(
        vkGetInstanceProcAddr(instance_, "vkSetDebugUtilsObjectNameEXT"));
  }

  return absl::OkStatus();
}

absl::Status Context::PickDevice(const std::string& wanted) {
  // Choose the device: by name if asked, else the best type that offers Vulkan 1.3 and a
  // graphics queue.
  uint32_t count = 0;
  vkEnumeratePhysicalDevices(instance_, &count, nullptr);
  std::vector<VkPhysicalDevice> devices(count);
  vkEnumeratePhysicalDevices(instance_, &count, devices.data());
  std::vector<DeviceCandidate> candidates;
  std::vector<int> family_of;
  std::vector<uint32_t> timestamp_bits;
  for (VkPhysicalDevice pd : devices) {
    VkPhysicalDeviceProperties props;
    vkGetPhysicalDeviceProperties(pd, &props);
    uint32_t qcount = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(pd, &qcount, nullptr);
    std::vector<VkQueueFamilyProperties> families(qcount);
    vkGetPhysicalDeviceQueueFamilyProperties(pd, &qcount, families.data());
    int family = -1;
    for (uint32_t i = 0; i < qcount; ++i) {
      const VkQueueFlags need = VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT;
      if ((families[i].queueFlags & need) == need && families[i].timestampValidBits > 0) {
        family = static_cast<int>(i);
        break;
      }
    }
    candidates.push_back({props.deviceName, TypeName(props.deviceType),
                          props.apiVersion >= VK_API_VERSION_1_3 && family >= 0});
    family_of.push_back(family);
    timestamp_bits.push_back(family >= 0 ? families[family].timestampValidBits : 0);
  }
  ASSIGN_OR_RETURN(size_t chosen, ChooseDevice(candidates, wanted));
  physical_ = devices[chosen];
  queue_family_ = static_cast<uint32_t>(family_of[chosen]);
  info_.timestamp_valid_bits = timestamp_bits[chosen];

  return absl::OkStatus();
}

void Context::DescribeDevice(const VkPhysicalDeviceProperties& p,
                             const VkPhysicalDeviceDriverProperties& driver,
                             const VkPhysicalDeviceFeatures& supported, bool validation) {
  DeviceInfo& info = info_;
  info.name = p.deviceName;
  info.type = TypeName(p.deviceType);
  info.driver_name = driver.driverName;
  info.driver_info = driver.driverInfo;
  info.host_specialization = driver.driverID == VK_DRIVER_ID_GOOGLE_SWIFTSHADER;
  info.api_version =
      absl::StrCat(VK_API_VERSION_MAJOR(p.apiVersion), ".", VK_API_VERSION_MINOR(p.apiVersion), ".",
                   VK_API_VERSION_PATCH(p.apiVersion));
  info.max_samples =
      MaxSamples(p.limits.framebufferColorSampleCounts & p.limits.framebufferDepthSampleCounts);
  {
    VkPhysicalDeviceVulkan12Properties p12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_PROPERTIES};
    VkPhysicalDeviceSubgroupProperties sub{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_PROPERTIES};
    p12.pNext = &sub;
    VkPhysicalDeviceProperties2 pp{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
    pp.pNext = &p12;
    vkGetPhysicalDeviceProperties2(physical_, &pp);
    // Per format rather than the device-wide limits: lavapipe reports 1x in
    // framebufferIntegerColorSampleCounts yet supports 4x R32_UINT attachments.
    info.sample_counts = p.limits.framebufferColorSampleCounts &
                         p.limits.framebufferDepthSampleCounts;
    const std::pair<VkFormat, VkImageUsageFlags> targets[] = {
        {VK_FORMAT_R16G16B16A16_SFLOAT, VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT},
        {VK_FORMAT_R32_UINT, VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT},
        {VK_FORMAT_D32_SFLOAT, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT}};
    for (const auto& [format, usage] : targets) {
      VkImageFormatProperties fp{};
      if (vkGetPhysicalDeviceImageFormatProperties(physical_, format, VK_IMAGE_TYPE_2D,
                                                   VK_IMAGE_TILING_OPTIMAL, usage, 0,
                                                   &fp) != VK_SUCCESS) {
        fp.sampleCounts = VK_SAMPLE_COUNT_1_BIT;
      }
      info.sample_counts &= fp.sampleCounts;
    }
    info.sample_counts |= VK_SAMPLE_COUNT_1_BIT;
    info.max_samples = MaxSamples(info.sample_counts);
    info.depth_resolve_min = (p12.supportedDepthResolveModes & VK_RESOLVE_MODE_MIN_BIT) != 0;
    info.standard_sample_locations = p.limits.standardSampleLocations;
    info.primitive_id = supported.geometryShader;
    info.subgroup_size = sub.subgroupSize;
    constexpr VkSubgroupFeatureFlags kBallot =
        VK_SUBGROUP_FEATURE_BASIC_BIT | VK_SUBGROUP_FEATURE_BALLOT_BIT;
    const bool compute = (sub.supportedStages & VK_SHADER_STAGE_COMPUTE_BIT) != 0;
    info.subgroup_ballot = compute && (sub.supportedOperations & kBallot) == kBallot;
    constexpr VkSubgroupFeatureFlags kArithmetic =
        VK_SUBGROUP_FEATURE_BASIC_BIT | VK_SUBGROUP_FEATURE_ARITHMETIC_BIT;
    info.subgroup_arithmetic = compute && (sub.supportedOperations & kArithmetic) == kArithmetic;
  }
  info.max_texel_buffer_elements = p.limits.maxTexelBufferElements;
  info.texel_buffers = true;  // the formats are mandatory: checked in InitDevice
  info.vertex_pulling = p.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU || !info.primitive_id;
  info.max_image_dimension = p.limits.maxImageDimension2D;
  info.max_array_layers = p.limits.maxImageArrayLayers;
  info.timestamp_period_ns = p.limits.timestampPeriod;
  // Anisotropic filtering costs a lot on a CPU rasterizer and little on a GPU.
  info.max_anisotropy = (supported.samplerAnisotropy && p.deviceType != VK_PHYSICAL_DEVICE_TYPE_CPU)
                            ? std::min(8.0f, p.limits.maxSamplerAnisotropy)
                            : 1.0f;
  info.validation = validation;
}

namespace {

// What the device lacks, and the path taken instead (DeviceInfo::fallbacks).
std::vector<DeviceFallback> ListFallbacks(const DeviceInfo& info) {
  std::vector<DeviceFallback> out;
  if (!info.draw_indirect_count)
    out.push_back({"drawIndirectCount",
                   "indirect draws run each list's whole capacity; commands past the count are "
                   "zeroed and draw nothing"});
  if (!info.multi_draw_indirect)
    out.push_back({"multiDrawIndirect", "one indirect draw call per command"});
  if (!info.subgroup_arithmetic)
    out.push_back({"subgroup arithmetic in compute shaders",
                   "geometry culling's prefix sum in shared memory"});
  if (!info.subgroup_ballot)
    out.push_back({"subgroup ballot in compute shaders",
                   "visibility classification and vis_mlaa's resolve count with one atomic per "
                   "pixel"});
  if (!info.sampler_minmax)
    out.push_back({"samplerFilterMinmax on R32_SFLOAT",
                   "the depth pyramid reads four texels and takes their minimum"});
  if (!info.primitive_id && info.vertex_pulling)
    out.push_back({"gl_PrimitiveID in fragment shaders (geometryShader)",
                   "the visibility pass pulls its vertices and passes each triangle's id on "
                   "from the vertex shader"});
  if (!info.visibility_buffer)
    out.push_back({!info.visibility_limit.empty()
                       ? absl::StrCat("room in the descriptor limits for the visibility passes (",
                                      info.visibility_limit, ")")
                   : !info.standard_sample_locations ? "standard sample locations"
                   : !info.primitive_id && !info.vertex_pulling
                       ? "gl_PrimitiveID in fragment shaders (geometryShader), with "
                         "vertex_pulling disabled"
                       : "visibility_buffer (disabled)",
                   "aa vis_mlaa renders msaa; pipeline visibility renders forward"});
  if (!info.shade_all_limit.empty() && info.visibility_buffer)
    out.push_back({absl::StrCat("room in the descriptor limits for the visibility shading in one "
                                "dispatch (",
                                info.shade_all_limit, ")"),
                   "the visibility shading classifies the pixels by material and runs one "
                   "dispatch per material over its list"});
  if (!info.sampler_indexing && info.visibility_buffer)
    out.push_back(
        {"sampler array indexing (shaderSampledImageArrayDynamicIndexing, "
         "shaderSampledImageArrayNonUniformIndexing)",
         "the visibility shading classifies the pixels by material and runs one "
         "dispatch per material over its list"});
  if (!info.storage_rg16f)
    out.push_back({"R16G16_SFLOAT storage images",
                   "the IBL's split-sum table is written as RGBA16F (two channels used)"});
  if (!info.pipeline_statistics)
    out.push_back({"pipelineStatisticsQuery", "frame stats report no fragment invocations"});
  if (!info.texel_buffers)
    out.push_back({"texel_buffers (disabled)",
                   "the visibility passes read the scene's vertices, indices and drawables, "
                   "and the shading the lights, from storage buffers"});
  if (!info.vertex_pulling && info.type == "cpu" && info.primitive_id)
    out.push_back({"vertex_pulling (disabled)",
                   "the visibility pass draws indexed, its fragment shaders reading "
                   "gl_PrimitiveID"});
  if (info.max_samples < kMaxSamples)
    out.push_back({absl::StrCat(kMaxSamples, "x multisampling"),
                   absl::StrCat("samples clamped to ", info.max_samples)});
  return out;
}

}  // namespace

absl::Status Context::InitDevice(bool validation, const std::vector<std::string>& disabled,
                                 AppendMode appends, ShadeDispatch shading) {
  auto off = [&](const char* name) {
    return std::find(disabled.begin(), disabled.end(), name) != disabled.end();
  };
  VkPhysicalDeviceDriverProperties driver{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES};
  VkPhysicalDeviceProperties2 props2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  props2.pNext = &driver;
  vkGetPhysicalDeviceProperties2(physical_, &props2);
  const VkPhysicalDeviceProperties& p = props2.properties;
  limits_ = p.limits;
  vkGetPhysicalDeviceMemoryProperties(physical_, &memory_);

  VkPhysicalDeviceFeatures supported{};
  vkGetPhysicalDeviceFeatures(physical_, &supported);
  VkPhysicalDeviceVulkan13Features f13_supported{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES};
  VkPhysicalDeviceFeatures2 f2_supported{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  f2_supported.pNext = &f13_supported;
  vkGetPhysicalDeviceFeatures2(physical_, &f2_supported);
  if (!f13_supported.dynamicRendering || !f13_supported.synchronization2) {
    return absl::FailedPreconditionError(absl::StrCat(
        p.deviceName, " lacks dynamicRendering or synchronization2 (Vulkan 1.3 features)"));
  }

  auto format_properties = [&](VkFormat format) {
    VkFormatProperties fp{};
    vkGetPhysicalDeviceFormatProperties(physical_, format, &fp);
    return fp;
  };
  // The format features Tessera relies on (vk/format_support.h).
  const std::vector<std::string> missing = MissingFormatFeatures(format_properties);
  if (!missing.empty()) {
    return absl::FailedPreconditionError(
        absl::StrCat(p.deviceName, " lacks ", absl::StrJoin(missing, ", ")));
  }
  DescribeDevice(p, driver, supported, validation);
  DeviceInfo& info = info_;
  if (off("subgroup_arithmetic")) info.subgroup_arithmetic = false;
  if (off("subgroup_ballot")) info.subgroup_ballot = false;
  info.subgroup_appends =
      info.subgroup_ballot && (appends == AppendMode::kSubgroup ||
                               (appends == AppendMode::kAuto && info.type != "cpu"));
  if (off("material_variants")) info.material_variants = false;
  if (off("texel_buffers")) info.texel_buffers = false;
  if (off("vertex_pulling")) info.vertex_pulling = false;
  if (off("host_specialization")) info.host_specialization = false;
  // The resolve assumes the standard sample locations; the visibility pass reads the triangle as
  // gl_PrimitiveID or pulls its vertices and passes the id on from the vertex shader.
  info.visibility_buffer = info.standard_sample_locations &&
                           (info.primitive_id || info.vertex_pulling) && !off("visibility_buffer");
  if (off("pipeline_statistics")) supported.pipelineStatisticsQuery = VK_FALSE;
  if (off("multi_draw_indirect")) supported.multiDrawIndirect = VK_FALSE;
  info.multi_draw_indirect = supported.multiDrawIndirect == VK_TRUE;
  info.max_draw_indirect_count = info.multi_draw_indirect ? p.limits.maxDrawIndirectCount : 1;
  VkPhysicalDeviceFeatures enabled{};
  enabled.samplerAnisotropy = info.max_anisotropy > 1.0f ? VK_TRUE : VK_FALSE;
  enabled.multiDrawIndirect = supported.multiDrawIndirect;
  enabled.drawIndirectFirstInstance = supported.drawIndirectFirstInstance;
  enabled.fragmentStoresAndAtomics = supported.fragmentStoresAndAtomics;
  enabled.shaderInt64 = supported.shaderInt64;
  enabled.pipelineStatisticsQuery = supported.pipelineStatisticsQuery;
  enabled.geometryShader = supported.geometryShader;  // gl_PrimitiveID in fragment shaders
  enabled.sampleRateShading = supported.sampleRateShading;
  info.pipeline_statistics = supported.pipelineStatisticsQuery == VK_TRUE;

  VkPhysicalDeviceVulkan13Features f13{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES};
  f13.dynamicRendering = VK_TRUE;
  f13.synchronization2 = VK_TRUE;
  f13.maintenance4 = f13_supported.maintenance4;
  VkPhysicalDeviceVulkan12Features f12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  f12.pNext = &f13;
  VkPhysicalDeviceVulkan12Features f12_supported{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  VkPhysicalDeviceFeatures2 q{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  q.pNext = &f12_supported;
  vkGetPhysicalDeviceFeatures2(physical_, &q);
  // Every scene draw is an indexed indirect draw whose firstInstance is its drawable. The count
  // is GPU-written where the device has drawIndirectCount; else the lists are zero-padded.
  if (!supported.drawIndirectFirstInstance) {
    return absl::FailedPreconditionError(absl::StrCat(
        p.deviceName, " lacks drawIndirectFirstInstance, which every draw uses"));
  }
  info.draw_indirect_count = f12_supported.drawIndirectCount && !off("draw_indirect_count");
  f12.drawIndirectCount = info.draw_indirect_count ? VK_TRUE : VK_FALSE;
  auto optimal_has = [&](VkFormat format, VkFormatFeatureFlags feature) {
    return (format_properties(format).optimalTilingFeatures & feature) != 0;
  };
  info.sampler_minmax =
      f12_supported.samplerFilterMinmax && !off("sampler_minmax") &&
      optimal_has(VK_FORMAT_R32_SFLOAT, VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_MINMAX_BIT);
  f12.samplerFilterMinmax = info.sampler_minmax ? VK_TRUE : VK_FALSE;
  info.storage_rg16f = optimal_has(VK_FORMAT_R16G16_SFLOAT, VK_FORMAT_FEATURE_STORAGE_IMAGE_BIT) &&
                       !off("storage_rg16f");
  info.sampler_indexing = supported.shaderSampledImageArrayDynamicIndexing &&
                          f12_supported.shaderSampledImageArrayNonUniformIndexing &&
                          !off("sampler_indexing");
  enabled.shaderSampledImageArrayDynamicIndexing = info.sampler_indexing ? VK_TRUE : VK_FALSE;
  f12.shaderSampledImageArrayNonUniformIndexing = info.sampler_indexing ? VK_TRUE : VK_FALSE;
  // (Its layouts, the largest of the visibility shading's, are checked against the device's
  // descriptor limits when the passes are made: DisableShadeAllMaterials where they exceed them.)
  info.shade_all_materials = info.sampler_indexing && info.subgroup_ballot &&
                             info.visibility_buffer &&
                             (shading == ShadeDispatch::kAllMaterials ||
                              (shading == ShadeDispatch::kAuto && info.type != "cpu"));
  f12.hostQueryReset = f12_supported.hostQueryReset;
  f12.scalarBlockLayout = f12_supported.scalarBlockLayout;
  info.fallbacks = ListFallbacks(info);

  const float priority = 1.0f;
  VkDeviceQueueCreateInfo qci{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
  qci.queueFamilyIndex = queue_family_;
  qci.queueCount = 1;
  qci.pQueuePriorities = &priority;
  VkDeviceCreateInfo dci{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
  dci.pNext = &f12;
  dci.queueCreateInfoCount = 1;
  dci.pQueueCreateInfos = &qci;
  dci.pEnabledFeatures = &enabled;
  VK_RETURN_IF_ERROR(vkCreateDevice(physical_, &dci, nullptr, &device_), "vkCreateDevice");
  PinDriverModulesForLeakSanitizer();
  vkGetDeviceQueue(device_, queue_family_, 0, &queue_);

  VkCommandPoolCreateInfo pci{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  pci.flags = VK_COMMAND_POOL_CREATE_TRANSIENT_BIT;
  pci.queueFamilyIndex = queue_family_;
  VK_CHECK(vkCreateCommandPool(device_, &pci, nullptr, &upload_pool_));
  VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  VK_CHECK(vkCreateFence(device_, &fci, nullptr, &upload_fence_));

  return absl::OkStatus();
}

Context::~Context() {
  if (device_) {
    vkDeviceWaitIdle(device_);
    vkDestroyFence(device_, upload_fence_, nullptr);
    vkDestroyCommandPool(device_, upload_pool_, nullptr);
    vkDestroyDevice(device_, nullptr);
  }
  if (messenger_) {
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
    if (destroy) destroy(instance_, messenger_, nullptr);
  }
  if (instance_) vkDestroyInstance(instance_, nullptr);
}

void Context::DisableVisibilityBuffer(const std::string& why) {
  if (!info_.visibility_buffer) return;  // off already, for the reason its fallback gives
  info_.visibility_buffer = false;
  info_.shade_all_materials = false;
  info_.visibility_limit = why;
  info_.fallbacks = ListFallbacks(info_);
  Log().warn(
      "{}: the visibility pipeline is off (pipeline visibility renders forward, aa "
      "vis_mlaa renders msaa)",
      why);
}

void Context::DisableShadeAllMaterials(const std::string& why) {
  if (!info_.shade_all_materials) return;
  info_.shade_all_materials = false;
  info_.shade_all_limit = why;
  info_.fallbacks = ListFallbacks(info_);
  Log().warn("{}: the visibility shading runs one dispatch per material", why);
}

absl::Status Context::CreateSetLayout(const std::vector<VkDescriptorSetLayoutBinding>& bindings,
                                      const std::string& name,
                                      UniqueDescriptorSetLayout* out) const {
  VkDescriptorSetLayoutCreateInfo li{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  li.bindingCount = static_cast<uint32_t>(bindings.size());
  li.pBindings = bindings.data();
  if (out->get() != VK_NULL_HANDLE) {  // the layout it replaces: its entry goes with it
    std::lock_guard<std::mutex> lock(set_layouts_mutex_);
    set_layouts_.erase(out->get());
  }
  VK_RETURN_IF_ERROR(vkCreateDescriptorSetLayout(device_, &li, nullptr, out->Replace(device_)),
                     name.c_str());
  std::vector<VkDescriptorSetLayoutBinding> kept = bindings;
  for (VkDescriptorSetLayoutBinding& b : kept) b.pImmutableSamplers = nullptr;  // not kept alive
  std::lock_guard<std::mutex> lock(set_layouts_mutex_);
  set_layouts_[out->get()] = std::move(kept);
  return absl::OkStatus();
}

absl::Status Context::CreatePipelineLayout(const std::vector<VkDescriptorSetLayout>& sets,
                                           const std::vector<VkPushConstantRange>& push,
                                           const std::string& name,
                                           UniquePipelineLayout* out) const {
  std::vector<std::vector<VkDescriptorSetLayoutBinding>> bindings;
  {
    std::lock_guard<std::mutex> lock(set_layouts_mutex_);
    for (VkDescriptorSetLayout set : sets) {
      const auto it = set_layouts_.find(set);
      if (it == set_layouts_.end()) {
        return absl::InternalError(
            absl::StrCat(name, ": a set layout not made by Context::CreateSetLayout"));
      }
      bindings.push_back(it->second);
    }
  }
  uint32_t push_bytes = 0;
  for (const VkPushConstantRange& r : push) push_bytes = std::max(push_bytes, r.offset + r.size);
  RETURN_IF_ERROR(
      CheckDescriptorLimits(limits_, bindings, push_bytes, absl::StrCat(name, " on ", info_.name)));
  VkPipelineLayoutCreateInfo pli{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  pli.setLayoutCount = static_cast<uint32_t>(sets.size());
  pli.pSetLayouts = sets.data();
  pli.pushConstantRangeCount = static_cast<uint32_t>(push.size());
  pli.pPushConstantRanges = push.data();
  VK_RETURN_IF_ERROR(vkCreatePipelineLayout(device_, &pli, nullptr, out->Replace(device_)),
                     name.c_str());
  return absl::OkStatus();
}

uint32_t Context::FindMemoryType(uint32_t type_bits, VkMemoryPropertyFlags required,
                                 VkMemoryPropertyFlags preferred,
                                 VkMemoryPropertyFlags avoid) const {
  uint32_t fallback = UINT32_MAX;
  for (uint32_t i = 0; i < memory_.memoryTypeCount; ++i) {
    if (!(type_bits & (1u << i))) continue;
    const VkMemoryPropertyFlags flags = memory_.memoryTypes[i].propertyFlags;
    if ((flags & required) != required || (flags & avoid) != 0) continue;
    if ((flags & preferred) == preferred) return i;
    if (fallback == UINT32_MAX) fallback = i;
  }
  return fallback;
}

void Context::SetName(VkObjectType type, uint64_t handle, const std::string& name) const {
  if (!set_name_ || handle == 0) return;
  VkDebugUtilsObjectNameInfoEXT ni{VK_STRUCTURE_TYPE_DEBUG_UTILS_OBJECT_NAME_INFO_EXT};
  ni.objectType = type;
  ni.objectHandle = handle;
  ni.pObjectName = name.c_str();
  set_name_(device_, &ni);
}

absl::Status Context::SubmitOnce(const std::function<void(VkCommandBuffer)>& record) {
  VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  ai.commandPool = upload_pool_;
  ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  ai.commandBufferCount = 1;
  VkCommandBuffer cmd;
  VK_RETURN_IF_ERROR(vkAllocateCommandBuffers(device_, &ai, &cmd), "vkAllocateCommandBuffers");
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  VK_CHECK(vkBeginCommandBuffer(cmd, &bi));
  record(cmd);
  VK_CHECK(vkEndCommandBuffer(cmd));
  VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cmd;
  VkResult r = vkQueueSubmit(queue_, 1, &si, upload_fence_);
  if (r == VK_SUCCESS) r = vkWaitForFences(device_, 1, &upload_fence_, VK_TRUE, UINT64_MAX);
  vkResetFences(device_, 1, &upload_fence_);
  vkFreeCommandBuffers(device_, upload_pool_, 1, &cmd);
  VK_RETURN_IF_ERROR(r, "upload submit");
  return absl::OkStatus();
}

std::vector<std::string> Context::validation_messages() const {
  std::lock_guard lock(messages_mutex_);
  return messages_;
}

}  // namespace tessera::vk
