#pragma once
// Runs a frame's plan (frame_graph.h) on the device queue. The executor owns the command
// buffer, the fence, the timestamp and pipeline-statistics queries and the per-pass
// submission used on CPU devices, and records every barrier the plan derived from the passes'
// declared uses. Passes record their own commands only.
#include <vulkan/vulkan.h>

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "renderer/graph/frame_graph.h"
#include "renderer/renderer.h"
#include "renderer/vk/context.h"
#include "renderer/vk/handle.h"
#include "renderer/vk/resources.h"

namespace tessera {

// The whole-image transition from one access to another.
vk::ImageTransition Between(Access from, Access to);

class GraphExecutor {
 public:
  using Clock = std::chrono::steady_clock;

  static absl::StatusOr<std::unique_ptr<GraphExecutor>> Create(const vk::Context& ctx);

  // What a frame's execution measured.
  struct Result {
    std::vector<PassTiming> passes;  // in execution order
    TimingSource timing = TimingSource::kGpuTimestamps;
    double gpu_total_ms = 0.0;
    double record_ms = 0.0;       // CPU time recording (from `record_start`)
    double submit_wait_ms = 0.0;  // submit -> fence, summed over the submits
    uint32_t submissions = 0;     // 1, or one per pass (CPU devices with pass_timing)
    // Over the geometry passes, where the device has pipeline statistics.
    bool pipeline_statistics = false;
    uint64_t primitives_in = 0;
    uint64_t primitives_clipped = 0;
    uint64_t fragment_invocations = 0;
  };

  // Records and submits `plan`, and waits for it: before each pass the transitions the plan
  // lists, on the images `image` gives for the resources; GPU timestamps around each pass and
  // pipeline statistics around the geometry passes; `record` records the pass itself. With
  // `pass_timing` (Settings::pass_timing) on CPU devices (lavapipe) each pass is submitted and
  // waited for on its own and timed by the wall clock: lavapipe stamps a pass when its
  // rasterizer threads reach the stamp in their tiles, so a pass rasterized in one batch would
  // read ~0 ms. Without it the frame is one submission everywhere.
  absl::StatusOr<Result> Execute(const FramePlan& plan,
                                 const std::function<const vk::Image&(Resource)>& image,
                                 const std::function<void(PassId, VkCommandBuffer)>& record,
                                 Clock::time_point record_start, bool pass_timing);

  // One-off work outside a frame (test captures, bakes): BeginOneTime(), record into cmd(),
  // then SubmitAndWait(); with `host_read`, transfer writes are made visible to the host.
  VkCommandBuffer cmd() const { return cmd_; }
  void BeginOneTime();
  absl::Status SubmitAndWait(bool host_read);

 private:
  explicit GraphExecutor(const vk::Context& ctx) : ctx_(ctx) {}
  absl::StatusOr<double> EndSubmitAndWait();
  absl::Status ReadStatistics(const FramePlan& plan, Result& result);
  // Image barriers for image resources, memory barriers for buffers, in one dependency.
  void RecordTransitions(const std::vector<Transition>& transitions,
                         const std::function<const vk::Image&(Resource)>& image);

  const vk::Context& ctx_;
  vk::UniqueCommandPool pool_;
  VkCommandBuffer cmd_ = VK_NULL_HANDLE;  // freed with pool_
  vk::UniqueFence fence_;
  vk::UniqueQueryPool timestamps_;
  vk::UniqueQueryPool statistics_;  // one query per PassId; absent without the feature
};

}  // namespace tessera
