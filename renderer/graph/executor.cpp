#include "renderer/graph/executor.h"

#include "common/status_macros.h"
#include "renderer/vk/vk_check.h"

namespace tessera {

namespace {

constexpr uint32_t kMaxTimestamps = 2 * static_cast<uint32_t>(PassId::kCount);
// Pipeline statistics gathered per geometry pass, in the order Vulkan returns them.
constexpr VkQueryPipelineStatisticFlags kPipelineStats =
    VK_QUERY_PIPELINE_STATISTIC_INPUT_ASSEMBLY_PRIMITIVES_BIT |
    VK_QUERY_PIPELINE_STATISTIC_CLIPPING_PRIMITIVES_BIT |
    VK_QUERY_PIPELINE_STATISTIC_FRAGMENT_SHADER_INVOCATIONS_BIT;

double MsSince(GraphExecutor::Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(GraphExecutor::Clock::now() - t0).count();
}

bool IsGeometryPass(PassId id) {
  return id == PassId::kDepthPrepass || id == PassId::kDepthPrepassLate ||
         id == PassId::kVisibility || id == PassId::kVisibilityLate ||
         id == PassId::kForward || id == PassId::kTransparent;
}

// How a declared Access maps to Vulkan synchronization.
struct AccessInfo {
  VkPipelineStageFlags2 stage;
  VkAccessFlags2 access;
  VkImageLayout layout;
};

// For a buffer resource (frame_graph.h: IsBuffer): the stages and accesses of a use.
struct BufferAccessInfo {
  VkPipelineStageFlags2 stage;
  VkAccessFlags2 access;
};

AccessInfo ToVulkan(Access a) {
  constexpr VkPipelineStageFlags2 kDepthStages =
      VK_PIPELINE_STAGE_2_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_2_LATE_FRAGMENT_TESTS_BIT;
  switch (a) {
    case Access::kNone:
      return {VK_PIPELINE_STAGE_2_NONE, VK_ACCESS_2_NONE, VK_IMAGE_LAYOUT_UNDEFINED};
    case Access::kDepthWrite:
      return {kDepthStages,
              VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT |
                  VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT,
              VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL};
    case Access::kDepthTest:
      return {kDepthStages, VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT,
              VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL};
    case Access::kColorWrite:
      return {VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT,
              VK_ACCESS_2_COLOR_ATTACHMENT_READ_BIT | VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT,
              VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
    case Access::kSampled:
      return {VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT, VK_ACCESS_2_SHADER_SAMPLED_READ_BIT,
              VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    case Access::kComputeRead:
      return {VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_SAMPLED_READ_BIT,
              VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    case Access::kTransferSrc:
      return {VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_READ_BIT,
              VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL};
    case Access::kComputeWrite:
      return {VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
              VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT | VK_ACCESS_2_SHADER_STORAGE_READ_BIT |
                  VK_ACCESS_2_SHADER_SAMPLED_READ_BIT,
              VK_IMAGE_LAYOUT_GENERAL};
    case Access::kSampledGeneral:
      return {VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT, VK_ACCESS_2_SHADER_SAMPLED_READ_BIT,
              VK_IMAGE_LAYOUT_GENERAL};
    case Access::kComputeReadGeneral:
      return {VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_SAMPLED_READ_BIT,
              VK_IMAGE_LAYOUT_GENERAL};
    case Access::kIndirectRead:  // buffers only
    case Access::kGeometryRead:
    case Access::kHostWrite:
    case Access::kHostRead:
      break;
    case Access::kDepthResolve:
      // Depth resolves write in the colour-output stage with colour-attachment access.
      return {kDepthStages | VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT,
              VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT |
                  VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT |
                  VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT,
              VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL};
  }
  return {};
}

BufferAccessInfo ToVulkanBuffer(Access a) {
  switch (a) {
    case Access::kComputeWrite:  // storage writes, and the clears a pass makes before them
      return {VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_ALL_TRANSFER_BIT,
              VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT |
                  VK_ACCESS_2_TRANSFER_WRITE_BIT};
    // Buffer reads: storage buffers, or uniform texel buffers (sampled reads) over them.
    case Access::kComputeRead:
      return {VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
              VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_SAMPLED_READ_BIT};
    case Access::kSampled:
      return {VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT,
              VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_SAMPLED_READ_BIT};
    case Access::kIndirectRead:  // and the storage reads of the dispatches that use them
      return {VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT | VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
              VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_READ_BIT};
    case Access::kGeometryRead:
      return {VK_PIPELINE_STAGE_2_VERTEX_ATTRIBUTE_INPUT_BIT | VK_PIPELINE_STAGE_2_INDEX_INPUT_BIT |
                  VK_PIPELINE_STAGE_2_VERTEX_SHADER_BIT | VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT |
                  VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
              VK_ACCESS_2_VERTEX_ATTRIBUTE_READ_BIT | VK_ACCESS_2_INDEX_READ_BIT |
                  VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_SAMPLED_READ_BIT};
    case Access::kHostWrite:
      return {VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_WRITE_BIT};
    case Access::kHostRead:
      return {VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_READ_BIT};
    default:
      return {VK_PIPELINE_STAGE_2_NONE, VK_ACCESS_2_NONE};
  }
}

VkMemoryBarrier2 BufferBarrier(Access from, Access to) {
  const BufferAccessInfo a = ToVulkanBuffer(from), b = ToVulkanBuffer(to);
  return vk::MakeMemoryBarrier(a.stage, a.access, b.stage, b.access);
}

}  // namespace

vk::ImageTransition Between(Access from, Access to) {
  const AccessInfo a = ToVulkan(from), b = ToVulkan(to);
  return {a.stage, a.access, a.layout, b.stage, b.access, b.layout};
}

absl::StatusOr<std::unique_ptr<GraphExecutor>> GraphExecutor::Create(const vk::Context& ctx) {
  std::unique_ptr<GraphExecutor> e(new GraphExecutor(ctx));
  const VkDevice d = ctx.device();
  VkCommandPoolCreateInfo pci{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  pci.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  pci.queueFamilyIndex = ctx.queue_family();
  VK_RETURN_IF_ERROR(vkCreateCommandPool(d, &pci, nullptr, e->pool_.Replace(d)), "command pool");
  VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  ai.commandPool = e->pool_.get();
  ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  ai.commandBufferCount = 1;
  VK_RETURN_IF_ERROR(vkAllocateCommandBuffers(d, &ai, &e->cmd_), "command buffer");
  VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  VK_RETURN_IF_ERROR(vkCreateFence(d, &fci, nullptr, e->fence_.Replace(d)), "fence");
  VkQueryPoolCreateInfo qi{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
  qi.queryType = VK_QUERY_TYPE_TIMESTAMP;
  qi.queryCount = kMaxTimestamps;
  VK_RETURN_IF_ERROR(vkCreateQueryPool(d, &qi, nullptr, e->timestamps_.Replace(d)), "query pool");
  if (ctx.info().pipeline_statistics) {
    VkQueryPoolCreateInfo si{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    si.queryType = VK_QUERY_TYPE_PIPELINE_STATISTICS;
    si.queryCount = static_cast<uint32_t>(PassId::kCount);
    si.pipelineStatistics = kPipelineStats;
    VK_RETURN_IF_ERROR(vkCreateQueryPool(d, &si, nullptr, e->statistics_.Replace(d)),
                       "statistics pool");
  }
  return e;
}

void GraphExecutor::BeginOneTime() {
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  VK_CHECK(vkResetCommandBuffer(cmd_, 0));
  VK_CHECK(vkBeginCommandBuffer(cmd_, &bi));
}

absl::StatusOr<double> GraphExecutor::EndSubmitAndWait() {
  VK_CHECK(vkEndCommandBuffer(cmd_));
  const auto t0 = Clock::now();
  VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cmd_;
  const VkFence fence = fence_.get();
  VK_RETURN_IF_ERROR(vkQueueSubmit(ctx_.queue(), 1, &si, fence), "vkQueueSubmit");
  VK_RETURN_IF_ERROR(vkWaitForFences(ctx_.device(), 1, &fence, VK_TRUE, UINT64_MAX),
                     "vkWaitForFences");
  VK_CHECK(vkResetFences(ctx_.device(), 1, &fence));
  return MsSince(t0);
}

absl::Status GraphExecutor::SubmitAndWait(bool host_read) {
  if (host_read) {
    vk::CmdMemoryBarrier(cmd_, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                         VK_PIPELINE_STAGE_2_HOST_BIT, VK_ACCESS_2_HOST_READ_BIT);
  }
  return EndSubmitAndWait().status();
}

absl::StatusOr<GraphExecutor::Result> GraphExecutor::Execute(
    const FramePlan& plan, const std::function<const vk::Image&(Resource)>& image,
    const std::function<void(PassId, VkCommandBuffer)>& record, Clock::time_point record_start,
    bool pass_timing) {
  Result result;
  const bool cpu_device = ctx_.info().type == "cpu";
  const bool per_pass_submit = cpu_device && pass_timing;
  result.timing = !cpu_device       ? TimingSource::kGpuTimestamps
                  : per_pass_submit ? TimingSource::kPassWallClock
                                    : TimingSource::kFrameWallClock;
  const VkQueryPool stamps_pool = timestamps_.get();
  const VkQueryPool stats_pool = statistics_.get();
  BeginOneTime();
  vkCmdResetQueryPool(cmd_, stamps_pool, 0, kMaxTimestamps);
  if (stats_pool) vkCmdResetQueryPool(cmd_, stats_pool, 0, static_cast<uint32_t>(PassId::kCount));

  std::vector<double> pass_wall_ms;
  auto t_chunk = record_start;
  const size_t n = plan.passes.size();
  for (size_t i = 0; i < n; ++i) {
    const PlannedPass& pass = plan.passes[i];
    RecordTransitions(pass.before, image);
    vkCmdWriteTimestamp2(cmd_, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, stamps_pool, uint32_t(2 * i));
    const bool stats_query = stats_pool && IsGeometryPass(pass.id);
    if (stats_query) vkCmdBeginQuery(cmd_, stats_pool, uint32_t(pass.id), 0);
    record(pass.id, cmd_);
    if (stats_query) vkCmdEndQuery(cmd_, stats_pool, uint32_t(pass.id));
    vkCmdWriteTimestamp2(cmd_, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, stamps_pool,
                         uint32_t(2 * i + 1));
    if (i + 1 == n) RecordTransitions(plan.after, image);  // imports: as the next frame expects
    if (per_pass_submit && i + 1 < n) {
      result.record_ms += MsSince(t_chunk);
      ASSIGN_OR_RETURN(const double wall, EndSubmitAndWait());
      pass_wall_ms.push_back(wall);
      t_chunk = Clock::now();
      BeginOneTime();
    }
  }
  result.record_ms += MsSince(t_chunk);
  ASSIGN_OR_RETURN(const double wall, EndSubmitAndWait());
  pass_wall_ms.push_back(wall);
  for (double w : pass_wall_ms) result.submit_wait_ms += w;
  result.submissions = uint32_t(pass_wall_ms.size());
  if (n == 0) return result;

  std::vector<uint64_t> stamps(2 * n);
  VK_RETURN_IF_ERROR(
      vkGetQueryPoolResults(ctx_.device(), stamps_pool, 0, uint32_t(stamps.size()),
                            stamps.size() * sizeof(uint64_t), stamps.data(), sizeof(uint64_t),
                            VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT),
      "timestamps");
  const uint32_t bits = ctx_.info().timestamp_valid_bits;
  const uint64_t mask = bits >= 64 ? ~0ull : ((1ull << bits) - 1);
  const double ns = ctx_.info().timestamp_period_ns;
  auto stamp_ms = [&](size_t a, size_t b) {
    return double((stamps[b] - stamps[a]) & mask) * ns * 1e-6;
  };
  for (size_t i = 0; i < n; ++i) {
    const double stamped = stamp_ms(2 * i, 2 * i + 1);
    result.passes.push_back({std::string(PassName(plan.passes[i].id)),
                             per_pass_submit ? pass_wall_ms[i] : stamped, stamped});
  }
  // CPU devices: the wall time (their timestamps misattribute work between passes).
  result.gpu_total_ms = cpu_device ? result.submit_wait_ms : stamp_ms(0, stamps.size() - 1);
  RETURN_IF_ERROR(ReadStatistics(plan, result));
  return result;
}

void GraphExecutor::RecordTransitions(const std::vector<Transition>& transitions,
                                      const std::function<const vk::Image&(Resource)>& image) {
  std::vector<VkImageMemoryBarrier2> images;
  std::vector<VkMemoryBarrier2> memory;
  for (const Transition& t : transitions) {
    if (IsBuffer(t.resource)) {
      memory.push_back(BufferBarrier(t.from, t.to));
    } else {
      images.push_back(vk::MakeImageBarrier(image(t.resource), Between(t.from, t.to)));
    }
  }
  if (images.empty() && memory.empty()) return;
  VkDependencyInfo dep{VK_STRUCTURE_TYPE_DEPENDENCY_INFO};
  dep.memoryBarrierCount = uint32_t(memory.size());
  dep.pMemoryBarriers = memory.data();
  dep.imageMemoryBarrierCount = uint32_t(images.size());
  dep.pImageMemoryBarriers = images.data();
  vkCmdPipelineBarrier2(cmd_, &dep);
}

absl::Status GraphExecutor::ReadStatistics(const FramePlan& plan, Result& result) {
  if (!statistics_) return absl::OkStatus();
  result.pipeline_statistics = true;
  for (const PlannedPass& pass : plan.passes) {
    if (!IsGeometryPass(pass.id)) continue;
    uint64_t values[3] = {};
    VK_RETURN_IF_ERROR(vkGetQueryPoolResults(ctx_.device(), statistics_.get(), uint32_t(pass.id),
                                             1, sizeof(values), values, sizeof(values),
                                             VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT),
                       "pipeline statistics");
    result.primitives_in += values[0];
    result.primitives_clipped += values[1];
    result.fragment_invocations += values[2];
  }
  return absl::OkStatus();
}

}  // namespace tessera
