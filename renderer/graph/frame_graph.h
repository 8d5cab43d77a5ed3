#pragma once
// The frame graph's plan: which passes run for a Settings value, in which order, and the
// barriers between them. Each feature (renderer/features/) declares its passes and the
// resources they read and write in its Setup; the graph derives every layout transition from
// those declarations, so no pass hand-codes a barrier for another's output. The plan is pure
// data and is unit-tested without a device; graph/executor.h runs it.
#include <cstdint>
#include <string_view>
#include <vector>

#include "renderer/settings.h"

namespace tessera {

// The frame's transient resources.
// kDepth is always single-sampled: with multisampling it is the resolve of kDepthMs (the
// farthest sample where the device can), which light culling, the depth pyramid, TAA and the
// transparent pass of vis_mlaa read; vis_mlaa_coverage analytic draws it at one sample (the
// pixel centre's depth).
enum class Resource : uint8_t {
  kDepth,
  kHdrColor,  // the shaded frame (for msaa: the resolve of kHdrMs)
  kLdrColor,  // tonemapped, sRGB
  kHiz,
  kDepthMs,        // msaa / vis_mlaa (raster coverage): multisampled depth
  kHdrMs,          // msaa: multisampled colour
  kVisMs,          // vis_mlaa: the visibility ids (drawable | triangle per sample; analytic: one)
  kVisId,          // vis_mlaa, visibility pipeline: per pixel the id of the triangle to shade
  kVisCoverage,    // vis_mlaa: per pixel the coverage mask and mean position of its surface
  kPostHdr,        // taa's output and vis_mlaa's aa_mask view, tonemapped
  kFxaaColor,      // fxaa output, read back
  kAo,             // ssao: visibility (r) and view depth (g), half (or full) resolution
  kAoTemp,         // ssao: the blur's intermediate
  // bloom: the downsample chain (mips from half the frame down) and the upsample chain (one
  // mip fewer; its level 0 is the bloom). The bloom pass writes them (each mip is drawn, then
  // read by the next draw: those per-mip barriers are its own) and hands bloom_up back as a
  // colour target, all mips, so the graph's transition to the tonemap's read covers it.
  kBloomDown,
  kBloomUp,
  kMotion,  // taa on animated scenes: per pixel the object motion beyond the camera's (RG16F uv
            // offsets, 0 where nothing moved), drawn by the motion pass, read by TAA
  // Long-lived resources the renderer keeps between frames and imports into each frame that
  // uses them (graph/frame_graph.h: GraphBuilder::Import): they enter in the state the last
  // frame left them in and leave in the one the next frame expects.
  kShadowAtlas,     // shadows: the atlas of every shadow map (shader-read between frames)
  kTaaHistory,      // taa: the view's last output (read)
  kTaaHistoryNext,  // taa: this frame's output, the next frame's history (written)
  kExposureState,   // auto exposure: the view's adapted average (1x1, general layout)
  // Buffers: the graph orders their uses with memory barriers (they have no layout).
  kDrawLists,       // the indirect draw commands and counts (written by the cull passes or,
                    // for none / cpu_frustum, by the host before the frame)
  kVisibilityBits,  // gpu_occlusion: the view's visibility bits (last frame's read, this
                    // frame's written by the late cull)
  kLightLists,      // forward+: per-tile light counts and lists
  kShadeLists,      // visibility pipeline: per material its pixel count, list offset and
                    // dispatch size, and the pixel lists the shading dispatches read
  kEdgeSurfaces,    // vis_mlaa: per edge pixel its runner-up surface (the resolve's record) and
                    // a colour (the runner-up's shading, then geometric AA's blend)
  kPosedGeometry,   // animated scenes: the drawable records and deformed vertices the skinning
                    // pass writes for the frame's pose (the scene's buffers; only in frames
                    // that run it: every pass that reads the geometry uses it if present)
  kCount
};

// Whether `r` is a buffer (its transitions are memory barriers) rather than an image.
inline bool IsBuffer(Resource r) {
  return r == Resource::kDrawLists || r == Resource::kVisibilityBits ||
         r == Resource::kLightLists || r == Resource::kShadeLists ||
         r == Resource::kEdgeSurfaces || r == Resource::kPosedGeometry;
}
// Barriers inside a pass between its own steps (bloom's and the pyramid's mips, ssao's blur, a
// cull pass's clears before its dispatch, light culling's copy of its counts for the host) are
// the pass's.

// How a pass uses a resource.
enum class Access : uint8_t {
  kNone,            // not yet used this frame (contents undefined)
  kDepthWrite,      // depth attachment, test + write
  kDepthTest,       // depth attachment, test only
  kColorWrite,      // colour attachment
  kSampled,         // read in a fragment shader
  kComputeRead,     // read (sampled) in a compute shader
  kComputeWrite,    // written (storage image) and read back in a compute shader, general layout
  kTransferSrc,     // copied from
  kDepthResolve,    // written by the multisample resolve of a depth attachment
  kSampledGeneral,  // read in a fragment shader in the general layout (auto exposure's state)
  kComputeReadGeneral,  // read (sampled) in a compute shader in the general layout
  // Buffers only (kComputeWrite, kComputeRead and kSampled apply to buffers too: storage writes
  // and clears, storage reads in compute, storage reads in fragment shaders).
  kIndirectRead,  // indirect draw and dispatch commands and counts
  kGeometryRead,  // vertex and index fetch, and storage reads of vertices and drawable records
                  // in any shader stage (the geometry passes, culling, visibility shading)
  kHostWrite,     // written by the host before the frame was submitted
  kHostRead,      // read by the host after the frame
};

struct ResourceUse {
  Resource resource;
  Access access;
};

// Every pass the renderer knows, in the only order they may run.
enum class PassId : uint8_t {
  kSkinning,      // animated scenes: the pose's drawable records and skinned/morphed vertices
  kCull,          // gpu_frustum / gpu_occlusion: indirect draw lists from the drawables (compute)
  kDepthPrepass,  // depth of opaque + alpha-mask geometry, so shading runs once per pixel
  kVisibility,    // vis_mlaa: multisampled ids + depth of opaque + alpha-mask geometry
  kHizBuild,      // gpu_occlusion: the depth pyramid of what the first phase drew
  kCullLate,      // gpu_occlusion: the other drawables against the pyramid
  kDepthPrepassLate,  // gpu_occlusion: depth of the drawables that became visible
  kVisibilityLate,    // gpu_occlusion + vis_mlaa: their ids
  kLightCull,     // forward+: per-tile light lists from the prepass depth (compute)
  kShadows,       // shadows: the atlas faces whose view changed (the atlas is not a frame target)
  kSsao,          // ssao: obscurance from the depth, then a bilateral blur (two directions)
  kVisResolve,    // vis_mlaa: group each pixel's samples by surface, pick the one to shade
  kVisClassify,   // visibility shading: each pixel's material (or the sky), per-material lists
  kShade,         // visibility shading: each listed pixel shaded once (compute, per material)
  kForward,       // PBR shading of opaque + alpha-mask geometry against the prepass depth
  kGeometricAa,   // vis_mlaa: blend partly covered pixels with the neighbours the mask points to
  kTransparent,   // blended materials, back to front, over the opaque result
  kMotion,        // taa, animated scenes: the moved geometry's motion, and the pose kept
  kTaa,           // taa: this frame blended with the reprojected history
  kExposure,      // auto exposure: the frame's average log luma, adapted per view (compute)
  kBloom,         // bloom: soft-threshold, 13-tap downsample chain, tent upsample chain
  kTonemap,       // HDR -> exposure -> tonemap -> sRGB RGBA8
  kFxaa,          // fxaa: one luma-based pass on the tonemapped image
  kReadback,      // RGBA8 image -> host buffer for the encoder
  kCount
};

std::string_view PassName(PassId id);

// What the frame graph needs to know about the scene to pick passes.
struct FrameFeatures {
  bool has_transparent = false;  // any visible BLEND drawable
  uint32_t local_lights = 0;     // point and spot lights to shade
  uint32_t global_lights = 0;    // directional and unbounded lights to shade
  // What the long-lived resources hold as the frame starts (else their contents are undefined).
  bool shadow_atlas_valid = false;  // the atlas holds earlier frames' maps
  bool taa_history_valid = false;   // the view's history holds its last frame
  bool exposure_valid = false;      // the view's exposure state holds an adapted value
  bool pose_pending = false;  // an animated scene's new pose is not on the device yet
  // taa: animated geometry moved since the view's last frame (or the view keeps its first pose):
  // the motion pass runs.
  bool object_motion = false;
  // The shading reads the local lights and the tiles' light lists through texel buffers (they
  // fit the device's maxTexelBufferElements: Renderer::Impl::LightTexelsFit).
  bool light_texels = false;
  // A FrameCapture asks for the frame (tests): the visibility classification also counts the
  // pixels it wrote the sky at (FrameCapture::background_pixels), which frames without one do
  // not pay for (about 8 ms of a mostly-sky 1280x720 frame on lavapipe). The one-dispatch
  // shading (shade_all_materials) counts them in every frame, one atomic per subgroup.
  bool count_background = false;
  // The visibility shading is one dispatch over every pixel, with no classification
  // (DeviceInfo::shade_all_materials).
  bool shade_all_materials = false;
};

// A resource moving from one access to another before a pass.
struct Transition {
  Resource resource;
  Access from;
  Access to;
};

// One pass of a frame: what it uses, and the transitions to make before it runs.
struct PlannedPass {
  PassId id;
  std::vector<ResourceUse> uses;
  std::vector<Transition> before;
};

// A long-lived resource in a frame: the access it enters in (kNone: undefined contents) and
// the one it must leave in.
struct ResourceImport {
  Resource resource;
  Access initial;
  Access final;
};

// The passes of one frame, in order, with every barrier between them.
struct FramePlan {
  std::vector<PlannedPass> passes;
  std::vector<ResourceImport> imports;
  std::vector<Transition> after;  // after the last pass: the imports into their final access
  // The scene's HDR colour as the frame leaves it: what the post passes (exposure, bloom,
  // tonemap) read.
  Resource scene_color = Resource::kHdrColor;

  std::vector<PassId> ids() const;
  bool Has(PassId id) const;
  // The access a resource is left in after the last pass (kNone: unused this frame).
  Access FinalAccess(Resource r) const;
};

// What features declare their passes with. A feature's Setup adds its passes (in the order
// they run) and says what each reads and writes; Build() then derives every transition:
// a transition is emitted when the layout changes or either side writes (write-after-write and
// read-after-write hazards), and between reads in different stages (a compute read then a
// fragment read: the barrier before the first made the last write visible to its stage only);
// the same read again needs none.
class GraphBuilder {
 public:
  GraphBuilder(const Settings& settings, const FrameFeatures& features)
      : settings_(settings), features_(features) {}

  const Settings& settings() const { return settings_; }
  const FrameFeatures& features() const { return features_; }

  // Starts pass `id`; the uses that follow are its own.
  GraphBuilder& Pass(PassId id);
  // The current pass uses `r` as `access`.
  GraphBuilder& Use(Resource r, Access access);
  // The same, only when `r` is present: imported, or written by an earlier pass of this frame
  // (an optional input such as ssao's obscurance or bloom's glow: the feature that makes it
  // decides whether it exists).
  GraphBuilder& UseIfPresent(Resource r, Access access);
  // Whether a pass added so far writes `r`.
  bool Written(Resource r) const;
  // `r` lives across frames: it enters this frame in `initial` (kNone: contents undefined) and
  // leaves it in `final`.
  GraphBuilder& Import(Resource r, Access initial, Access final);
  bool Imported(Resource r) const;
  // The scene's HDR colour as it stands: the post-AA colour once a pass wrote it, else the
  // shaded colour.
  Resource SceneColor() const;

  FramePlan Build() &&;

 private:
  const Settings& settings_;
  const FrameFeatures& features_;
  std::vector<PlannedPass> passes_;
  std::vector<ResourceImport> imports_;
};

// The frame for `settings`: every feature's Setup, in the frame's order
// (renderer/features/frame.cpp).
FramePlan PlanFrame(const Settings& settings, const FrameFeatures& features);

// Convenience for tests and tools: the pass ids of PlanFrame.
std::vector<PassId> SelectPasses(const Settings& settings, const FrameFeatures& features);

}  // namespace tessera
