// Shadows, SSAO, bloom, auto exposure and IBL on the device (lavapipe in CI, validation on):
// goldens of each feature, physical checks that hold whatever the golden (a shadow only removes
// light, and darkens where the sun's ray from an occluder meets the floor; bloom only adds light,
// near what is brighter than white), the shadow cache's face counts, auto exposure against a
// CPU reduction of the captured HDR frame, and the IBL bake's count and orientation.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include "renderer/camera.h"
#include "renderer/image_metrics.h"
#include "renderer/renderer.h"
#include "renderer/scene/demo_scene.h"
#include "tests/render/golden.h"
#include "tests/render/shared_renderer.h"

namespace tessera {
namespace {

constexpr uint32_t kWidth = 320, kHeight = 180;

// The demo scene from behind, where the sun's shadows fall towards the camera.
Camera BackCamera() {
  Camera c;
  c.eye = glm::vec3(-5.0f, 3.5f, -4.0f);
  c.target = glm::vec3(0.0f, 0.4f, 0.0f);
  return c;
}

Settings Lit(bool shadows, bool ssao, AaMode aa = AaMode::kNone) {
  Settings s;
  s.width = kWidth;
  s.height = kHeight;
  s.aa = aa;
  s.shadows = shadows;
  s.ssao = ssao;
  return s;
}

Frame RenderOrDie(const Scene& scene, const Camera& camera, const Settings& s, uint64_t view = 0) {
  absl::StatusOr<Frame> f = SharedRenderer().Render(scene, camera, s, view);
  EXPECT_TRUE(f.ok()) << f.status();
  return f.ok() ? std::move(*f) : Frame{};
}

float Luma(const RgbaImage& image, int x, int y) {
  const uint8_t* p = &image.pixels[(size_t(y) * image.width + x) * 4];
  return 0.2126f * p[0] + 0.7152f * p[1] + 0.0722f * p[2];
}

// Mean luma of the 3x3 pixels around where `world` projects.
float LumaAt(const RgbaImage& image, const Camera& camera, glm::vec3 world) {
  const glm::mat4 vp = ProjectionMatrix(camera, float(image.width) / float(image.height)) *
                       ViewMatrix(camera);
  const glm::vec4 clip = vp * glm::vec4(world, 1.0f);
  const glm::vec2 px = (glm::vec2(clip) / clip.w * 0.5f + 0.5f) *
                       glm::vec2(float(image.width), float(image.height));
  const int x = std::clamp(int(px.x), 1, int(image.width) - 2);
  const int y = std::clamp(int(px.y), 1, int(image.height) - 2);
  float sum = 0.0f;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) sum += Luma(image, x + dx, y + dy);
  return sum / 9.0f;
}

// Lit(shadows on) for each way of shading: the forward pass, the visibility pipeline's shading
// and vis_mlaa's, with a name for the messages.
std::vector<std::pair<std::string, Settings>> ShadowedPaths() {
  std::vector<std::pair<std::string, Settings>> out;
  for (const auto& [pipeline, aa] : {std::pair{Pipeline::kForward, AaMode::kNone},
                                     std::pair{Pipeline::kVisibility, AaMode::kNone},
                                     std::pair{Pipeline::kAuto, AaMode::kVisMlaa}}) {
    Settings on = Lit(true, false, aa);
    on.pipeline = pipeline;
    out.push_back({std::string(ToString(pipeline)) + " " + std::string(ToString(aa)), on});
  }
  return out;
}

// `base` in each way of shading the device has, named "forward", "visibility" and "vis_mlaa"
// (then `suffix`): the forward pass, and where the device draws the visibility buffer the
// visibility pipeline's shading and vis_mlaa's.
std::vector<std::pair<std::string, Settings>> ShadingPaths(Settings base,
                                                           const std::string& suffix = "") {
  std::vector<std::pair<std::string, Settings>> out;
  base.pipeline = Pipeline::kForward;
  out.push_back({"forward" + suffix, base});
  if (SharedRenderer().device_info().visibility_buffer) {
    base.pipeline = Pipeline::kVisibility;
    out.push_back({"visibility" + suffix, base});
    base.pipeline = Pipeline::kAuto;
    base.aa = AaMode::kVisMlaa;
    out.push_back({"vis_mlaa" + suffix, base});
  }
  return out;
}

double MeanLuma(const RgbaImage& image) {
  double sum = 0.0;
  for (uint32_t y = 0; y < image.height; ++y)
    for (uint32_t x = 0; x < image.width; ++x) sum += Luma(image, int(x), int(y));
  return sum / (double(image.width) * image.height);
}

// Where the sun's ray through the centre of the demo's gold sphere meets the floor.
glm::vec3 GoldSphereShadow() {
  const glm::vec3 center(-1.6f, 0.5f, 0.3f);
  const glm::vec3 sun = glm::normalize(glm::vec3(-0.45f, -1.0f, -0.35f));
  return center + sun * (center.y / -sun.y);
}

// An effect that occludes light only removes it: the picture's mean drops, some pixels drop
// clearly, and next to none get brighter. (A few may, by a few levels: the PBR Neutral
// tonemapper subtracts an offset that shrinks with a pixel's darkest channel, so losing the
// light of one colour can lift the other channels of a saturated pixel a little.)
void ExpectOnlyDarker(const RgbaImage& with, const RgbaImage& without, const char* what) {
  ASSERT_EQ(with.pixels.size(), without.pixels.size());
  double sum_with = 0.0, sum_without = 0.0;
  int brighter = 0;
  float largest_drop = 0.0f;
  for (uint32_t y = 0; y < with.height; ++y) {
    for (uint32_t x = 0; x < with.width; ++x) {
      const float a = Luma(with, x, y), b = Luma(without, x, y);
      sum_with += a;
      sum_without += b;
      if (a > b + 3.0f) ++brighter;
      EXPECT_LT(a, b + 12.0f) << what << ": pixel " << x << "," << y << " much brighter";
      largest_drop = std::max(largest_drop, b - a);
    }
  }
  EXPECT_LT(brighter, int(with.width * with.height / 200)) << what << ": pixels brighter";
  EXPECT_LT(sum_with, sum_without) << what << ": the effect darkens nothing on average";
  EXPECT_GT(largest_drop, 10.0f) << what << ": no pixel clearly darker";
}

TEST(ShadowTest, SunShadowFallsWhereTheRayMeetsTheFloor) {
  const SceneHandle& scene = SharedDemoScene();
  const Camera camera = BackCamera();
  const Frame off = RenderOrDie(*scene, camera, Lit(false, false));
  const Frame on = RenderOrDie(*scene, camera, Lit(true, false));
  EXPECT_EQ(on.settings.notes.size(), 0u);
  // The sun, three point lights and a spot light, all in view: every one is shadowed.
  EXPECT_EQ(on.stats.shadowed_lights, 5u);
  EXPECT_EQ(on.stats.shadow_views, 4u + 3u * 6u + 1u);
  const glm::vec3 q = GoldSphereShadow();
  EXPECT_LT(LumaAt(on.image, camera, q), 0.75f * LumaAt(off.image, camera, q));
  ExpectOnlyDarker(on.image, off.image, "shadows");
  ExpectNoValidationMessages(SharedRenderer());
}

TEST(ShadowTest, MatchesGolden) {
  const SceneHandle& scene = SharedDemoScene();
  CompareWithGolden("shadows", RenderOrDie(*scene, BackCamera(), Lit(true, false)).image);
  ExpectNoValidationMessages(SharedRenderer());
}

// The shading finds the shadowed sun at global light 0 (PrepareLights puts directional lights
// first): a global light listed before the sun (a point light without a range, here of no
// intensity) must not take its place, so the picture is the demo's own.
TEST(ShadowTest, SunShadowWhateverTheOrderOfTheGlobalLights) {
  CpuScene cpu = BuildDemoScene();
  Light first;
  first.name = "dark global point light";
  first.type = LightType::kPoint;
  first.intensity = 0.0f;
  first.range = 0.0f;  // global: it reaches everywhere
  first.position = {0.0f, 3.0f, 0.0f};
  cpu.lights.insert(cpu.lights.begin(), first);
  absl::StatusOr<SceneHandle> scene = SharedRenderer().LoadScene(cpu);
  ASSERT_TRUE(scene.ok()) << scene.status();
  for (const auto& [what, on] : ShadowedPaths()) {
    Settings off = on;
    off.shadows = false;
    const Frame reordered = RenderOrDie(**scene, BackCamera(), on);
    const Frame demo = RenderOrDie(*SharedDemoScene(), BackCamera(), on);
    EXPECT_EQ(reordered.stats.shadowed_lights, demo.stats.shadowed_lights) << what;
    absl::StatusOr<double> psnr = Psnr(reordered.image, demo.image);
    ASSERT_TRUE(psnr.ok());
    EXPECT_GT(*psnr, 60.0) << what;
    const glm::vec3 q = GoldSphereShadow();
    const Frame unshadowed = RenderOrDie(**scene, BackCamera(), off);
    EXPECT_LT(LumaAt(reordered.image, BackCamera(), q),
              0.75f * LumaAt(unshadowed.image, BackCamera(), q))
        << what;
  }
  ExpectNoValidationMessages(SharedRenderer());
}

// With shadows the first global light is shaded on its own, and a frame with no other global
// light has no loop over them (kGlobalLightsOn): that light is shaded whether or not it has
// cascades. Here the demo's only light is an unbounded point light (global, and PlaceSun shadows
// directional lights only): the same picture with shadows on as off, nothing else casting any,
// and brighter where it shines than with the light dark.
TEST(ShadowTest, TheOnlyGlobalLightIsShadedWithoutCascades) {
  auto scene_with = [](float intensity) {
    CpuScene cpu = BuildDemoScene();
    Light light;
    light.name = "unbounded point light";
    light.type = LightType::kPoint;
    light.intensity = intensity;
    light.range = 0.0f;  // global: it reaches everywhere
    light.position = {1.0f, 4.0f, 1.0f};
    cpu.lights = {light};
    absl::StatusOr<SceneHandle> scene = SharedRenderer().LoadScene(cpu);
    EXPECT_TRUE(scene.ok()) << scene.status();
    return scene.ok() ? *scene : nullptr;
  };
  const SceneHandle lit = scene_with(200.0f), dark = scene_with(0.0f);
  ASSERT_NE(lit, nullptr);
  ASSERT_NE(dark, nullptr);
  for (const auto& [what, on] : ShadowedPaths()) {
    Settings off = on;
    off.shadows = false;
    const Frame shadowed = RenderOrDie(*lit, BackCamera(), on);
    const Frame unshadowed = RenderOrDie(*lit, BackCamera(), off);
    const Frame unlit = RenderOrDie(*dark, BackCamera(), on);
    EXPECT_EQ(shadowed.stats.shadowed_lights, 0u) << what;
    absl::StatusOr<double> psnr = Psnr(shadowed.image, unshadowed.image);
    ASSERT_TRUE(psnr.ok());
    EXPECT_GT(*psnr, 60.0) << what;
    EXPECT_GT(MeanLuma(shadowed.image), MeanLuma(unlit.image) + 20.0) << what;
  }
  ExpectNoValidationMessages(SharedRenderer());
}

// Point and spot lights alone (the demo without its sun): their cubemaps and spot map.
TEST(ShadowTest, LocalLightsMatchGolden) {
  CpuScene cpu = BuildDemoScene();
  std::erase_if(cpu.lights, [](const Light& l) { return l.type == LightType::kDirectional; });
  absl::StatusOr<SceneHandle> scene = SharedRenderer().LoadScene(cpu);
  ASSERT_TRUE(scene.ok()) << scene.status();
  const Frame off = RenderOrDie(**scene, BackCamera(), Lit(false, false));
  const Frame on = RenderOrDie(**scene, BackCamera(), Lit(true, false));
  EXPECT_EQ(on.stats.shadowed_lights, 4u);
  EXPECT_EQ(on.stats.shadow_views, 3u * 6u + 1u);
  ExpectOnlyDarker(on.image, off.image, "local shadows");
  CompareWithGolden("shadows_local", on.image);
  // The atlas view: a square of depths at the left (the atlas also holds faces other tests
  // cached, so no golden), black beside it.
  Settings atlas = Lit(true, false);
  atlas.debug_view = DebugView::kShadowAtlas;
  const RgbaImage view = RenderOrDie(**scene, BackCamera(), atlas).image;
  int near = 0;
  for (uint32_t y = 0; y < view.height; ++y) {
    for (uint32_t x = 0; x < view.width; ++x) {
      if (x >= view.height + 1) EXPECT_EQ(Luma(view, x, y), 0.0f) << x << "," << y;
      if (x < view.height && Luma(view, x, y) < 250.0f) ++near;
    }
  }
  EXPECT_GT(near, 20) << "no rendered depth in the atlas view";
  ExpectNoValidationMessages(SharedRenderer());
}

// vis_mlaa shades with the same shadow lookups: its picture stays close to the forward one.
TEST(ShadowTest, VisMlaaAgreesWithForward) {
  const SceneHandle& scene = SharedDemoScene();
  const Frame forward = RenderOrDie(*scene, BackCamera(), Lit(true, true, AaMode::kMsaa));
  const Frame vis = RenderOrDie(*scene, BackCamera(), Lit(true, true, AaMode::kVisMlaa));
  const Frame vis_off = RenderOrDie(*scene, BackCamera(), Lit(false, false, AaMode::kVisMlaa));
  absl::StatusOr<double> psnr = Psnr(vis.image, forward.image);
  ASSERT_TRUE(psnr.ok());
  EXPECT_GT(*psnr, 30.0);
  const glm::vec3 q = GoldSphereShadow();
  EXPECT_LT(LumaAt(vis.image, BackCamera(), q), 0.75f * LumaAt(vis_off.image, BackCamera(), q));
  ExpectNoValidationMessages(SharedRenderer());
}

// The cache: a face is rendered again only when its view changes.
TEST(ShadowCacheTest, NothingIsRenderedAgainWhenNothingMoves) {
  const SceneHandle& scene = SharedDemoScene();
  const Settings s = Lit(true, false);
  constexpr uint64_t kView = 4242;
  const Frame first = RenderOrDie(*scene, BackCamera(), s, kView);
  const Frame again = RenderOrDie(*scene, BackCamera(), s, kView);
  EXPECT_GT(again.stats.shadow_views, 0u);
  EXPECT_EQ(again.stats.shadow_faces_rendered, 0u);
  EXPECT_EQ(again.stats.shadow_draws, 0u);
  EXPECT_EQ(again.image.pixels, first.image.pixels);  // cached maps give the same picture

  // The camera moves: only the sun's cascades follow it; the local lights' faces stay.
  Camera moved = BackCamera();
  moved.eye += glm::vec3(0.37f, 0.11f, 0.23f);
  const Frame after_move = RenderOrDie(*scene, moved, s, kView);
  EXPECT_GT(after_move.stats.shadow_faces_rendered, 0u);
  EXPECT_LE(after_move.stats.shadow_faces_rendered, 4u);

  // Without the cache every face is rendered every frame, and the picture is the same.
  Settings uncached = s;
  uncached.shadow_cache = false;
  const Frame full = RenderOrDie(*scene, BackCamera(), uncached, kView);
  EXPECT_EQ(full.stats.shadow_faces_rendered, full.stats.shadow_views);
  EXPECT_EQ(full.image.pixels, first.image.pixels);
  ExpectNoValidationMessages(SharedRenderer());
}

TEST(ShadowCacheTest, MovingLightsRenderOnlyTheirFaces) {
  const SceneHandle& scene = SharedDemoScene();
  Settings s = Lit(true, false);
  s.synthetic_lights = 4;
  s.lights_animated = true;
  s.light_radius_min = s.light_radius_max = 2.0f;
  constexpr uint64_t kView = 4343;
  RenderOrDie(*scene, BackCamera(), s, kView);
  const Frame still = RenderOrDie(*scene, BackCamera(), s, kView);
  EXPECT_EQ(still.stats.shadow_faces_rendered, 0u);
  s.light_time = 0.5f;  // the synthetic lights move, the scene's do not
  const Frame moved = RenderOrDie(*scene, BackCamera(), s, kView);
  EXPECT_GT(moved.stats.shadow_faces_rendered, 0u);
  EXPECT_EQ(moved.stats.shadow_faces_rendered % 6, 0u);  // whole cubemaps, no cascade
  EXPECT_LE(moved.stats.shadow_faces_rendered, 4u * 6u);
  ExpectNoValidationMessages(SharedRenderer());
}

// Each face draws only what is in its frustum; with culling none, everything.
TEST(ShadowCacheTest, FacesAreCulled) {
  const SceneHandle& scene = SharedDemoScene();
  Settings s = Lit(true, false);
  s.shadow_cache = false;
  const Frame culled = RenderOrDie(*scene, BackCamera(), s);
  s.culling = CullingMode::kNone;
  const Frame all = RenderOrDie(*scene, BackCamera(), s);
  EXPECT_LT(culled.stats.shadow_draws, all.stats.shadow_draws);
  EXPECT_EQ(culled.image.pixels, all.image.pixels);
}

TEST(ShadowTest, SmallAtlasSaysWhatIsUnshadowed) {
  const SceneHandle& scene = SharedDemoScene();
  Settings s = Lit(true, false);
  s.shadow_atlas_size = 512;  // the cascades take a quarter; 64-texel faces fill the rest
  s.synthetic_lights = 40;
  s.shadow_lights = 32;
  const Frame f = RenderOrDie(*scene, BackCamera(), s);
  bool noted = false;
  for (const SettingNote& n : f.settings.notes) noted |= n.field == "shadow_lights";
  EXPECT_TRUE(noted);
  // 3/4 of 512^2 holds 48 faces of 64^2: 8 cubemaps, or 7 and the spot light.
  EXPECT_GE(f.stats.shadowed_lights, 1u + 5u);
  EXPECT_LE(f.stats.shadowed_lights, 1u + 9u);
  ExpectNoValidationMessages(SharedRenderer());
}

TEST(SsaoTest, DarkensAmbientOnlyAndMatchesGolden) {
  const SceneHandle& scene = SharedDemoScene();
  const Frame off = RenderOrDie(*scene, BackCamera(), Lit(false, false));
  const Frame on = RenderOrDie(*scene, BackCamera(), Lit(false, true));
  ExpectOnlyDarker(on.image, off.image, "ssao");
  CompareWithGolden("ssao", on.image);
  Settings debug = Lit(false, true);
  debug.debug_view = DebugView::kSsao;
  CompareWithGolden("ssao_debug", RenderOrDie(*scene, BackCamera(), debug).image);
  ExpectNoValidationMessages(SharedRenderer());
}

// Half resolution is an approximation of the full-resolution result, not a different one.
TEST(SsaoTest, HalfResolutionAgreesWithFull) {
  const SceneHandle& scene = SharedDemoScene();
  Settings s = Lit(false, true);
  const Frame half = RenderOrDie(*scene, BackCamera(), s);
  s.ssao_half_res = false;
  const Frame full = RenderOrDie(*scene, BackCamera(), s);
  absl::StatusOr<double> psnr = Psnr(half.image, full.image);
  ASSERT_TRUE(psnr.ok());
  EXPECT_GT(*psnr, 32.0);
  bool ssao_pass = false;
  for (const PassTiming& p : full.passes) ssao_pass |= p.pass == "ssao";
  EXPECT_TRUE(ssao_pass);
  ExpectNoValidationMessages(SharedRenderer());
}

// ---------------------------------------------------------------------------------------------
// Bloom

float LumaHdr(const std::vector<float>& hdr, size_t i) {
  return 0.2126f * hdr[4 * i] + 0.7152f * hdr[4 * i + 1] + 0.0722f * hdr[4 * i + 2];
}

// Bloom adds light and nothing else, and adds it around what is brighter than white (the
// threshold, in exposed units): pixels near such pixels gain much more than pixels far from all.
TEST(BloomTest, AddsLightAroundWhatIsBrighterThanWhite) {
  const SceneHandle& scene = SharedDemoScene();
  Settings s = Lit(false, false);
  FrameCapture capture;
  absl::StatusOr<Frame> off = SharedRenderer().Render(*scene, BackCamera(), s, 0, &capture);
  ASSERT_TRUE(off.ok()) << off.status();
  s.bloom = true;
  s.bloom_strength = 0.5f;
  const Frame on = RenderOrDie(*scene, BackCamera(), s);
  // Distance (Chebyshev, in pixels, capped) from each pixel to the nearest one above 1.5.
  const int w = int(kWidth), h = int(kHeight);
  std::vector<int> dist(size_t(w) * h, 1 << 20);
  int bright = 0;
  for (int i = 0; i < w * h; ++i)
    if (LumaHdr(capture.hdr, size_t(i)) > 1.5f) dist[i] = 0, ++bright;
  ASSERT_GT(bright, 20) << "the demo has highlights brighter than white";
  for (int pass = 0; pass < 2; ++pass) {  // two sweeps of a chamfer transform
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const int yy = pass == 0 ? y : h - 1 - y, xx = pass == 0 ? x : w - 1 - x;
        const int d = pass == 0 ? -1 : 1;
        int& v = dist[size_t(yy) * w + xx];
        for (auto [dx, dy] : {std::pair{d, 0}, {0, d}, {d, d}, {-d, d}}) {
          const int nx = xx + dx, ny = yy + dy;
          if (nx >= 0 && nx < w && ny >= 0 && ny < h) v = std::min(v, dist[size_t(ny) * w + nx] + 1);
        }
      }
    }
  }
  double near_gain = 0.0, far_gain = 0.0;
  int near = 0, far = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float gain = Luma(on.image, x, y) - Luma(off->image, x, y);
      // A few levels down can happen: PBR Neutral's offset shrinks with a pixel's darkest
      // channel, so light added to one channel can dim the others a little (ExpectOnlyDarker).
      EXPECT_GE(gain, -4.0f) << "bloom darkened pixel " << x << "," << y;
      const int d = dist[size_t(y) * w + x];
      if (d >= 1 && d <= 4) near_gain += gain, ++near;
      if (d > 60) far_gain += gain, ++far;
    }
  }
  ASSERT_GT(near, 0);
  ASSERT_GT(far, 0);
  EXPECT_GT(near_gain / near, 2.0) << "no glow next to the highlights";
  // The glow reaches far (six levels: 1/64 of the frame) but falls off.
  EXPECT_GT(near_gain / near, 2.5 * (far_gain / far)) << "the glow does not fall off";
  CompareWithGolden("bloom", on.image);
  s.debug_view = DebugView::kBloom;
  CompareWithGolden("bloom_debug", RenderOrDie(*scene, BackCamera(), s).image);
  ExpectNoValidationMessages(SharedRenderer());
}

// ---------------------------------------------------------------------------------------------
// Auto exposure

// exposure.comp's reduction on the CPU: the mean of clamp(log2(luma)) over a grid of up to
// 64 x 64 points, each the bilinear mean of the 2x2 pixels around a texel corner.
float ReferenceLog2Luma(const std::vector<float>& hdr, uint32_t w, uint32_t h) {
  const uint32_t gw = std::min(w, 64u), gh = std::min(h, 64u);
  double sum = 0.0;
  for (uint32_t j = 0; j < gh; ++j) {
    for (uint32_t i = 0; i < gw; ++i) {
      // floor(x + 0.5) as the shader: ties (5i + 2.5 at 320 wide) round up on both sides.
      const int cx = std::clamp(int(std::floor((i + 0.5) / gw * w + 0.5)), 1, int(w) - 1);
      const int cy = std::clamp(int(std::floor((j + 0.5) / gh * h + 0.5)), 1, int(h) - 1);
      float lum = 0.0f;
      for (int dy = -1; dy <= 0; ++dy)
        for (int dx = -1; dx <= 0; ++dx) lum += 0.25f * LumaHdr(hdr, size_t(cy + dy) * w + cx + dx);
      sum += std::clamp(std::log2(std::max(lum, 1e-5f)), -16.0f, 16.0f);
    }
  }
  return float(sum / (gw * gh));
}

Settings AutoExposure() {
  Settings s = Lit(false, false);
  s.exposure_mode = ExposureMode::kAuto;
  s.tonemapper = Tonemapper::kPhotographic;
  return s;
}

// A single render converges at once: the state is this frame's average, and the picture is the
// fixed-exposure picture at the exposure that maps that average to middle grey.
TEST(AutoExposureTest, MapsTheAverageToMiddleGreyAtOnce) {
  const SceneHandle& scene = SharedDemoScene();
  FrameCapture capture;
  absl::StatusOr<Frame> autof =
      SharedRenderer().Render(*scene, BackCamera(), AutoExposure(), 101, &capture);
  ASSERT_TRUE(autof.ok()) << autof.status();
  const float expected = ReferenceLog2Luma(capture.hdr, kWidth, kHeight);
  EXPECT_NEAR(capture.exposure_log2, expected, 0.01);
  Settings fixed = AutoExposure();
  fixed.exposure_mode = ExposureMode::kFixed;
  fixed.exposure_ev = std::log2(0.18f) - capture.exposure_log2;
  const Frame f = RenderOrDie(*scene, BackCamera(), fixed);
  absl::StatusOr<double> psnr = Psnr(autof->image, f.image);
  ASSERT_TRUE(psnr.ok());
  EXPECT_GT(*psnr, 45.0);
  // exposure_ev compensates: +1 stop brightens the auto-exposed picture.
  Settings brighter = AutoExposure();
  brighter.exposure_ev = 1.0f;
  const Frame b = RenderOrDie(*scene, BackCamera(), brighter, 102);
  ExpectOnlyDarker(autof->image, b.image, "one stop less");
  CompareWithGolden("auto_exposure", autof->image);
  SharedRenderer().ForgetView(*scene, 101);
  SharedRenderer().ForgetView(*scene, 102);
  ExpectNoValidationMessages(SharedRenderer());
}

// In a stream the exposure moves a tenth of the way to each new frame's average; a view's state
// is its own, and forgetting the view starts it afresh.
TEST(AutoExposureTest, AdaptsOverAStreamsFrames) {
  const SceneHandle& scene = SharedDemoScene();
  Camera sky = BackCamera();  // the same place, looking up at the sky: a brighter frame
  sky.target = sky.eye + glm::vec3(0.3f, 1.0f, 0.4f);
  auto state = [&](const Camera& c, uint64_t view) {
    FrameCapture capture;
    absl::StatusOr<Frame> f = SharedRenderer().Render(*scene, c, AutoExposure(), view, &capture);
    EXPECT_TRUE(f.ok()) << f.status();
    return capture.exposure_log2;
  };
  const float floor_avg = state(BackCamera(), 201);
  const float sky_avg = state(sky, 202);
  ASSERT_GT(std::abs(sky_avg - floor_avg), 0.2f) << "the two views should differ in brightness";
  const float one = state(sky, 201);  // view 201 adapts from the floor towards the sky
  EXPECT_NEAR(one, floor_avg + 0.1f * (sky_avg - floor_avg), 1e-3);
  const float two = state(sky, 201);
  EXPECT_NEAR(two, one + 0.1f * (sky_avg - one), 1e-3);
  EXPECT_NEAR(state(sky, 202), sky_avg, 1e-4);  // converged view 202 stays put
  SharedRenderer().ForgetView(*scene, 201);
  EXPECT_NEAR(state(sky, 201), sky_avg, 1e-4);  // a forgotten view starts afresh
  SharedRenderer().ForgetView(*scene, 201);
  SharedRenderer().ForgetView(*scene, 202);
  ExpectNoValidationMessages(SharedRenderer());
}

// ---------------------------------------------------------------------------------------------
// IBL

Settings Ibl(AaMode aa = AaMode::kNone) {
  Settings s = Lit(false, false, aa);
  s.ibl = true;
  return s;
}

TEST(IblTest, MatchesGoldenInBothPaths) {
  const SceneHandle& scene = SharedDemoScene();
  const Frame forward = RenderOrDie(*scene, BackCamera(), Ibl());
  CompareWithGolden("ibl", forward.image);
  const Frame vis = RenderOrDie(*scene, BackCamera(), Ibl(AaMode::kVisMlaa));
  absl::StatusOr<double> psnr = Psnr(vis.image, forward.image);
  ASSERT_TRUE(psnr.ok());
  EXPECT_GT(*psnr, 30.0);
  // IBL changes the ambient light, not the direct: the picture differs from the hemisphere's,
  // but not wildly (the procedural sky is as bright as the hemisphere).
  const Frame hemisphere = RenderOrDie(*scene, BackCamera(), Lit(false, false));
  psnr = Psnr(forward.image, hemisphere.image);
  ASSERT_TRUE(psnr.ok());
  EXPECT_LT(*psnr, 45.0);
  EXPECT_GT(*psnr, 18.0);
  ExpectNoValidationMessages(SharedRenderer());
}

// The split-sum table is RG16F where the device has R16G16_SFLOAT storage images, else RGBA16F
// (two channels used): the same half floats, so the same picture, pixel for pixel.
TEST(IblTest, TheTableInEitherFormatGivesTheSamePicture) {
  absl::StatusOr<std::unique_ptr<Renderer>> wide =
      Renderer::Create({.validation = true, .disable_features = {"storage_rg16f"}});
  ASSERT_TRUE(wide.ok()) << wide.status();
  EXPECT_FALSE((*wide)->device_info().storage_rg16f);
  EXPECT_TRUE(HasFallback((*wide)->device_info(), "R16G16_SFLOAT storage images"));
  std::printf("default device: %s\n", SharedRenderer().device_info().storage_rg16f
                                          ? "RG16F table"
                                          : "RGBA16F table (no R16G16_SFLOAT storage)");
  absl::StatusOr<SceneHandle> scene = (*wide)->LoadScene(BuildDemoScene());
  ASSERT_TRUE(scene.ok()) << scene.status();
  for (const AaMode aa : {AaMode::kNone, AaMode::kVisMlaa}) {
    absl::StatusOr<Frame> f = (*wide)->Render(**scene, BackCamera(), Ibl(aa));
    ASSERT_TRUE(f.ok()) << f.status();
    const Frame g = RenderOrDie(*SharedDemoScene(), BackCamera(), Ibl(aa));
    EXPECT_EQ(f->image.pixels, g.image.pixels);
  }
  EXPECT_EQ((*wide)->validation_message_count(), 0u);
}

// The maps are baked once per sky: a frame with the same sun bakes nothing; another sun bakes.
TEST(IblTest, BakedOncePerSky) {
  const SceneHandle& scene = SharedDemoScene();
  RenderOrDie(*scene, BackCamera(), Ibl());
  EXPECT_EQ(RenderOrDie(*scene, BackCamera(), Ibl()).stats.ibl_bakes, 0u);
  Camera other = BackCamera();
  other.eye.x += 1.0f;
  EXPECT_EQ(RenderOrDie(*scene, other, Ibl()).stats.ibl_bakes, 0u);  // the camera is not the sky
  Settings default_sun = Ibl();
  default_sun.scene_lights = false;  // the built-in sun, from another direction
  EXPECT_EQ(RenderOrDie(*scene, BackCamera(), default_sun).stats.ibl_bakes, 1u);
  EXPECT_EQ(RenderOrDie(*scene, BackCamera(), Ibl()).stats.ibl_bakes, 1u);
  ExpectNoValidationMessages(SharedRenderer());
}

// The environment cube is oriented as the world: looking straight at the sun, its disc is the
// brightest thing in the picture and lies at the centre.
TEST(IblTest, TheSunIsWhereTheLightComesFrom) {
  const SceneHandle& scene = SharedDemoScene();
  const glm::vec3 to_sun = -glm::normalize(glm::vec3(-0.45f, -1.0f, -0.35f));  // demo's sun
  Camera c;
  c.eye = glm::vec3(0.0f, 5.0f, 0.0f);
  c.target = c.eye + to_sun;
  c.yfov = 0.5f;
  const Frame f = RenderOrDie(*scene, c, Ibl());
  // The centroid of the brightest pixels (the disc saturates: many share the maximum).
  float best = -1.0f;
  for (uint32_t y = 0; y < kHeight; ++y)
    for (uint32_t x = 0; x < kWidth; ++x) best = std::max(best, Luma(f.image, x, y));
  double sx = 0.0, sy = 0.0;
  int n = 0;
  for (uint32_t y = 0; y < kHeight; ++y)
    for (uint32_t x = 0; x < kWidth; ++x)
      if (Luma(f.image, x, y) >= best - 1.0f) sx += x + 0.5, sy += y + 0.5, ++n;
  ASSERT_GT(n, 0);
  EXPECT_NEAR(sx / n, kWidth / 2.0, 4.0);
  EXPECT_NEAR(sy / n, kHeight / 2.0, 4.0);
  EXPECT_LT(n, int(kWidth * kHeight / 20)) << "no disc: most of the sky is as bright";
  EXPECT_GT(best, Luma(f.image, 10, 10) + 20.0f) << "no sun disc";
  ExpectNoValidationMessages(SharedRenderer());
}

}  // namespace
}  // namespace tessera

namespace tessera {
namespace {

// The visibility pipeline shades with the same lighting as the forward path: shadows (sun and
// local), SSAO, IBL, forward+ light lists, bloom, auto exposure; and under fxaa and taa.
TEST(VisibilityPipelineTest, MatchesForwardWithEveryEffect) {
  TESSERA_SKIP_WITHOUT_VISIBILITY_BUFFER(SharedRenderer());
  const SceneHandle& scene = SharedDemoScene();
  for (AaMode aa : {AaMode::kNone, AaMode::kFxaa, AaMode::kTaa}) {
    Settings s = Lit(true, true, aa);
    s.ibl = true;
    s.bloom = true;
    s.exposure_mode = ExposureMode::kAuto;
    s.synthetic_lights = 64;
    s.pipeline = Pipeline::kForward;
    // A view of their own each, so taa starts from an empty history in both.
    const Frame forward = RenderOrDie(*scene, BackCamera(), s, 901);
    s.pipeline = Pipeline::kVisibility;
    const Frame vis = RenderOrDie(*scene, BackCamera(), s, 902);
    EXPECT_EQ(vis.settings.effective.pipeline, Pipeline::kVisibility);
    EXPECT_GT(vis.stats.shaded_pixels, 0u);
    EXPECT_GT(vis.stats.tile_lights_max, 0u);  // the light lists were built and read
    absl::StatusOr<double> psnr = Psnr(vis.image, forward.image);
    ASSERT_TRUE(psnr.ok()) << psnr.status();
    EXPECT_GE(*psnr, 40.0) << ToString(aa);
  }
  ExpectNoValidationMessages(SharedRenderer());
}

// The visibility pipeline writes the background at every pixel no surface covers, with the
// hemisphere sky and with IBL's environment, one sample and vis_mlaa: where the sky is most of
// the frame, in its classification's pass over the pixels, and where it is less than a third,
// listed by that pass and written by a dispatch of its own (shaders/common/vis_classify.glsl).
// Each frame matches the forward path's and follows one of the debug view "normals" of the same
// view and size, whose plain background a missed pixel would show.
TEST(VisibilityPipelineTest, WritesTheSkyWhereNoSurfaceIs) {
  TESSERA_SKIP_WITHOUT_VISIBILITY_BUFFER(SharedRenderer());
  const SceneHandle& scene = SharedDemoScene();
  const uint64_t pixels = uint64_t(kWidth) * kHeight;
  uint64_t view = 990;
  for (const float target_y : {2.0f, -1.6f}) {  // the sky 60% of the frame, then 6%
    Camera c = BackCamera();
    c.target.y = target_y;
    for (AaMode aa : {AaMode::kNone, AaMode::kVisMlaa}) {
      for (bool ibl : {false, true}) {
        const std::string name = std::string(ToString(aa)) + (ibl ? " ibl" : "") +
                                 (target_y > 1.0f ? ", much sky" : ", little sky");
        SCOPED_TRACE(name);
        Settings s = Lit(false, false, aa);
        s.ibl = ibl;
        s.pipeline = Pipeline::kVisibility;
        s.debug_view = DebugView::kNormals;
        RenderOrDie(*scene, c, s, view);
        s.debug_view = DebugView::kNone;
        FrameCapture capture;
        absl::StatusOr<Frame> vis = SharedRenderer().Render(*scene, c, s, view, &capture);
        ASSERT_TRUE(vis.ok()) << vis.status();
        ASSERT_EQ(vis->settings.effective.pipeline, Pipeline::kVisibility);
        if (target_y > 1.0f) {
          EXPECT_GT(capture.background_pixels, pixels / 2);
        } else {
          EXPECT_GT(capture.background_pixels, pixels / 40);
          EXPECT_LT(capture.background_pixels, pixels / 3);  // listed
        }
        // Against forward without AA (vis_mlaa: as AaTest.VisMlaaGolden compares it).
        s.pipeline = Pipeline::kForward;
        s.aa = AaMode::kNone;
        const Frame forward = RenderOrDie(*scene, c, s, view + 1);
        absl::StatusOr<double> psnr = Psnr(vis->image, forward.image);
        ASSERT_TRUE(psnr.ok()) << psnr.status();
        EXPECT_GE(*psnr, aa == AaMode::kNone ? 40.0 : 30.0);
        std::printf("%s: sky %.1f%% of the frame, %.2f dB against forward\n", name.c_str(),
                    100.0 * double(capture.background_pixels) / double(pixels), *psnr);
        view += 2;
      }
    }
  }
  ExpectNoValidationMessages(SharedRenderer());
}

// Where the device indexes sampler arrays (DeviceInfo::sampler_indexing: SwiftShader, GPUs), the
// visibility shading in one dispatch over every pixel (DeviceInfo::shade_all_materials: forced
// here, chosen by default on GPUs) against one dispatch per material over the classification's
// lists: the demo scene (textured, alpha-masked and plain materials, the sky at 60% of the frame)
// with shadows, SSAO, IBL and local lights, one sample and vis_mlaa. The same pixels and the same
// counts; no lists, and every pixel either shaded once or the sky. Skipped where the device cannot
// index samplers (lavapipe).
TEST(VisibilityPipelineTest, OneDispatchShadesAsThePerMaterialLists) {
  TESSERA_SKIP_WITHOUT_VISIBILITY_BUFFER(SharedRenderer());
  const DeviceInfo& device = SharedRenderer().device_info();
  if (!device.sampler_indexing || !device.subgroup_ballot) {
    GTEST_SKIP() << device.name << " does not index sampler arrays in compute shaders (or has no "
                 << "subgroup ballots): its visibility shading is per material only";
  }
  absl::StatusOr<std::unique_ptr<Renderer>> all =
      Renderer::Create({.validation = true, .shading = ShadeDispatch::kAllMaterials});
  absl::StatusOr<std::unique_ptr<Renderer>> per =
      Renderer::Create({.validation = true, .shading = ShadeDispatch::kPerMaterial});
  ASSERT_TRUE(all.ok()) << all.status();
  ASSERT_TRUE(per.ok()) << per.status();
  EXPECT_TRUE((*all)->device_info().shade_all_materials);
  EXPECT_FALSE((*per)->device_info().shade_all_materials);
  // GPUs shade in one dispatch unless told otherwise; CPU devices per material.
  EXPECT_EQ(device.shade_all_materials, device.type != "cpu");
  absl::StatusOr<SceneHandle> all_scene = (*all)->LoadScene(BuildDemoScene());
  absl::StatusOr<SceneHandle> per_scene = (*per)->LoadScene(BuildDemoScene());
  ASSERT_TRUE(all_scene.ok()) << all_scene.status();
  ASSERT_TRUE(per_scene.ok()) << per_scene.status();
  Camera c = BackCamera();
  c.target.y = 2.0f;  // the sky 60% of the frame
  const uint64_t pixels = uint64_t(kWidth) * kHeight;
  for (AaMode aa : {AaMode::kNone, AaMode::kVisMlaa}) {
    SCOPED_TRACE(ToString(aa));
    Settings s = Lit(true, true, aa);
    s.pipeline = Pipeline::kVisibility;
    s.ibl = true;
    s.synthetic_lights = 32;
    FrameCapture a_capture, b_capture;
    absl::StatusOr<Frame> a = (*all)->Render(**all_scene, c, s, 0, &a_capture);
    absl::StatusOr<Frame> b = (*per)->Render(**per_scene, c, s, 0, &b_capture);
    ASSERT_TRUE(a.ok()) << a.status();
    ASSERT_TRUE(b.ok()) << b.status();
    ASSERT_EQ(a->settings.effective.pipeline, Pipeline::kVisibility);
    ASSERT_EQ(a->settings.effective.aa, aa);
    EXPECT_TRUE(a->image.pixels == b->image.pixels) << "the pictures differ";
    auto has_pass = [](const Frame& f, const char* name) {
      return std::any_of(f.passes.begin(), f.passes.end(),
                         [&](const PassTiming& p) { return p.pass == name; });
    };
    EXPECT_FALSE(has_pass(*a, "vis_classify"));
    EXPECT_TRUE(has_pass(*b, "vis_classify"));
    EXPECT_EQ(a->stats.shading_dispatches, aa == AaMode::kVisMlaa ? 2u : 1u);
    EXPECT_GT(b->stats.shading_dispatches, 2u);  // the demo's materials in view
    EXPECT_TRUE(a_capture.shade_lists.empty());
    EXPECT_FALSE(b_capture.shade_lists.empty());
    EXPECT_EQ(a->stats.shaded_pixels, b->stats.shaded_pixels);
    EXPECT_EQ(a_capture.background_pixels, b_capture.background_pixels);
    EXPECT_GT(a_capture.background_pixels, pixels / 2);
    EXPECT_EQ(a->stats.edge_pixels, b->stats.edge_pixels);
    EXPECT_EQ(a->stats.blend_pixels, b->stats.blend_pixels);
    EXPECT_EQ(a->stats.runner_up_pixels, b->stats.runner_up_pixels);
    // One invocation per pixel of whole 8x8 tiles (320x180: 40x23 tiles), and vis_mlaa's over
    // its blend list.
    const uint64_t tiles = uint64_t(kWidth / 8) * ((kHeight + 7) / 8);
    if (aa == AaMode::kNone) {
      EXPECT_EQ(a->stats.shaded_pixels + a_capture.background_pixels, pixels);
      EXPECT_EQ(a->stats.shading_invocations, tiles * 64);
    } else {
      EXPECT_GT(a->stats.runner_up_pixels, 0u);
      EXPECT_GE(a->stats.shading_invocations, tiles * 64 + a->stats.runner_up_pixels);
      EXPECT_LE(a->stats.shading_invocations, tiles * 64 + a->stats.blend_pixels + 63);
    }
  }
  ExpectNoValidationMessages(**all);
  ExpectNoValidationMessages(**per);
}

// SSAO and bloom run as fragment or compute shaders (post_stage): the same picture. (Compute
// derives each pixel's uv from its index where the fragment shader interpolates it, so bloom's
// bilinear taps may differ in the last bit.)
// At 320x180 bloom's compute downsample runs both its variants: levels 0, 1 and 3 halve their
// source exactly (2x2 pixels an invocation, bloom_down.comp's kBloomDownQuads), levels 2 (80x45 to
// 40x22), 4 (20x11 to 10x5) and 5 do not (a pixel an invocation, as the fragment shader).
TEST(PostStageTest, SsaoAndBloomAgreeInBothStages) {
  const SceneHandle& scene = SharedDemoScene();
  Settings s = Lit(false, true);
  s.bloom = true;
  s.exposure_mode = ExposureMode::kAuto;
  // The frame in each stage (views `view` and `view + 1`), and the two compared.
  constexpr PostStage kStages[2] = {PostStage::kFragment, PostStage::kCompute};
  auto in_both_stages = [&](uint64_t view) {
    std::array<Frame, 2> frames;
    for (int i = 0; i < 2; ++i) {
      s.post_stage = kStages[i];
      frames[i] = RenderOrDie(*scene, BackCamera(), s, view + i);
    }
    return frames;
  };
  auto expect_same = [](const std::array<Frame, 2>& frames) {
    absl::StatusOr<double> psnr = Psnr(frames[0].image, frames[1].image);
    ASSERT_TRUE(psnr.ok()) << psnr.status();
    EXPECT_GE(*psnr, 55.0);
  };
  const std::array<Frame, 2> picture = in_both_stages(950);
  for (int i = 0; i < 2; ++i) EXPECT_EQ(picture[i].settings.effective.post_stage, kStages[i]);
  expect_same(picture);
  // The AO itself: the same; the tonemap's sRGB encoding (its own in compute, the target's in
  // fragment) may round differently (see TonemapInComputeGivesTheSamePicture).
  s.debug_view = DebugView::kSsao;
  expect_same(in_both_stages(960));
  s.debug_view = DebugView::kBloom;  // the bloom itself
  expect_same(in_both_stages(970));
  ExpectNoValidationMessages(SharedRenderer());
}

}  // namespace
}  // namespace tessera

namespace tessera {
namespace {

// The tonemap in compute sRGB-encodes in the shader what the fragment path's sRGB target
// encodes: the same picture for both tonemappers and the debug views it draws, and with FXAA
// after it (FXAA in compute samples the UNORM image through an sRGB view, as the fragment FXAA
// samples the sRGB image). Not the same bytes everywhere: lavapipe's
// sRGB targets round their encoding differently (up to a third of the bytes of a debug view
// differ, by one step, and a few by up to 3 in the darks, where the curve is steepest), the
// shader uses the exact IEC 61966-2-1 curve.
TEST(PostStageTest, TonemapInComputeGivesTheSamePicture) {
  const SceneHandle& scene = SharedDemoScene();
  struct Case {
    Tonemapper tonemapper;
    DebugView view;
  };
  uint64_t view = 980;
  for (const Case& c : {Case{Tonemapper::kPbrNeutral, DebugView::kNone},
                        Case{Tonemapper::kPhotographic, DebugView::kNone},
                        Case{Tonemapper::kPbrNeutral, DebugView::kNormals},
                        Case{Tonemapper::kPbrNeutral, DebugView::kSsao},
                        Case{Tonemapper::kPbrNeutral, DebugView::kBloom}}) {
    Settings s = Lit(true, true);
    s.bloom = true;
    s.exposure_mode = ExposureMode::kAuto;
    s.tonemapper = c.tonemapper;
    s.debug_view = c.view;
    Frame f[2];
    for (int i = 0; i < 2; ++i) {
      s.post_stage = i == 0 ? PostStage::kFragment : PostStage::kCompute;
      f[i] = RenderOrDie(*scene, BackCamera(), s, ++view);
    }
    ASSERT_EQ(f[0].image.pixels.size(), f[1].image.pixels.size());
    int worst = 0;
    size_t differing = 0;
    for (size_t k = 0; k < f[0].image.pixels.size(); ++k) {
      const int d = std::abs(int(f[0].image.pixels[k]) - int(f[1].image.pixels[k]));
      worst = std::max(worst, d);
      differing += d != 0;
    }
    EXPECT_LE(worst, 3) << ToString(c.tonemapper) << " " << ToString(c.view);
    std::printf("tonemap %s %s: %zu of %zu bytes differ, by %d at most\n",
                std::string(ToString(c.tonemapper)).c_str(), std::string(ToString(c.view)).c_str(),
                differing, f[0].image.pixels.size(), worst);
    absl::StatusOr<double> psnr = Psnr(f[0].image, f[1].image);
    ASSERT_TRUE(psnr.ok()) << psnr.status();
    EXPECT_GE(*psnr, 50.0) << ToString(c.tonemapper) << " " << ToString(c.view);
  }
  // FXAA after the tonemap, both in the stage asked for. Its edge pixels blend their neighbours
  // in linear light in both stages; the tonemap's rounding differences (above) reach it only
  // through its input.
  Settings fxaa = Lit(true, true, AaMode::kFxaa);
  Frame with_fxaa[2];
  for (int i = 0; i < 2; ++i) {
    fxaa.post_stage = i == 0 ? PostStage::kFragment : PostStage::kCompute;
    with_fxaa[i] = RenderOrDie(*scene, BackCamera(), fxaa, ++view);
    EXPECT_EQ(with_fxaa[i].settings.effective.post_stage, fxaa.post_stage);
  }
  // A one-step difference in the tonemapped input can tip FXAA's edge test or its search, so
  // a few bytes differ by more; they must stay few (0.5 %; the sRGB view's absence makes 74 %).
  const size_t bytes = with_fxaa[0].image.pixels.size();
  size_t far = 0;
  for (size_t k = 0; k < bytes; ++k)
    far += std::abs(int(with_fxaa[0].image.pixels[k]) - int(with_fxaa[1].image.pixels[k])) > 3;
  absl::StatusOr<double> psnr = Psnr(with_fxaa[0].image, with_fxaa[1].image);
  ASSERT_TRUE(psnr.ok()) << psnr.status();
  std::printf("fxaa: compute vs fragment %.2f dB, %zu of %zu bytes differ by more than 3\n",
              *psnr, far, bytes);
  EXPECT_LE(far, bytes / 200);  // measured on lavapipe: 200 of 230400 (0.09 %)
  EXPECT_GE(*psnr, 50.0);
  // FXAA changed the picture (it found edges), so the comparison above covers its work.
  Settings plain = fxaa;
  plain.aa = AaMode::kNone;
  plain.post_stage = PostStage::kCompute;
  const Frame without = RenderOrDie(*scene, BackCamera(), plain, ++view);
  absl::StatusOr<double> changed = Psnr(without.image, with_fxaa[1].image);
  ASSERT_TRUE(changed.ok()) << changed.status();
  std::printf("fxaa: with vs without %.2f dB\n", *changed);
  EXPECT_LT(*changed, 45.0);
  ExpectNoValidationMessages(SharedRenderer());
}

// The material at pixel (x, y) of a kWidth-wide capture with ids, where its 3x3 neighbourhood
// shows one drawable (else -1: an edge or the sky).
int InteriorMaterial(const CpuScene& cpu, const FrameCapture& c, uint32_t x, uint32_t y) {
  const uint32_t id = c.ids[size_t(y) * kWidth + x];
  if (id == 0) return -1;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx)
      if (c.ids[size_t(int(y) + dy) * kWidth + (int(x) + dx)] != id) return -1;
  return int(cpu.primitives[cpu.drawables[id - 1].primitive].material);
}

glm::vec3 HdrAt(const FrameCapture& c, uint32_t x, uint32_t y) {
  const float* p = &c.hdr[(size_t(y) * kWidth + x) * 4];
  return glm::vec3(p[0], p[1], p[2]);
}

// Where the device indexes sampler arrays, the visibility pipeline shading `cpu` in one dispatch
// (GPUs' default) gives the same picture as per material: two renderers of their own, each at
// its first frame (SSAO's noise follows the frame count).
void ExpectOneDispatchShadesAsPerMaterial(const CpuScene& cpu, Settings s) {
  const DeviceInfo& device = SharedRenderer().device_info();
  if (!device.visibility_buffer || !device.sampler_indexing || !device.subgroup_ballot) return;
  s.pipeline = Pipeline::kVisibility;
  Frame frames[2];
  for (int i = 0; i < 2; ++i) {
    absl::StatusOr<std::unique_ptr<Renderer>> r = Renderer::Create(
        {.validation = true,
         .shading = i == 0 ? ShadeDispatch::kAllMaterials : ShadeDispatch::kPerMaterial});
    ASSERT_TRUE(r.ok()) << r.status();
    absl::StatusOr<SceneHandle> scene = (*r)->LoadScene(cpu);
    ASSERT_TRUE(scene.ok()) << scene.status();
    absl::StatusOr<Frame> f = (*r)->Render(**scene, BackCamera(), s);
    ASSERT_TRUE(f.ok()) << f.status();
    frames[i] = std::move(*f);
    ExpectNoValidationMessages(**r);
  }
  EXPECT_EQ(frames[0].stats.shading_dispatches, 1u);
  EXPECT_GT(frames[1].stats.shading_dispatches, 1u);
  EXPECT_TRUE(frames[0].image.pixels == frames[1].image.pixels) << "one dispatch shades otherwise";
}

// KHR_materials_unlit (Material::unlit): an unlit surface's HDR colour is its base colour, the
// same under no effect and under every one (shadows, SSAO, IBL, local lights), in the forward
// pass, the visibility pipeline's shading and vis_mlaa's. The demo scene with its red plastic
// (a constant base colour: the CPU's value) and its textured metal (the base-colour debug view's
// value in the same frame, which samples the same texture) made unlit; only pixels whose 3x3
// neighbourhood shows one drawable are compared, so no edge between surfaces enters.
TEST(UnlitTest, ShowsItsBaseColourWhateverTheLight) {
  CpuScene cpu = BuildDemoScene();
  glm::vec3 red{0.0f};
  std::vector<bool> unlit(cpu.materials.size(), false);
  for (size_t m = 0; m < cpu.materials.size(); ++m) {
    Material& mat = cpu.materials[m];
    if (mat.name != "Red plastic" && mat.name != "Checker metal-roughness") continue;
    mat.unlit = true;
    unlit[m] = true;
    if (mat.name == "Red plastic") red = glm::vec3(mat.base_color_factor);
  }
  ASSERT_NE(red, glm::vec3(0.0f));
  absl::StatusOr<SceneHandle> scene = SharedRenderer().LoadScene(cpu);
  ASSERT_TRUE(scene.ok()) << scene.status();
  auto material_at = [&](const FrameCapture& c, uint32_t x, uint32_t y) {
    return InteriorMaterial(cpu, c, x, y);
  };
  Settings plain = Lit(false, false);
  plain.pipeline = Pipeline::kForward;
  Settings every = Lit(true, true);
  every.ibl = true;
  every.synthetic_lights = 64;
  std::vector<std::pair<std::string, Settings>> cases = {{"forward, no effects", plain}};
  for (const auto& path : ShadingPaths(every, ", every effect")) cases.push_back(path);
  for (const auto& [name, settings] : cases) {
    SCOPED_TRACE(name);
    FrameCapture c;
    c.want_ids = true;
    absl::StatusOr<Frame> f = SharedRenderer().Render(**scene, BackCamera(), settings, 0, &c);
    ASSERT_TRUE(f.ok()) << f.status();
    // The base colour at each pixel, as the same frame's debug view shows it (vis_mlaa's
    // shading smooths the checker's edges as it does any texture's).
    Settings base = settings;
    base.debug_view = DebugView::kBaseColor;
    FrameCapture reference;
    reference.want_ids = true;
    ASSERT_TRUE(SharedRenderer().Render(**scene, BackCamera(), base, 0, &reference).ok());
    ASSERT_EQ(c.hdr.size(), size_t(kWidth) * kHeight * 4);
    size_t red_pixels = 0, textured_pixels = 0, textured_far = 0, lit_pixels = 0, lit_far = 0;
    for (uint32_t y = 1; y + 1 < kHeight; ++y) {
      for (uint32_t x = 1; x + 1 < kWidth; ++x) {
        const int m = material_at(c, x, y);
        if (m < 0 || m != material_at(reference, x, y)) continue;
        const glm::vec3 got = HdrAt(c, x, y);
        const glm::vec3 want = HdrAt(reference, x, y);
        const float diff = glm::length(got - want);
        if (!unlit[m]) {  // a lit surface: lighting makes it differ from its base colour
          ++lit_pixels;
          lit_far += diff > 0.05f;
        } else if (cpu.materials[m].base_color.texture < 0) {
          ++red_pixels;
          ASSERT_LT(glm::length(got - red), 2e-3f)
              << "pixel " << x << "," << y << ": " << got.r << " " << got.g << " " << got.b;
        } else {
          ++textured_pixels;
          textured_far += diff > 1.0f / 64.0f;
        }
      }
    }
    std::printf(
        "unlit, %s: %zu red and %zu textured pixels (%zu differ from the base colour); "
        "%zu of %zu lit pixels differ\n",
        name.c_str(), red_pixels, textured_pixels, textured_far, lit_far, lit_pixels);
    EXPECT_GT(red_pixels, 100u);
    EXPECT_GT(textured_pixels, 100u);
    EXPECT_LE(textured_far, textured_pixels / 100);
    EXPECT_GT(lit_far, lit_pixels / 2);  // the comparison can tell lit from unlit
  }
  ExpectNoValidationMessages(SharedRenderer());
}

// COLOR_0 (Vertex::color, Primitive::vertex_colors) multiplies the base colour, interpolated
// across each triangle, in the forward pass, the visibility pipeline's shading and vis_mlaa's. The
// demo scene with its floor's vertices one colour `k` and its torus's a gradient: in the
// base-colour view each floor pixel is `k` times the plain scene's (the checker texture's), and
// the visibility shading's torus matches the forward pass's; a lit frame changes there too.
TEST(VertexColorTest, MultipliesTheBaseColourInEveryPath) {
  const CpuScene plain_cpu = BuildDemoScene();
  CpuScene cpu = plain_cpu;
  const glm::vec4 k(0.25f, 0.5f, 1.0f, 1.0f);
  int floor_material = -1, torus_material = -1;
  for (const Drawable& d : cpu.drawables) {
    const std::string& name = cpu.meshes[d.mesh].name;
    if (name != "Floor" && name != "Copper torus") continue;
    Primitive& p = cpu.primitives[d.primitive];
    p.vertex_colors = true;
    for (uint32_t v = p.first_vertex; v < p.first_vertex + p.vertex_count; ++v) {
      const glm::vec3 q = cpu.vertices[v].position;
      cpu.vertices[v].color =
          name == "Floor" ? PackVertexColor(k)
                          : PackVertexColor(glm::vec4(0.5f + 0.5f * glm::sin(q * 7.0f), 1.0f));
    }
    (name == "Floor" ? floor_material : torus_material) = int(p.material);
  }
  ASSERT_GE(floor_material, 0);
  ASSERT_GE(torus_material, 0);
  absl::StatusOr<SceneHandle> plain = SharedRenderer().LoadScene(plain_cpu);
  absl::StatusOr<SceneHandle> colored = SharedRenderer().LoadScene(cpu);
  ASSERT_TRUE(plain.ok()) << plain.status();
  ASSERT_TRUE(colored.ok()) << colored.status();
  auto material_at = [&](const FrameCapture& c, uint32_t x, uint32_t y) {
    return InteriorMaterial(cpu, c, x, y);
  };
  auto render = [&](const SceneHandle& scene, const Settings& s, FrameCapture* c) {
    c->want_ids = true;
    absl::StatusOr<Frame> f = SharedRenderer().Render(*scene, BackCamera(), s, 0, c);
    ASSERT_TRUE(f.ok()) << f.status();
    ASSERT_EQ(c->hdr.size(), size_t(kWidth) * kHeight * 4);
  };

  Settings base = Lit(false, false);
  base.debug_view = DebugView::kBaseColor;
  FrameCapture forward_torus;
  for (const auto& [name, settings] : ShadingPaths(base)) {
    SCOPED_TRACE(name);
    FrameCapture with, without;
    render(*colored, settings, &with);
    render(*plain, settings, &without);
    if (HasFatalFailure()) return;
    if (name == "forward") forward_torus = with;
    size_t floor_pixels = 0, torus_pixels = 0, torus_far = 0;
    for (uint32_t y = 1; y + 1 < kHeight; ++y) {
      for (uint32_t x = 1; x + 1 < kWidth; ++x) {
        const int m = material_at(with, x, y);
        if (m < 0 || m != material_at(without, x, y)) continue;
        if (m == floor_material) {
          ++floor_pixels;
          const glm::vec3 want = glm::vec3(k) * HdrAt(without, x, y);
          ASSERT_LT(glm::length(HdrAt(with, x, y) - want), 2e-3f + 2e-3f * glm::length(want))
              << "floor pixel " << x << "," << y;
        } else if (m == torus_material && name == "visibility" &&
                   material_at(forward_torus, x, y) == m) {
          ++torus_pixels;
          torus_far += glm::length(HdrAt(with, x, y) - HdrAt(forward_torus, x, y)) > 1.0f / 64;
        }
      }
    }
    std::printf(
        "vertex colours, %s: %zu floor pixels; torus %zu pixels, %zu differ from "
        "forward's\n",
        name.c_str(), floor_pixels, torus_pixels, torus_far);
    EXPECT_GT(floor_pixels, 1000u);
    if (name == "visibility") {
      EXPECT_GT(torus_pixels, 300u);
      EXPECT_LE(torus_far, torus_pixels / 100);
    }
  }
  ExpectOneDispatchShadesAsPerMaterial(cpu, Lit(true, true));
  // Lit, the torus's gradient and the floor's tint change what they colour.
  const Frame lit_plain = RenderOrDie(**plain, BackCamera(), Lit(true, true));
  const Frame lit_colored = RenderOrDie(**colored, BackCamera(), Lit(true, true));
  absl::StatusOr<double> psnr = Psnr(lit_plain.image, lit_colored.image);
  ASSERT_TRUE(psnr.ok()) << psnr.status();
  EXPECT_LT(*psnr, 25.0);
  ExpectNoValidationMessages(SharedRenderer());
}

// COLOR_0's alpha is cut out as the texture's is, in every pass that tests an alpha mask: the
// demo's perforated tube (an alpha-mask material) with every vertex's alpha 0 vanishes, its
// shadow too, and leaves the picture of the scene without it, in the forward path (depth
// prepass, shadow maps, drawable ids), the visibility pipeline and vis_mlaa (the visibility
// pass, indexed or pulled as the device draws it).
TEST(VertexColorTest, ItsAlphaCutsOutMaskedSurfaces) {
  const CpuScene demo = BuildDemoScene();
  CpuScene cut = demo, without = demo;
  const auto tube = std::find_if(
      demo.drawables.begin(), demo.drawables.end(),
      [&](const Drawable& d) { return demo.meshes[d.mesh].name == "Perforated tube"; });
  ASSERT_NE(tube, demo.drawables.end());
  const size_t tube_index = size_t(tube - demo.drawables.begin());
  Primitive& p = cut.primitives[tube->primitive];
  ASSERT_EQ(cut.materials[p.material].alpha_mode, AlphaMode::kMask);
  p.vertex_colors = true;
  for (uint32_t v = p.first_vertex; v < p.first_vertex + p.vertex_count; ++v)
    cut.vertices[v].color = PackVertexColor(glm::vec4(1.0f, 1.0f, 1.0f, 0.0f));
  // The tube stays, drawn nowhere: far below the floor, out of every view and shadow.
  without.drawables[tube_index].world =
      glm::translate(glm::mat4(1.0f), glm::vec3(0.0f, -1000.0f, 0.0f)) * tube->world;
  without.drawables[tube_index].world_bounds =
      demo.primitives[tube->primitive].bounds.transformed(without.drawables[tube_index].world);
  absl::StatusOr<SceneHandle> cut_scene = SharedRenderer().LoadScene(cut);
  absl::StatusOr<SceneHandle> without_scene = SharedRenderer().LoadScene(without);
  absl::StatusOr<SceneHandle> demo_scene = SharedRenderer().LoadScene(demo);
  ASSERT_TRUE(cut_scene.ok()) << cut_scene.status();
  ASSERT_TRUE(without_scene.ok()) << without_scene.status();
  ASSERT_TRUE(demo_scene.ok()) << demo_scene.status();
  Camera c = BackCamera();
  c.target = glm::vec3(1.0f, 0.6f, -0.8f);  // the tube and its shadow in the middle
  for (const auto& [name, settings] : ShadingPaths(Lit(true, false))) {
    SCOPED_TRACE(name);
    FrameCapture capture;
    capture.want_ids = true;
    absl::StatusOr<Frame> a = SharedRenderer().Render(**cut_scene, c, settings, 0, &capture);
    ASSERT_TRUE(a.ok()) << a.status();
    const Frame b = RenderOrDie(**without_scene, c, settings);
    const Frame shown = RenderOrDie(**demo_scene, c, settings);
    EXPECT_EQ(std::count(capture.ids.begin(), capture.ids.end(), uint32_t(tube_index + 1)), 0);
    absl::StatusOr<double> same = Psnr(a->image, b.image);
    absl::StatusOr<double> differs = Psnr(shown.image, b.image);
    ASSERT_TRUE(same.ok() && differs.ok());
    std::printf("vertex alpha 0, %s: %.2f dB against the scene without the tube; with it %.2f\n",
                name.c_str(), *same, *differs);
    EXPECT_GE(*same, 60.0);
    EXPECT_LT(*differs, 35.0);  // the tube and its shadow are in view
  }
  ExpectNoValidationMessages(SharedRenderer());
}

// A texture of one colour (4x4 RGBA8), as a CpuScene texture.
int32_t AddFlatTexture(CpuScene& cpu, std::array<uint8_t, 4> rgba, bool srgb) {
  auto image = std::make_shared<Image>();
  image->name = "flat";
  image->width = image->height = 4;
  for (int i = 0; i < 16; ++i) image->rgba8.insert(image->rgba8.end(), rgba.begin(), rgba.end());
  cpu.textures.push_back(Texture{.image = std::move(image), .srgb = srgb});
  return int32_t(cpu.textures.size() - 1);
}

// KHR_materials_ior and KHR_materials_specular (Material::ior, specular_factor,
// specular_color_factor and their textures) in the forward pass, the visibility pipeline's
// shading and vis_mlaa's, with shadows, SSAO, IBL and 64 local lights. The demo's red plastic is
// made black, so that what it shows is its specular reflection alone: the dielectric's Fresnel
// term f0 (1 - w) + f90 w with f0 = min(F0(ior) x colour, 1) x specular and f90 = specular
// (the extension's dielectric_f0 and dielectric_f90) times light that does not depend on them.
// So in every path, pixel by pixel (interior pixels, whose 3x3 neighbourhood shows one
// drawable):
//  - specular 0 leaves the plastic black, and the gold sphere (a metal) as it was;
//  - specular 0.5, as a factor or as a texture's alpha, halves the reflection;
//  - ior 1.7889 (F0 0.08) reflects as specularColorFactor 2 at ior 1.5, and more than the default;
//  - a specular colour texture's sRGB texels multiply the F0 channel by channel, as the factor
//    of their linear values does.
TEST(SpecularTest, ScalesTheDielectricsReflection) {
  const CpuScene demo = BuildDemoScene();
  int plastic = -1, gold = -1;
  for (size_t m = 0; m < demo.materials.size(); ++m) {
    if (demo.materials[m].name == "Red plastic") plastic = int(m);
    if (demo.materials[m].name == "Polished gold") gold = int(m);
  }
  ASSERT_GE(plastic, 0);
  ASSERT_GE(gold, 0);
  ASSERT_EQ(demo.materials[gold].metallic_factor, 1.0f);
  auto variant = [&](auto change) {
    CpuScene cpu = demo;
    cpu.materials[plastic].base_color_factor = glm::vec4(0.0f, 0.0f, 0.0f, 1.0f);
    change(cpu, cpu.materials[plastic]);
    return cpu;
  };
  // sRGB 188 in linear light.
  const float srgb_188 = std::pow((188.0f / 255.0f + 0.055f) / 1.055f, 2.4f);
  struct Case {
    std::string name;
    CpuScene cpu;
  };
  std::vector<Case> variants;
  variants.push_back({"default", variant([](CpuScene&, Material&) {})});
  variants.push_back({"specular 0", variant([&](CpuScene& cpu, Material& m) {
                        m.specular_factor = 0.0f;
                        cpu.materials[gold].specular_factor = 0.0f;
                      })});
  variants.push_back(
      {"specular 0.5", variant([](CpuScene&, Material& m) { m.specular_factor = 0.5f; })});
  variants.push_back({"specular texture 128", variant([](CpuScene& cpu, Material& m) {
                        m.specular.texture = AddFlatTexture(cpu, {255, 255, 255, 128}, false);
                      })});
  variants.push_back({"ior 1.7889", variant([](CpuScene&, Material& m) {
                        m.ior = (1.0f + std::sqrt(0.08f)) / (1.0f - std::sqrt(0.08f));
                      })});
  variants.push_back({"colour 2", variant([](CpuScene&, Material& m) {
                        m.specular_color_factor = glm::vec3(2.0f);
                      })});
  variants.push_back({"colour texture", variant([](CpuScene& cpu, Material& m) {
                        m.specular_color_factor = glm::vec3(2.0f);
                        m.specular_color.texture = AddFlatTexture(cpu, {255, 188, 0, 255}, true);
                      })});
  variants.push_back({"colour factor", variant([&](CpuScene&, Material& m) {
                        m.specular_color_factor = glm::vec3(2.0f, 2.0f * srgb_188, 0.0f);
                      })});
  variants.push_back({"ior 0", variant([](CpuScene&, Material& m) { m.ior = 0.0f; })});
  variants.push_back({"colour 50", variant([](CpuScene&, Material& m) {
                        m.specular_color_factor = glm::vec3(50.0f);
                      })});
  const glm::vec4 grey(0.8f, 0.8f, 0.8f, 1.0f);
  variants.push_back({"grey, colour (2, 1, 1)", variant([&](CpuScene&, Material& m) {
                        m.base_color_factor = grey;
                        m.specular_color_factor = glm::vec3(2.0f, 1.0f, 1.0f);
                      })});
  variants.push_back({"grey, colour 2", variant([&](CpuScene&, Material& m) {
                        m.base_color_factor = grey;
                        m.specular_color_factor = glm::vec3(2.0f);
                      })});
  std::vector<SceneHandle> scenes;
  for (const Case& c : variants) {
    absl::StatusOr<SceneHandle> scene = SharedRenderer().LoadScene(c.cpu);
    ASSERT_TRUE(scene.ok()) << c.name << ": " << scene.status();
    scenes.push_back(std::move(*scene));
  }
  enum {
    kDefault,
    kZero,
    kHalf,
    kHalfTexture,
    kIor,
    kColour2,
    kColourTexture,
    kColourFactor,
    kIor0,
    kColour50,
    kGreyRedSpecular,
    kGreySpecular
  };

  Settings every = Lit(true, true);
  every.ibl = true;
  every.synthetic_lights = 64;
  for (const auto& [name, settings] : ShadingPaths(every)) {
    SCOPED_TRACE(name);
    std::vector<FrameCapture> captures(variants.size());
    for (size_t v = 0; v < variants.size(); ++v) {
      captures[v].want_ids = true;
      absl::StatusOr<Frame> f =
          SharedRenderer().Render(*scenes[v], BackCamera(), settings, 0, &captures[v]);
      ASSERT_TRUE(f.ok()) << variants[v].name << ": " << f.status();
      ASSERT_EQ(captures[v].hdr.size(), size_t(kWidth) * kHeight * 4);
    }
    // Where every capture shows `m` inside one drawable.
    auto interior = [&](uint32_t x, uint32_t y, int m) {
      for (const FrameCapture& c : captures)
        if (InteriorMaterial(variants[0].cpu, c, x, y) != m) return false;
      return true;
    };
    // got == k x want + add, to the HDR target's half-float rounding.
    auto expect_scaled = [&](size_t got, size_t want, glm::vec3 k, uint32_t x, uint32_t y,
                             glm::vec3 add = glm::vec3(0.0f)) {
      const glm::vec3 a = HdrAt(captures[got], x, y), b = k * HdrAt(captures[want], x, y) + add;
      const glm::vec3 tolerance = 2e-3f * (glm::abs(b) + glm::abs(add)) + 1e-4f;
      const bool ok = glm::all(glm::lessThanEqual(glm::abs(a - b), tolerance));
      EXPECT_TRUE(ok) << variants[got].name << " at " << x << "," << y << ": " << a.r << " " << a.g
                      << " " << a.b << ", want " << b.r << " " << b.g << " " << b.b;
      return ok;
    };
    size_t plastic_pixels = 0, gold_pixels = 0, failures = 0;
    double reflected = 0.0, reflected_ior = 0.0;
    for (uint32_t y = 1; y + 1 < kHeight && failures < 5; ++y) {
      for (uint32_t x = 1; x + 1 < kWidth && failures < 5; ++x) {
        if (interior(x, y, gold)) {
          ++gold_pixels;
          failures += !expect_scaled(kZero, kDefault, glm::vec3(1.0f), x, y);
        }
        if (!interior(x, y, plastic)) continue;
        ++plastic_pixels;
        const float half_texel = 128.0f / 255.0f;
        failures += !expect_scaled(kZero, kDefault, glm::vec3(0.0f), x, y);
        failures += !expect_scaled(kHalf, kDefault, glm::vec3(0.5f), x, y);
        failures += !expect_scaled(kHalfTexture, kDefault, glm::vec3(half_texel), x, y);
        failures += !expect_scaled(kIor, kColour2, glm::vec3(1.0f), x, y);
        failures += !expect_scaled(kColourTexture, kColourFactor, glm::vec3(1.0f), x, y);
        failures += !expect_scaled(kIor0, kColour50, glm::vec3(1.0f), x, y);
        // A grey plastic with a red-tinted specular: its diffuse light is what the F0 of 0.08
        // leaves (the largest channel), as with a grey specular of 0.08; green and blue reflect
        // F0 0.04 as the black plastic's default does.
        const glm::vec3 s1 = HdrAt(captures[kDefault], x, y), s2 = HdrAt(captures[kColour2], x, y);
        failures += !expect_scaled(kGreyRedSpecular, kGreySpecular, glm::vec3(1.0f), x, y,
                                   glm::vec3(0.0f, s1.g - s2.g, s1.b - s2.b));
        reflected += glm::dot(HdrAt(captures[kDefault], x, y), glm::vec3(1.0f));
        reflected_ior += glm::dot(HdrAt(captures[kIor], x, y), glm::vec3(1.0f));
      }
    }
    std::printf(
        "specular, %s: %zu plastic pixels (reflection %.4f; at ior 1.7889 %.4f), %zu gold\n",
        name.c_str(), plastic_pixels, reflected / std::max<size_t>(plastic_pixels, 1),
        reflected_ior / std::max<size_t>(plastic_pixels, 1), gold_pixels);
    EXPECT_GT(plastic_pixels, 200u);  // lavapipe: 562 (vis_mlaa: 246)
    EXPECT_GT(gold_pixels, 200u);     // 837 (435)
    // The black plastic reflects (the comparisons above are not of zeros), and a higher IOR
    // reflects more: F0 0.08 against 0.04.
    EXPECT_GT(reflected, 0.01 * double(plastic_pixels));
    EXPECT_GT(reflected_ior, 1.2 * reflected);
  }
  // Shaded in one dispatch, the specular textures as per material.
  for (size_t v : {size_t(kHalfTexture), size_t(kColourTexture)}) {
    SCOPED_TRACE(variants[v].name);
    ExpectOneDispatchShadesAsPerMaterial(variants[v].cpu, every);
  }
  ExpectNoValidationMessages(SharedRenderer());
}

}  // namespace
}  // namespace tessera
