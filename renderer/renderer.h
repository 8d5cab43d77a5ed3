#pragma once
// Tessera's renderer: the public face used by the daemon, the tools, the tests and the
// benchmarks. Load a scene, render it with a camera and settings, get back RGBA8 pixels with
// the GPU time of every pass. Knows nothing of gRPC; includes no Vulkan header.
//
// Threading: Renderer is thread-safe; LoadScene and Render serialize on the device queue.
// Render is synchronous: it returns after the frame's fence, so nothing it used is in flight.
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "renderer/camera.h"
#include "renderer/device_info.h"
#include "renderer/image_io.h"
#include "renderer/scene/cpu_scene.h"
#include "renderer/scene/gltf_import.h"
#include "renderer/settings.h"
#include "shaders/common/gpu_types.h"  // GpuLightBounds (glm only, no Vulkan)

namespace tessera {

struct RendererOptions {
  std::string device_name;  // substring of the device to use; empty: $TESSERA_DEVICE or best
  bool validation = false;  // Vulkan validation layers (also TESSERA_VALIDATION=1)
  // Optional device features to treat as absent, to test their fallbacks (DisableableFeatures();
  // also TESSERA_DISABLE_FEATURES=a,b).
  std::vector<std::string> disable_features;
  // Treat the device's storage buffer range as at most this many bytes (0: the device's), to
  // test what a scene larger than a device's storage buffers does (vk::ContextOptions).
  uint64_t max_storage_buffer_range = 0;
  // Treat these descriptor limits of the device (named as the spec spells them, e.g.
  // "maxPerStageDescriptorStorageBuffers") as at most these values, to test what a device with
  // smaller limits gets (vk::ContextOptions; also $TESSERA_DESCRIPTOR_LIMITS).
  std::vector<std::pair<std::string, uint32_t>> descriptor_limit_caps;
  // How the visibility passes append pixels to lists (DeviceInfo::subgroup_appends): kAuto, by
  // the kind of device; forced, to test both ways on one device.
  AppendMode appends = AppendMode::kAuto;
  // How the visibility shading dispatches (DeviceInfo::shade_all_materials): kAuto, by the kind
  // of device (or $TESSERA_SHADE_DISPATCH); forced, to test both ways on one device.
  ShadeDispatch shading = ShadeDispatch::kAuto;
  // Not 0: frames lend their pixels where the device copied them (Frame::lent) instead of
  // copying them out of mapped memory into Frame::image.pixels, for callers that encode a frame
  // and drop it (the server, tessera-bench), from at most this many buffers per frame size (the
  // frames a caller holds, plus the one rendering); a frame beyond them, or on a device without
  // host-cached memory, is copied out. 0: every frame owns its pixels.
  uint32_t lent_buffers = 0;
};

// What a loaded scene is, without its geometry.
// An animation as SceneInfo lists it.
struct AnimationSummary {
  std::string name;
  float duration_s = 0.0f;
  uint32_t channels = 0;
};

struct SceneInfo {
  std::string name;
  SceneCounts counts;
  Aabb bounds;
  std::vector<SceneCamera> cameras;
  std::vector<std::string> warnings;
  uint64_t device_bytes = 0;  // buffers + textures on the device
  std::vector<AnimationSummary> animations;
};

class GpuScene;
namespace vk {
class Context;
}
// A scene on the device. Shared by every frame that renders it; freed with the last handle
// (which may outlive the Renderer: the scene keeps the device alive).
class Scene {
 public:
  ~Scene();
  const SceneInfo& info() const { return info_; }

 private:
  friend class Renderer;
  Scene() = default;
  SceneInfo info_;
  std::shared_ptr<vk::Context> device_;  // declared first: destroyed after gpu_
  std::unique_ptr<GpuScene> gpu_;
};
using SceneHandle = std::shared_ptr<const Scene>;

struct PassTiming {
  std::string pass;           // e.g. "depth_prepass"
  double gpu_ms = 0.0;        // the pass's device time (see TimingSource)
  double timestamp_ms = 0.0;  // what the device's timestamps said, for comparison
};

// Where PassTiming::gpu_ms comes from.
enum class TimingSource {
  kGpuTimestamps,   // GPU timestamps around each pass (real GPUs)
  kPassWallClock,   // CPU devices (lavapipe): each pass submitted alone and timed by the wall
                    // clock, because lavapipe's per-pass timestamps misattribute work
  kFrameWallClock,  // CPU devices with Settings::pass_timing off: the frame in one submission,
                    // its total by the wall clock, the passes as the device's timestamps say
};
// "gpu_timestamps", "pass_wall_clock", "frame_wall_clock" (the proto's names, lower case).
std::string_view ToString(TimingSource source);

// CPU stages of one frame, milliseconds.
struct CpuTimings {
  double record_ms = 0.0;       // culling, sorting, uniforms, command recording
  double submit_wait_ms = 0.0;  // vkQueueSubmit until the fence signals (summed over submits)
  uint32_t submissions = 0;     // the frame's queue submissions: 1, or one per pass (pass_timing)
  double readback_ms = 0.0;     // copying the mapped pixels out (~0 when they are lent)
  double encode_ms = 0.0;       // JPEG/PNG encoding (EncodeFrame)
};

struct FrameStats {
  // Geometry culling. A drawable is one node x primitive instance.
  uint32_t drawables = 0;             // in the scene
  uint32_t drawables_in_frustum = 0;  // passed the frustum test (all of them with culling none)
  uint32_t drawables_drawn = 0;       // after frustum and occlusion culling: submitted
  uint32_t drawables_culled = 0;      // drawables - drawables_drawn
  uint32_t drawables_late = 0;        // gpu_occlusion: drawn by the second phase (newly visible)
  uint32_t drawables_stale = 0;       // gpu_occlusion: drawn by the first phase, occluded now
  uint32_t draws = 0;                 // indexed draws executed over all passes (indirect commands)
  uint32_t indirect_draws = 0;        // vkCmdDrawIndexedIndirectCount calls recorded
  uint64_t triangles_submitted = 0;   // over all passes
  // Pipeline statistics queries over the geometry passes, where the device has them.
  bool pipeline_statistics = false;
  uint64_t primitives_in = 0;          // input-assembly primitives
  uint64_t primitives_clipped = 0;     // primitives out of clipping (reach the rasterizer)
  uint64_t fragment_invocations = 0;   // fragment-shader invocations
  // The visibility pipeline's shading pass (0 otherwise): the pixels it shaded (each once; with
  // vis_mlaa also the runner-up surfaces it shaded, runner_up_pixels, except the sky's) and its
  // compute invocations (those rounded up to whole workgroups per material).
  uint64_t shaded_pixels = 0;
  uint64_t shading_invocations = 0;
  // Its compute dispatches: one per material in view (classified per material), or one over
  // every pixel, and vis_mlaa's over its runner-ups (DeviceInfo::shade_all_materials).
  uint32_t shading_dispatches = 0;
  // vis_mlaa: the pixels the resolve grouped: whose samples hit more than one triangle (raster
  // coverage), whose 3x3 neighbourhood shows more than one surface (analytic).
  uint64_t edge_pixels = 0;
  // vis_mlaa: the edge pixels with more than one surface (a runner-up), which geometric AA blends;
  // the others are edges between triangles of one surface, which it passes through.
  uint64_t blend_pixels = 0;
  // vis_mlaa: edge pixels whose runner-up surface (the one with the next most samples, down to
  // one sample, where no neighbour shows it) was shaded as well.
  uint64_t runner_up_pixels = 0;
  uint32_t lights = 0;               // punctual lights shaded (incl. the default sun)
  uint32_t local_lights = 0;         // of which point and spot lights (scene + synthetic)
  // Forward+ (when the light-culling pass ran): lights per tile over all tiles.
  double tile_lights_avg = 0.0;
  uint32_t tile_lights_p50 = 0;
  uint32_t tile_lights_p95 = 0;
  uint32_t tile_lights_max = 0;
  uint32_t tile_overflows = 0;  // tiles with more than kMaxLightsPerTile (256) lights
  // Shadows: lights with shadow maps (the sun counts once), the maps (views) in the atlas this
  // frame, how many of them were rendered (the rest were cached), their draws, and the faces
  // evicted from the atlas to make room.
  uint32_t shadowed_lights = 0;
  uint32_t shadow_views = 0;
  uint32_t shadow_faces_rendered = 0;
  uint32_t shadow_draws = 0;
  uint32_t shadow_evictions = 0;
  // ibl: 1 when this frame baked the environment maps (its sky changed), else 0.
  uint32_t ibl_bakes = 0;
  // Render targets this frame had to make: 0 once the pool holds its size and AA mode's.
  uint32_t targets_created = 0;
  // Animated scenes: drawables that move or deform, and the vertices the skinning pass skinned
  // or morphed this frame (0 when the pose was already on the device).
  uint32_t animated_drawables = 0;
  uint64_t deformed_vertices = 0;
};

// What tests need to check a frame's light culling against the CPU reference.
struct FrameCapture {
  // Set by the caller: also render every drawable's id (no culling) against the frame's depth.
  bool want_ids = false;
  std::vector<uint32_t> ids;      // width x height, drawable + 1 on top at each pixel (0: none)
  std::vector<uint32_t> drawn;    // drawables the frame drew, ascending
  std::vector<float> depth;           // prepass depth, width x height, row-major
  std::vector<uint32_t> tile_counts;  // per tile (| overflow bit)
  std::vector<uint32_t> tile_lights;  // tile * 256 + k
  std::vector<Light> local_lights;    // in the order the lists index
  // What the light culling read: each local light's bounds, and the row bins (row r's lights
  // are row_lights[row_lights[2r] .. row_lights[2r + 1])); made on the CPU or the GPU as the
  // effective light_binning says.
  std::vector<gpu::GpuLightBounds> light_bounds;
  std::vector<uint32_t> row_lights;
  std::vector<float> hdr;  // the tonemap's input (post-AA HDR colour), RGBA, width x height
  // taa on animated scenes, when the motion pass ran: its target, width x height uv offsets of
  // each pixel's surface on last frame's screen from where the camera alone puts it.
  std::vector<glm::vec2> motion;
  float exposure_log2 = 0.0f;  // auto exposure: the view's adapted average log2 luma (else NaN)
  glm::mat4 view{1.0f}, proj{1.0f};
  // The visibility shading: per material, then the sky, the pixel count its list was sized by
  // (x) and how many pixels were appended to it (y). Equal in every entry when each pixel (and
  // runner-up) was counted in the list it was appended to; else a list ran into the next one.
  std::vector<glm::uvec2> shade_lists;
  // The pixels the classification wrote the sky (or a debug view's background) at: those whose
  // surface is none.
  uint64_t background_pixels = 0;
};

struct ReadbackBuffer;  // renderer/graph/readback_ring.h

// A frame's pixels left in the mapped readback buffer the device copied them into, lent to the
// holder (RendererOptions::lent_buffers): what the encoders read without a copy. Move-only;
// dropping it (or Release) hands the buffer back for a later frame, which the device will not
// write before then. It may be read on any thread and may outlive the Renderer.
class LentPixels {
 public:
  LentPixels() = default;
  explicit LentPixels(std::shared_ptr<ReadbackBuffer> buffer);
  LentPixels(LentPixels&& o) noexcept = default;
  LentPixels& operator=(LentPixels&& o) noexcept;
  LentPixels(const LentPixels&) = delete;
  LentPixels& operator=(const LentPixels&) = delete;
  ~LentPixels() { Release(); }

  explicit operator bool() const { return buffer_ != nullptr; }
  std::span<const uint8_t> bytes() const;  // the frame's RGBA; empty when nothing is lent
  void Release();

 private:
  std::shared_ptr<ReadbackBuffer> buffer_;
};

struct Frame {
  // settings.effective.width x height, sRGB RGBA8; with `lent`, pixels is empty and lent holds
  // them (view() reads whichever).
  RgbaImage image;
  LentPixels lent;
  std::vector<PassTiming> passes;  // in execution order
  TimingSource timing = TimingSource::kGpuTimestamps;
  double gpu_total_ms = 0.0;  // first pass start to last pass end (device time)
  CpuTimings cpu;
  FrameStats stats;
  ResolvedSettings settings;  // effective settings and the notes on what changed

  RgbaView view() const {
    return lent ? RgbaView(image.width, image.height, lent.bytes()) : RgbaView(image);
  }
};

// kRgba: not encoded; the pixels stay in the frame (a video session encodes them in order when
// its client is ready for them).
enum class ImageFormat { kJpeg, kPng, kRgba };

// The animation Settings::animation names in a scene: -1 for none ("" or "none"), else its index
// (a name first, then decimal digits as an index). INVALID_ARGUMENT naming settings.animation
// and listing the scene's animations otherwise.
absl::StatusOr<int> FindAnimation(const SceneInfo& info, std::string_view animation);

// Whether `status` says the Vulkan device was lost (Renderer::device_lost).
bool IsDeviceLost(const absl::Status& status);

class Renderer {
 public:
  // Opens the Vulkan device. Errors are one line: no Vulkan, no device matching the name...
  static absl::StatusOr<std::unique_ptr<Renderer>> Create(const RendererOptions& options = {});
  ~Renderer();

  const DeviceInfo& device_info() const;
  DeviceCaps caps() const;

  // Imports (untrusted input: INVALID_ARGUMENT naming file and field) and uploads a glTF scene.
  absl::StatusOr<SceneHandle> LoadScene(const GltfSource& source);
  // Uploads an already-built CPU scene (e.g. BuildDemoScene()).
  absl::StatusOr<SceneHandle> LoadScene(const CpuScene& scene);
  // The device memory LoadScene(scene) will hold (SceneInfo::device_bytes), computed on the CPU
  // from the same layout, so an upload can be refused before it allocates.
  uint64_t EstimateDeviceBytes(const CpuScene& scene) const;
  // Device memory held by this process's renderers now: scenes, render targets, histories.
  static uint64_t DeviceMemoryBytes();

  // Renders one frame. INVALID_ARGUMENT for bad settings/camera (naming the field).
  absl::StatusOr<Frame> Render(const Scene& scene, const Camera& camera, const Settings& settings);
  // The same, also filling `capture` (tests; costs an extra copy and wait).
  absl::StatusOr<Frame> Render(const Scene& scene, const Camera& camera, const Settings& settings,
                               FrameCapture* capture);
  // The same for one of several views of the scene: gpu_occlusion starts from what `view` saw
  // in its last frame (a stream's session id, a job's id; 0 is the default view). Any view id
  // is correct; reusing one per camera keeps the first culling phase accurate.
  absl::StatusOr<Frame> Render(const Scene& scene, const Camera& camera, const Settings& settings,
                               uint64_t view, FrameCapture* capture = nullptr);

  // Drops what `view` remembers of `scene` (taa history, gpu_occlusion visibility), so its next
  // frame starts from reset temporal state: how job frames stay deterministic whatever was
  // rendered before, and how they give the memory back afterwards.
  void ForgetView(const Scene& scene, uint64_t view);

  // Gives back the pixel memory of a frame the caller is done with (after encoding it): the
  // next frames are read back into it instead of into fresh memory (a 4K frame's 33 MB,
  // page-faulted anew each time, cost half of its readback). Thread-safe (encoder threads call
  // it while another frame renders); at most kSparePixelBuffers are kept, the newest.
  void RecyclePixels(std::vector<uint8_t>&& pixels);
  static constexpr size_t kSparePixelBuffers = 2;
  // Drops the frame's pixels: lent ones go back to the ring, owned ones to RecyclePixels.
  void ReleasePixels(Frame& frame);
  // RendererOptions::lent_buffers: the readback buffers it lends from, and how many are lent now.
  struct LendingStats {
    size_t buffers = 0;
    size_t lent = 0;
  };
  LendingStats lending() const;

  // The device was lost (VK_ERROR_DEVICE_LOST: a GPU reset, a driver failure). The frame that
  // met it and every later one fail with UNAVAILABLE (IsDeviceLost), and this renderer does not
  // recover: tesserad exits so that its supervisor starts a fresh process.
  bool device_lost() const;
  // Test hooks: the next Render fails as if the device had been lost; the next Render first
  // blocks for `ms` (a wedged driver). Also TESSERA_TEST_DEVICE_LOST_AFTER_FRAMES=N at Create:
  // the (N+1)th Render meets a lost device.
  void SimulateDeviceLossForTesting();
  void StallNextRenderForTesting(uint32_t ms);
  // The scene's vertex buffer as the device holds it now, vertices [first, first + count): an
  // animated scene's deformed copies after the last frame's skinning pass (tests compare them
  // with the CPU reference).
  absl::StatusOr<std::vector<Vertex>> ReadVerticesForTesting(const Scene& scene, uint64_t first,
                                                              uint64_t count);

  // Validation-layer messages so far (tests require zero).
  uint64_t validation_message_count() const;
  std::vector<std::string> validation_messages() const;

 private:
  struct Impl;
  explicit Renderer(std::unique_ptr<Impl> impl);
  absl::StatusOr<Frame> RenderFrame(const Scene& scene, const Camera& camera,
                                    const Settings& settings, uint64_t view,
                                    FrameCapture* capture);
  std::unique_ptr<Impl> impl_;
};

// Encodes the frame's pixels, owned or lent (JPEG with its settings' quality and chroma
// subsampling, or PNG) and records the time in frame.cpu.encode_ms. JPEG frames of 1920x1080 pixels
// and more are encoded in strips on several threads (image_io.h).
absl::StatusOr<std::vector<uint8_t>> EncodeFrame(Frame& frame, ImageFormat format);

}  // namespace tessera
