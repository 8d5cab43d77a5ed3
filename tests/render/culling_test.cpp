// Geometry culling on the device (validation on): every mode keeps every truly visible drawable
// and renders the same image as no culling, along camera paths through Sponza and through a
// generated city where almost everything is hidden.
//
// "Truly visible" comes from a drawable-id image rendered without culling against the frame's
// depth (FrameCapture::want_ids): the drawables whose id is on top somewhere.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <set>
#include <string>
#include <vector>

#include "renderer/renderer.h"
#include "renderer/scene/city_scene.h"
#include "renderer/scene/gltf_import.h"
#include "shaders/common/gpu_types.h"
#include "shared_renderer.h"

namespace tessera {
namespace {

constexpr uint32_t kWidth = 320, kHeight = 180;

std::string AssetsDir() {
  const char* dir = std::getenv("TESSERA_ASSETS_DIR");
  return dir ? dir : TESSERA_DEFAULT_ASSETS_DIR;
}

Settings Small(CullingMode mode) {
  Settings s;
  s.width = kWidth;
  s.height = kHeight;
  s.culling = mode;
  return s;
}

// "" when the images are equal, else how many pixels differ, by how much at most, and where the
// first is: what a failure on another device needs to tell rounding from a wrong surface.
std::string PixelDifference(const RgbaImage& a, const RgbaImage& b) {
  if (a.width != b.width || a.height != b.height || a.pixels.size() != b.pixels.size())
    return "sizes differ";
  size_t count = 0, first = 0;
  int largest = 0;
  for (size_t p = 0; p + 4 <= a.pixels.size(); p += 4) {
    int d = 0;
    for (size_t c = 0; c < 4; ++c)
      d = std::max(d, std::abs(int(a.pixels[p + c]) - int(b.pixels[p + c])));
    if (d == 0) continue;
    if (count++ == 0) first = p / 4;
    largest = std::max(largest, d);
  }
  if (count == 0) return "";
  return std::to_string(count) + " of " + std::to_string(a.pixels.size() / 4) +
         " pixels differ, by up to " + std::to_string(largest) + "/255; the first at (" +
         std::to_string(first % a.width) + ", " + std::to_string(first / a.width) + ")";
}

std::set<uint32_t> TrulyVisible(const std::vector<uint32_t>& ids) {
  std::set<uint32_t> out;
  for (uint32_t id : ids)
    if (id != 0) out.insert(id - 1);
  return out;
}

// Sums over the frames [first_frame, end_frame) of a path (gpu_occlusion needs a frame or two
// of history before its first phase is accurate).
struct ModeResult {
  uint32_t frames = 0;
  uint64_t drawn = 0, in_frustum = 0, truly_visible = 0;
  uint64_t triangles = 0;
};

// Renders the path once per mode (each mode its own view, so gpu_occlusion carries its history
// from frame to frame) and checks every frame against the unculled one.
std::vector<ModeResult> CheckPath(const Scene& scene, const std::vector<Camera>& path,
                                  const std::string& what, size_t first_frame = 0,
                                  size_t end_frame = SIZE_MAX) {
  Renderer& r = SharedRenderer();
  const CullingMode modes[] = {CullingMode::kNone, CullingMode::kCpuFrustum,
                               CullingMode::kGpuFrustum, CullingMode::kGpuOcclusion};
  std::vector<ModeResult> results(4);
  for (size_t f = 0; f < path.size(); ++f) {
    FrameCapture truth;
    truth.want_ids = true;
    absl::StatusOr<Frame> reference =
        r.Render(scene, path[f], Small(CullingMode::kNone), /*view=*/1, &truth);
    if (!reference.ok()) {
      ADD_FAILURE() << reference.status();
      return results;
    }
    const std::set<uint32_t> visible = TrulyVisible(truth.ids);
    EXPECT_FALSE(visible.empty()) << what << " frame " << f << ": nothing visible";
    for (size_t m = 0; m < 4; ++m) {
      FrameCapture cap;
      absl::StatusOr<Frame> frame = r.Render(scene, path[f], Small(modes[m]), 100 + m, &cap);
      if (!frame.ok()) {
        ADD_FAILURE() << frame.status();
        return results;
      }
      const std::string where =
          what + " frame " + std::to_string(f) + " " + std::string(ToString(modes[m]));
      // Zero false negatives.
      const std::set<uint32_t> drawn(cap.drawn.begin(), cap.drawn.end());
      EXPECT_EQ(drawn.size(), cap.drawn.size()) << where << ": a drawable drawn twice";
      std::vector<uint32_t> missing;
      std::set_difference(visible.begin(), visible.end(), drawn.begin(), drawn.end(),
                          std::back_inserter(missing));
      EXPECT_TRUE(missing.empty())
          << where << ": " << missing.size() << " visible drawables culled, first " << missing[0];
      // The same picture as no culling, pixel for pixel.
      if (frame->image.pixels.size() != reference->image.pixels.size()) {
        ADD_FAILURE() << where << ": image size";
        continue;
      }
      size_t differing = 0;
      for (size_t i = 0; i < frame->image.pixels.size(); i += 4)
        differing +=
            std::equal(frame->image.pixels.begin() + i, frame->image.pixels.begin() + i + 4,
                       reference->image.pixels.begin() + i)
                ? 0
                : 1;
      EXPECT_EQ(differing, 0u) << where << ": pixels differ from the unculled image";
      // Statistics hold together.
      const FrameStats& st = frame->stats;
      EXPECT_EQ(st.drawables_drawn, cap.drawn.size()) << where;
      EXPECT_LE(st.drawables_drawn, st.drawables_in_frustum) << where;
      EXPECT_LE(st.drawables_in_frustum, st.drawables) << where;
      EXPECT_EQ(st.drawables_culled, st.drawables - st.drawables_drawn) << where;
      if (modes[m] != CullingMode::kGpuOcclusion) {
        EXPECT_EQ(st.drawables_late, 0u) << where;
      }
      if (modes[m] == CullingMode::kNone) {
        EXPECT_EQ(st.drawables_drawn, st.drawables) << where;
      }
      if (st.pipeline_statistics) {
        // The device's own count of input primitives matches what the draw lists submitted
        // (plus the forward pipeline's full-screen sky triangle; the visibility pipeline's
        // classification writes its sky in compute).
        const uint64_t sky = frame->settings.effective.pipeline == Pipeline::kForward ? 1 : 0;
        EXPECT_EQ(st.primitives_in, st.triangles_submitted + sky) << where;
      }
      if (std::getenv("TESSERA_CULLING_VERBOSE"))
        std::printf("%s: frustum %u drawn %u late %u stale %u visible %zu\n", where.c_str(),
                    st.drawables_in_frustum, st.drawables_drawn, st.drawables_late,
                    st.drawables_stale, visible.size());
      if (f < first_frame || f >= end_frame) continue;
      ModeResult& res = results[m];
      res.frames++;
      res.drawn += st.drawables_drawn;
      res.in_frustum += st.drawables_in_frustum;
      res.truly_visible += visible.size();
      res.triangles += st.triangles_submitted;
    }
  }
  ExpectNoValidationMessages(r);
  return results;
}

Camera LookAt(glm::vec3 eye, glm::vec3 target) {
  Camera c;
  c.eye = eye;
  c.target = target;
  c.yfov = 1.0f;
  c.znear = 0.1f;
  return c;
}

TEST(CullingTest, SponzaPathKeepsEveryVisibleDrawable) {
  absl::StatusOr<GltfSource> src = LoadGltfSourceFromDisk(AssetsDir() + "/Sponza/glTF/Sponza.gltf");
  ASSERT_TRUE(src.ok()) << src.status();
  absl::StatusOr<SceneHandle> scene = SharedRenderer().LoadScene(*src);
  ASSERT_TRUE(scene.ok()) << scene.status();
  // Down the atrium, a turn towards the arcade, a cut to the upper gallery, and back.
  const std::vector<Camera> path = {
      LookAt({9.0f, 1.6f, -0.4f}, {-5.0f, 3.5f, 0.3f}),
      LookAt({6.0f, 1.6f, -0.2f}, {-8.0f, 3.0f, 0.5f}),
      LookAt({3.0f, 1.6f, 0.0f}, {3.0f, 2.0f, 6.0f}),
      LookAt({0.0f, 1.6f, 0.5f}, {0.0f, 2.0f, -6.0f}),
      LookAt({-6.0f, 6.5f, 3.5f}, {8.0f, 5.0f, 3.5f}),
      LookAt({-10.0f, 1.6f, 0.0f}, {10.0f, 1.6f, 0.0f}),
  };
  const std::vector<ModeResult> r = CheckPath(**scene, path, "sponza");
  // Frustum culling removes something somewhere on this path.
  EXPECT_LT(r[1].drawn, r[0].drawn);
}

TEST(CullingTest, CityPathKeepsEveryVisibleDrawableAndCullsTheHiddenOnes) {
  CityParams params;
  params.facade_detail = 1;
  const CpuScene city = BuildCityScene(params);
  ASSERT_GE(city.drawables.size(), 10000u);
  absl::StatusOr<SceneHandle> scene = SharedRenderer().LoadScene(city);
  ASSERT_TRUE(scene.ok()) << scene.status();
  // Walk up a street at eye height (3 m a frame), turn into a crossing, then a cut to a view
  // from above the roofs, and back down.
  const float x = CityStreetX(params, 5);
  const float z0 = CityStreetZ(params, 10), z1 = CityStreetZ(params, 9);
  std::vector<Camera> path;
  for (int i = 0; i < 6; ++i) {
    const float z = z0 - 2.0f - 3.0f * float(i);
    path.push_back(LookAt({x, 1.7f, z}, {x + 0.2f * float(i), 1.7f, z - 100.0f}));
  }
  for (int i = 0; i < 4; ++i) {
    const float a = 0.4f * float(i);  // radians, turning left towards -x
    path.push_back(
        LookAt({x, 1.7f, z1}, {x - 100.0f * std::sin(a), 1.7f, z1 - 100.0f * std::cos(a)}));
  }
  path.push_back(LookAt({x, 90.0f, z0 + 40.0f}, {x, 0.0f, z1 - 200.0f}));
  path.push_back(LookAt({x, 1.7f, z0 - 2.0f}, {x, 1.7f, z0 - 100.0f}));
  const std::vector<ModeResult> r =
      CheckPath(**scene, path, "city", /*first_frame=*/2, /*end_frame=*/10);
  // At street level almost everything in the frustum is hidden. Over the walk and the turn
  // (the third to the tenth frame: once the view has history, and before the cuts, which cost
  // a frame each),
  // occlusion culling draws a small fraction of what frustum culling keeps.
  EXPECT_LT(r[3].drawn * 3, r[2].drawn) << "occlusion drew " << r[3].drawn << " of " << r[2].drawn;
  EXPECT_LT(r[3].triangles * 3, r[0].triangles);
}

TEST(CullingTest, OcclusionStartsFreshForANewView) {
  // A view's first frame has no history: the first phase draws nothing, the second everything
  // visible; the next frame of the same view draws almost everything in the first phase.
  // Both pipelines: the visibility pass is the depth pass of the visibility pipeline.
  Renderer& r = SharedRenderer();
  const SceneHandle& scene = SharedDemoScene();
  Camera cam;
  cam.eye = {0.0f, 3.0f, 9.0f};
  cam.target = {0.0f, 0.5f, 0.0f};
  for (Pipeline pipeline : {Pipeline::kForward, Pipeline::kVisibility}) {
    const uint64_t view = 7777 + static_cast<uint64_t>(pipeline);
    Settings s = Small(CullingMode::kGpuOcclusion);
    s.pipeline = pipeline;
    absl::StatusOr<Frame> first = r.Render(*scene, cam, s, view);
    ASSERT_TRUE(first.ok()) << first.status();
    EXPECT_GT(first->stats.drawables_drawn, 0u);
    EXPECT_EQ(first->stats.drawables_late, first->stats.drawables_drawn);
    EXPECT_GT(first->stats.triangles_submitted, 0u);
    absl::StatusOr<Frame> second = r.Render(*scene, cam, s, view);
    ASSERT_TRUE(second.ok()) << second.status();
    EXPECT_EQ(second->stats.drawables_drawn, first->stats.drawables_drawn);
    EXPECT_EQ(second->stats.drawables_late, 0u);
    EXPECT_EQ(second->image.pixels, first->image.pixels);
    // The passes of the two-phase frame are all reported.
    std::vector<std::string> names;
    for (const PassTiming& p : second->passes) names.push_back(p.pass);
    // A device without the visibility buffer renders the visibility request forward.
    const bool forward = second->settings.effective.pipeline == Pipeline::kForward;
    EXPECT_EQ(forward, pipeline == Pipeline::kForward || !r.device_info().visibility_buffer);
    for (const char* want : {"cull", forward ? "depth_prepass" : "visibility", "hiz_build",
                             "cull_late", forward ? "depth_prepass_late" : "visibility_late"})
      EXPECT_NE(std::find(names.begin(), names.end(), want), names.end()) << want;
  }
}

// The fallbacks for optional device features, forced on a device that has the features: draws
// without drawIndirectCount (and one command per call without multiDrawIndirect), culling's
// prefix sum without subgroup arithmetic, classification without ballots, the depth pyramid
// without min/max samplers; and every material shaded by the general pipeline instead of its set
// of texture slots' (material_variants: Sponza's materials have two sets); and the scene's
// triangles, its local lights and their tile lists read from storage buffers instead of texel
// buffers (texel_buffers); and on a CPU device with gl_PrimitiveID the visibility pass's indexed
// draws, whose fragment shaders read it, instead of pulled vertices (vertex_pulling), and the
// pulled vertices read from storage buffers (texel_buffers alone off); and on SwiftShader the
// shaders specialized by the driver instead of on the host (host_specialization); and where the
// device indexes sampler arrays (SwiftShader, GPUs), the visibility shading per material over the
// classification's lists instead of one dispatch over every pixel (sampler_indexing). Each frame
// must equal the one the full feature set renders, pixel for pixel, in every culling mode and
// both pipelines; and the frame stats must agree.
TEST(FallbackTest, EveryFallbackRendersTheSamePixels) {
  // The full feature set appends per subgroup even on a CPU device (which by default appends
  // per pixel: DeviceInfo::subgroup_appends), so the lean device's per-pixel appends are
  // compared with the ballots'.
  absl::StatusOr<std::unique_ptr<Renderer>> full =
      Renderer::Create({.validation = true,
                        .appends = AppendMode::kSubgroup,
                        .shading = ShadeDispatch::kAllMaterials});
  ASSERT_TRUE(full.ok()) << full.status();
  Renderer& r = **full;
  EXPECT_EQ(r.device_info().subgroup_appends, r.device_info().subgroup_ballot);
  // The lean device draws the visibility pass indexed, reading gl_PrimitiveID, where the device
  // has it; without it (SwiftShader) pulling is the visibility pass's only way.
  std::vector<std::string> off = {
      "draw_indirect_count", "multi_draw_indirect", "subgroup_arithmetic",
      "subgroup_ballot",     "sampler_minmax",      "material_variants",
      "texel_buffers",       "host_specialization", "sampler_indexing"};
  const bool primitive_id = r.device_info().primitive_id;
  if (primitive_id) off.push_back("vertex_pulling");
  absl::StatusOr<std::unique_ptr<Renderer>> lean =
      Renderer::Create({.validation = true, .disable_features = off});
  ASSERT_TRUE(lean.ok()) << lean.status();
  const DeviceInfo& info = (*lean)->device_info();
  EXPECT_FALSE(info.draw_indirect_count);
  EXPECT_FALSE(info.multi_draw_indirect);
  EXPECT_FALSE(info.subgroup_arithmetic);
  EXPECT_FALSE(info.sampler_minmax);
  EXPECT_FALSE(info.subgroup_ballot);
  EXPECT_FALSE(info.subgroup_appends);
  EXPECT_FALSE(info.material_variants);
  EXPECT_TRUE(r.device_info().material_variants);
  EXPECT_FALSE(info.texel_buffers);
  EXPECT_TRUE(r.device_info().texel_buffers);
  // SwiftShader's shaders specialized on the host, against the driver's specialization.
  EXPECT_FALSE(info.host_specialization);
  EXPECT_EQ(r.device_info().host_specialization,
            r.device_info().driver_name.find("SwiftShader") != std::string::npos)
      << r.device_info().driver_name;
  // One shading dispatch where the device can (forced: CPU devices shade per material by
  // default), per material without sampler indexing.
  EXPECT_FALSE(info.sampler_indexing);
  EXPECT_FALSE(info.shade_all_materials);
  EXPECT_EQ(r.device_info().shade_all_materials, r.device_info().sampler_indexing &&
                                                     r.device_info().subgroup_ballot &&
                                                     r.device_info().visibility_buffer);
  std::printf("visibility shading compared: %s against per material\n",
              r.device_info().shade_all_materials ? "one dispatch" : "per material");
  // Pulled vertices on CPU devices (the test's) and devices without gl_PrimitiveID, indexed
  // draws on other GPUs; the lean device draws indexed where it can.
  EXPECT_EQ(info.vertex_pulling, !primitive_id);
  EXPECT_EQ(r.device_info().vertex_pulling, r.device_info().type == "cpu" || !primitive_id);
  EXPECT_EQ(info.visibility_buffer, r.device_info().visibility_buffer);
  std::vector<std::string> missing;
  for (const DeviceFallback& f : info.fallbacks) missing.push_back(f.missing);
  for (const char* want : {"drawIndirectCount", "multiDrawIndirect"})
    EXPECT_NE(std::find(missing.begin(), missing.end(), want), missing.end()) << want;

  absl::StatusOr<GltfSource> src = LoadGltfSourceFromDisk(AssetsDir() + "/Sponza/glTF/Sponza.gltf");
  ASSERT_TRUE(src.ok()) << src.status();
  absl::StatusOr<SceneHandle> full_scene = r.LoadScene(*src);
  ASSERT_TRUE(full_scene.ok()) << full_scene.status();
  absl::StatusOr<SceneHandle> lean_scene = (*lean)->LoadScene(*src);
  ASSERT_TRUE(lean_scene.ok()) << lean_scene.status();
  // The full feature set but storage buffers: on a CPU device the visibility pass pulls its
  // vertices through them (a scene past the device's texel buffers does), the path neither of
  // the other two devices takes (with the one-dispatch shading where the device can).
  absl::StatusOr<std::unique_ptr<Renderer>> storage =
      Renderer::Create({.validation = true,
                        .disable_features = {"texel_buffers"},
                        .appends = AppendMode::kSubgroup,
                        .shading = ShadeDispatch::kAllMaterials});
  ASSERT_TRUE(storage.ok()) << storage.status();
  EXPECT_EQ((*storage)->device_info().vertex_pulling, r.device_info().vertex_pulling);
  absl::StatusOr<SceneHandle> storage_scene = (*storage)->LoadScene(*src);
  ASSERT_TRUE(storage_scene.ok()) << storage_scene.status();
  Camera cam;  // the atrium: some of Sponza is out of the frustum, some hidden
  cam.eye = {9.0f, 1.6f, -0.4f};
  cam.target = {-5.0f, 3.5f, 0.3f};
  std::vector<Pipeline> pipelines = {Pipeline::kForward};
  if (r.device_info().visibility_buffer) pipelines.push_back(Pipeline::kVisibility);
  for (Pipeline pipeline : pipelines) {
    for (CullingMode mode : {CullingMode::kNone, CullingMode::kCpuFrustum, CullingMode::kGpuFrustum,
                             CullingMode::kGpuOcclusion}) {
      Settings s = Small(mode);
      s.width = 160;
      s.height = 96;
      s.pipeline = pipeline;
      s.synthetic_lights = 64;  // tiled light lists (texel_buffers: read through texel views)
      const std::string what = std::string(ToString(mode)) + " " + std::string(ToString(pipeline));
      const uint64_t view = 300 + uint64_t(mode) * 4 + uint64_t(pipeline);
      for (int frame = 0; frame < 2; ++frame) {  // gpu_occlusion: the second has a history
        absl::StatusOr<Frame> a = r.Render(**full_scene, cam, s, view);
        absl::StatusOr<Frame> b = (*lean)->Render(**lean_scene, cam, s, view);
        ASSERT_TRUE(a.ok()) << a.status();
        ASSERT_TRUE(b.ok()) << b.status();
        EXPECT_EQ(a->image.pixels, b->image.pixels) << what << " frame " << frame;
        if (pipeline == Pipeline::kVisibility) {
          absl::StatusOr<Frame> c = (*storage)->Render(**storage_scene, cam, s, view);
          ASSERT_TRUE(c.ok()) << c.status();
          EXPECT_EQ(a->image.pixels, c->image.pixels) << what << " frame " << frame
                                                      << ", storage buffers";
        }
        EXPECT_EQ(a->stats.drawables_drawn, b->stats.drawables_drawn) << what;
        EXPECT_EQ(a->stats.drawables_in_frustum, b->stats.drawables_in_frustum) << what;
        EXPECT_EQ(a->stats.drawables_late, b->stats.drawables_late) << what;
        EXPECT_EQ(a->stats.triangles_submitted, b->stats.triangles_submitted) << what;
        EXPECT_EQ(a->stats.shaded_pixels, b->stats.shaded_pixels) << what;
        if (frame == 0) {
          std::printf("%-26s indirect draw calls %u with drawIndirectCount, %u without\n",
                      what.c_str(), a->stats.indirect_draws, b->stats.indirect_draws);
        }
      }
    }
  }
  // vis_mlaa: its resolve counts each pixel's surface and its classification lists the
  // runner-ups, one atomic per subgroup and material with ballots, one per pixel without.
  // Both ways of finding the samples (vis_mlaa_coverage: the resolve shaders of each).
  for (VisMlaaCoverage coverage : {VisMlaaCoverage::kRaster, VisMlaaCoverage::kAnalytic}) {
    if (!r.device_info().visibility_buffer || !r.device_info().subgroup_appends) break;
    const std::string what = "vis_mlaa " + std::string(ToString(coverage));
    const uint64_t view = 340 + uint64_t(coverage);
    Settings s = Small(CullingMode::kGpuFrustum);
    s.vis_mlaa_coverage = coverage;
    s.width = 160;
    s.height = 96;
    s.aa = AaMode::kVisMlaa;
    s.samples = 4;
    absl::StatusOr<Frame> a = r.Render(**full_scene, cam, s, view);
    absl::StatusOr<Frame> b = (*lean)->Render(**lean_scene, cam, s, view);
    ASSERT_TRUE(a.ok()) << a.status();
    ASSERT_TRUE(b.ok()) << b.status();
    ASSERT_EQ(b->settings.effective.aa, AaMode::kVisMlaa);
    ASSERT_EQ(b->settings.effective.vis_mlaa_coverage, coverage);
    EXPECT_EQ(PixelDifference(a->image, b->image), "") << what;
    absl::StatusOr<Frame> c = (*storage)->Render(**storage_scene, cam, s, view);
    ASSERT_TRUE(c.ok()) << c.status();
    EXPECT_EQ(PixelDifference(a->image, c->image), "") << what << ", storage buffers";
    // Each device renders the frame again to the same bits: a difference between the devices
    // that either shows against itself is a race, not a fallback. (An NVIDIA H200 failed the
    // comparison above with equal edge, runner-up and shaded counts, before this was checked.)
    absl::StatusOr<Frame> a2 = r.Render(**full_scene, cam, s, view);
    absl::StatusOr<Frame> b2 = (*lean)->Render(**lean_scene, cam, s, view);
    ASSERT_TRUE(a2.ok()) << a2.status();
    ASSERT_TRUE(b2.ok()) << b2.status();
    EXPECT_EQ(PixelDifference(a->image, a2->image), "") << what << " again, full device";
    EXPECT_EQ(PixelDifference(b->image, b2->image), "") << what << " again, lean device";
    EXPECT_GT(a->stats.edge_pixels, 0u);
    EXPECT_EQ(a->stats.edge_pixels, b->stats.edge_pixels);
    EXPECT_EQ(a->stats.runner_up_pixels, b->stats.runner_up_pixels);
    EXPECT_EQ(a->stats.shaded_pixels, b->stats.shaded_pixels);
  }
  ExpectNoValidationMessages(r);
  ExpectNoValidationMessages(**lean);
  ExpectNoValidationMessages(**storage);
}

// The visibility pipeline renders the same frame every time with many shadowed local lights.
// Its shading's loop over a pixel's shadowed lights was a do-while that lavapipe ran
// inconsistently. Where a tile held three or more shadowed lights, 25-383 of this frame's
// 230,400 pixels changed from one run to the next, by up to 41 levels. Two things vary between
// runs: the order of each material's pixel list (from atomic appends), and with it which pixels
// share a subgroup. The loop now counts its iterations first and tests the count at the bottom
// (shaders/common/shading.glsl).
TEST(VisibilityPipelineTest, ShadowedLocalLightsRenderTheSameEveryTime) {
  Renderer& r = SharedRenderer();
  TESSERA_SKIP_WITHOUT_VISIBILITY_BUFFER(r);
  absl::StatusOr<GltfSource> src = LoadGltfSourceFromDisk(AssetsDir() + "/Sponza/glTF/Sponza.gltf");
  ASSERT_TRUE(src.ok()) << src.status();
  absl::StatusOr<SceneHandle> scene = r.LoadScene(*src);
  ASSERT_TRUE(scene.ok()) << scene.status();
  Camera cam;  // the atrium
  cam.eye = {9.0f, 1.6f, -0.4f};
  cam.target = {-5.0f, 3.5f, 0.3f};
  Settings s;
  s.width = 640;
  s.height = 360;
  s.pipeline = Pipeline::kVisibility;
  s.synthetic_lights = 64;
  s.shadows = true;  // the sun and the 16 most important local lights
  absl::StatusOr<Frame> first = r.Render(**scene, cam, s);
  ASSERT_TRUE(first.ok()) << first.status();
  ASSERT_EQ(first->settings.effective.pipeline, Pipeline::kVisibility);
  ASSERT_GE(first->stats.shadowed_lights, 4u);  // the sun and three local lights at least
  for (int run = 1; run < 4; ++run) {
    absl::StatusOr<Frame> again = r.Render(**scene, cam, s);
    ASSERT_TRUE(again.ok()) << again.status();
    EXPECT_EQ(PixelDifference(again->image, first->image), "") << "run " << run;
  }
  ExpectNoValidationMessages(r);
}

// A scene larger than the device's storage buffers (lavapipe's range is 128 MiB: some 2.4
// million vertices) renders the same pixels: the bindings of the scene's index and vertex
// buffers stop at the range and the visibility passes read them through texel views; where
// those are missing too, or vis_mlaa's adjacency does not fit, the frame takes the other path
// and says so. What every frame binds whole (materials, drawables) must fit: the upload is
// refused, naming them. Here the range is taken as smaller than DamagedHelmet's vertex buffer,
// then than its index buffer.
TEST(FallbackTest, SceneLargerThanTheStorageBufferRange) {
  Renderer& r = SharedRenderer();
  if (!r.device_info().visibility_buffer || !r.device_info().texel_buffers)
    GTEST_SKIP() << "needs the visibility buffer and texel buffers";
  absl::StatusOr<GltfSource> src =
      LoadGltfSourceFromDisk(AssetsDir() + "/DamagedHelmet/glTF-Binary/DamagedHelmet.glb");
  ASSERT_TRUE(src.ok()) << src.status();
  absl::StatusOr<CpuScene> cpu = ImportGltf(*src);
  ASSERT_TRUE(cpu.ok()) << cpu.status();
  const uint64_t vertex_bytes = cpu->vertices.size() * sizeof(Vertex);
  const uint64_t index_bytes = cpu->indices.size() * sizeof(uint32_t);  // and the adjacency's
  ASSERT_GT(vertex_bytes, index_bytes + 4096);
  if (cpu->vertices.size() * gpu::kVertexTexels > r.device_info().max_texel_buffer_elements)
    GTEST_SKIP() << "the device's texel buffers do not cover DamagedHelmet's vertices";
  absl::StatusOr<SceneHandle> full_scene = r.LoadScene(*src);
  ASSERT_TRUE(full_scene.ok()) << full_scene.status();
  Camera cam;
  cam.eye = {0.5f, 0.4f, 2.6f};
  cam.target = {0.0f, 0.0f, 0.0f};
  Settings base;
  base.width = 96;  // the pixel lists (vis_mlaa: 12 bytes a pixel) fit every range below
  base.height = 64;
  auto render = [&](Renderer& rr, const Scene& scene, const Settings& s) {
    absl::StatusOr<Frame> f = rr.Render(scene, cam, s);
    EXPECT_TRUE(f.ok()) << f.status();
    return f.ok() ? *std::move(f) : Frame{};
  };
  auto note = [](const Frame& f, const std::string& field) {
    for (const SettingNote& n : f.settings.notes)
      if (n.field == field) return n.message;
    return std::string();
  };
  auto with = [&](Pipeline pipeline, AaMode aa, VisMlaaCoverage coverage) {
    Settings s = base;
    s.pipeline = pipeline;
    s.aa = aa;
    s.samples = 4;
    s.vis_mlaa_coverage = coverage;
    return s;
  };
  using enum VisMlaaCoverage;
  const Settings visibility = with(Pipeline::kVisibility, AaMode::kNone, kAuto);
  const Settings forward = with(Pipeline::kForward, AaMode::kNone, kAuto);
  const Settings analytic = with(Pipeline::kAuto, AaMode::kVisMlaa, kAnalytic);
  const Settings raster = with(Pipeline::kAuto, AaMode::kVisMlaa, kRaster);
  const Settings msaa = with(Pipeline::kAuto, AaMode::kMsaa, kAuto);
  const Frame want_visibility = render(r, **full_scene, visibility);
  const Frame want_forward = render(r, **full_scene, forward);
  const Frame want_analytic = render(r, **full_scene, analytic);
  const Frame want_raster = render(r, **full_scene, raster);
  const Frame want_msaa = render(r, **full_scene, msaa);
  ASSERT_EQ(want_visibility.settings.effective.pipeline, Pipeline::kVisibility);
  ASSERT_EQ(want_analytic.settings.effective.vis_mlaa_coverage, VisMlaaCoverage::kAnalytic);

  struct Case {
    const char* what;
    uint64_t range;
    std::vector<std::string> disabled;
  };
  for (const Case& c : {Case{"vertices past the range", index_bytes + 1024, {}},
                        Case{"vertices past the range, no texel buffers", index_bytes + 1024,
                             {"texel_buffers"}},
                        Case{"indices past the range too", index_bytes - 4, {}}}) {
    SCOPED_TRACE(c.what);
    absl::StatusOr<std::unique_ptr<Renderer>> narrow = Renderer::Create(
        {.validation = true, .disable_features = c.disabled, .max_storage_buffer_range = c.range});
    ASSERT_TRUE(narrow.ok()) << narrow.status();
    absl::StatusOr<SceneHandle> scene = (*narrow)->LoadScene(*src);
    ASSERT_TRUE(scene.ok()) << scene.status();
    const bool texels = c.disabled.empty();
    const Frame vis = render(**narrow, **scene, visibility);
    const Frame mlaa = render(**narrow, **scene, analytic);
    if (texels) {  // the texel views cover the geometry: nothing changes
      EXPECT_EQ(vis.settings.effective.pipeline, Pipeline::kVisibility);
      EXPECT_TRUE(vis.settings.notes.empty()) << note(vis, "pipeline");
      EXPECT_EQ(PixelDifference(vis.image, want_visibility.image), "");
      EXPECT_EQ(mlaa.settings.effective.aa, AaMode::kVisMlaa);
    } else {  // the visibility passes cannot read the geometry: forward, msaa
      EXPECT_EQ(vis.settings.effective.pipeline, Pipeline::kForward);
      EXPECT_NE(note(vis, "pipeline").find("storage buffer range"), std::string::npos)
          << note(vis, "pipeline");
      EXPECT_EQ(PixelDifference(vis.image, want_forward.image), "");
      EXPECT_EQ(mlaa.settings.effective.aa, AaMode::kMsaa);
      EXPECT_NE(note(mlaa, "aa").find("storage buffer range"), std::string::npos)
          << note(mlaa, "aa");
      EXPECT_EQ(PixelDifference(mlaa.image, want_msaa.image), "");
    }
    if (texels && c.range >= index_bytes) {  // the adjacency fits: analytic as asked
      EXPECT_EQ(mlaa.settings.effective.vis_mlaa_coverage, VisMlaaCoverage::kAnalytic);
      EXPECT_TRUE(mlaa.settings.notes.empty()) << note(mlaa, "vis_mlaa_coverage");
      EXPECT_EQ(PixelDifference(mlaa.image, want_analytic.image), "");
    } else if (texels) {  // it does not: raster
      EXPECT_EQ(mlaa.settings.effective.vis_mlaa_coverage, VisMlaaCoverage::kRaster);
      EXPECT_NE(note(mlaa, "vis_mlaa_coverage").find("storage buffer range"), std::string::npos)
          << note(mlaa, "vis_mlaa_coverage");
      EXPECT_EQ(PixelDifference(mlaa.image, want_raster.image), "");
    }
    ExpectNoValidationMessages(**narrow);
  }
  // One material's record past the range: refused at upload, naming it.
  absl::StatusOr<std::unique_ptr<Renderer>> tiny =
      Renderer::Create({.validation = true, .max_storage_buffer_range = 16});
  ASSERT_TRUE(tiny.ok()) << tiny.status();
  absl::StatusOr<SceneHandle> refused = (*tiny)->LoadScene(*src);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument) << refused.status();
  EXPECT_NE(refused.status().message().find("materials"), std::string::npos) << refused.status();
  EXPECT_NE(refused.status().message().find("maxStorageBufferRange"), std::string::npos)
      << refused.status();
  ExpectNoValidationMessages(**tiny);
  ExpectNoValidationMessages(r);
}

// The visibility passes append per subgroup where the device has ballots and is not a CPU
// device, unless told otherwise (DeviceInfo::subgroup_appends).
TEST(FallbackTest, AppendsFollowTheKindOfDeviceUnlessForced) {
  const DeviceInfo& d = SharedRenderer().device_info();
  EXPECT_EQ(d.subgroup_appends, d.subgroup_ballot && d.type != "cpu") << d.type;
  absl::StatusOr<std::unique_ptr<Renderer>> pixel =
      Renderer::Create({.validation = true, .appends = AppendMode::kPixel});
  ASSERT_TRUE(pixel.ok()) << pixel.status();
  EXPECT_FALSE((*pixel)->device_info().subgroup_appends);
  EXPECT_EQ((*pixel)->device_info().subgroup_ballot, d.subgroup_ballot);
}

// A device that cannot draw the visibility buffer (no standard sample locations; or no
// gl_PrimitiveID with vertex pulling turned off) lists why, and renders a request for the
// visibility pipeline forward and one for vis_mlaa as msaa, each saying so, with the pixels of
// the request it became.
TEST(FallbackTest, WithoutTheVisibilityBufferVisibilityRendersForwardAndVisMlaaMsaa) {
  absl::StatusOr<std::unique_ptr<Renderer>> lean =
      Renderer::Create({.validation = true, .disable_features = {"visibility_buffer"}});
  ASSERT_TRUE(lean.ok()) << lean.status();
  Renderer& r = **lean;
  EXPECT_FALSE(r.device_info().visibility_buffer);
  bool listed = false;
  for (const DeviceFallback& f : r.device_info().fallbacks) {
    listed |= f.missing == "visibility_buffer (disabled)" &&
              f.path == "aa vis_mlaa renders msaa; pipeline visibility renders forward";
  }
  EXPECT_TRUE(listed) << "the device's fallbacks say why and what the requests become";
  absl::StatusOr<SceneHandle> scene = r.LoadScene(BuildDemoScene());
  ASSERT_TRUE(scene.ok()) << scene.status();
  Camera cam;
  cam.eye = {0.0f, 3.0f, 9.0f};
  cam.target = {0.0f, 0.5f, 0.0f};
  auto render = [&](Pipeline pipeline, AaMode aa) {
    Settings s = Small(CullingMode::kGpuFrustum);
    s.pipeline = pipeline;
    s.aa = aa;
    absl::StatusOr<Frame> f = r.Render(**scene, cam, s);
    EXPECT_TRUE(f.ok()) << f.status();
    return f.ok() ? std::move(*f) : Frame();
  };
  const Frame forward = render(Pipeline::kForward, AaMode::kNone);
  const Frame visibility = render(Pipeline::kVisibility, AaMode::kNone);
  EXPECT_EQ(visibility.settings.effective.pipeline, Pipeline::kForward);
  EXPECT_TRUE(HasNote(visibility, "pipeline"));
  EXPECT_FALSE(HasNote(forward, "pipeline"));
  EXPECT_EQ(PixelDifference(visibility.image, forward.image), "");

  const Frame msaa = render(Pipeline::kAuto, AaMode::kMsaa);
  const Frame vis_mlaa = render(Pipeline::kAuto, AaMode::kVisMlaa);
  EXPECT_EQ(vis_mlaa.settings.effective.aa, AaMode::kMsaa);
  EXPECT_EQ(vis_mlaa.settings.effective.samples, msaa.settings.effective.samples);
  EXPECT_TRUE(HasNote(vis_mlaa, "aa"));
  EXPECT_EQ(PixelDifference(vis_mlaa.image, msaa.image), "");
  ExpectNoValidationMessages(r);
}

// Feature names are checked: a typo must not silently test the full path.
TEST(FallbackTest, UnknownFeatureIsRefused) {
  absl::StatusOr<std::unique_ptr<Renderer>> r =
      Renderer::Create({.disable_features = {"draw_indirect_cnt"}});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("draw_indirect_cnt"), std::string::npos) << r.status();
  EXPECT_NE(r.status().message().find("draw_indirect_count"), std::string::npos) << r.status();
}

}  // namespace
}  // namespace tessera
