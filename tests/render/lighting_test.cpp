// Shadows and SSAO on the device (lavapipe in CI, validation on): goldens of each feature,
// physical checks that hold whatever the golden (a shadow only removes light, and darkens where
// the sun's ray from an occluder meets the floor), and the shadow cache's face counts.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "renderer/camera.h"
#include "renderer/renderer.h"
#include "renderer/scene/demo_scene.h"
#include "tests/render/golden.h"
#include "tests/render/shared_renderer.h"

namespace tessera {
namespace {

constexpr uint32_t kWidth = 320, kHeight = 180;

void ExpectNoValidationMessages(const Renderer& r) {
  EXPECT_EQ(r.validation_message_count(), 0u);
  for (const std::string& m : r.validation_messages()) ADD_FAILURE() << "validation: " << m;
}

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
  CompareWithGolden("shadows", RenderOrDie(*scene, BackCamera(), Lit(true, false)).image, 35.0);
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
  CompareWithGolden("shadows_local", on.image, 35.0);
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
  CompareWithGolden("ssao", on.image, 35.0);
  Settings debug = Lit(false, true);
  debug.debug_view = DebugView::kSsao;
  CompareWithGolden("ssao_debug", RenderOrDie(*scene, BackCamera(), debug).image, 30.0);
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

}  // namespace
}  // namespace tessera
