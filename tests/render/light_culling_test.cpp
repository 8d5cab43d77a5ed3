// Forward+ light culling against its CPU reference (renderer/light_culling.h) and against the
// ground truth: every light that reaches a pixel must be in that pixel's tile list. Also the
// shading from the lists against the brute-force image, overflow handling, and determinism.
#include "renderer/light_culling.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <map>
#include <set>

#include "renderer/camera.h"
#include "renderer/image_io.h"
#include "renderer/renderer.h"
#include "renderer/scene/demo_scene.h"
#include "shared_renderer.h"

namespace tessera {
namespace {

const SceneHandle& DemoScene() { return SharedDemoScene(); }

Camera DemoCamera() { return FromSceneCamera(DemoScene()->info().cameras[0]); }

Settings LightSettings(uint32_t w, uint32_t h, uint32_t lights) {
  Settings s;
  s.width = w;
  s.height = h;
  s.synthetic_lights = lights;
  s.light_seed = 7;
  return s;
}

// --- pure CPU parts ----------------------------------------------------------------------

TEST(SyntheticLights, DeterministicInsideBoundsAndStableUnderCount) {
  Aabb box;
  box.extend(glm::vec3(-3.0f, 0.0f, -2.0f));
  box.extend(glm::vec3(5.0f, 4.0f, 6.0f));
  const std::vector<Light> a = MakeSyntheticLights(box, {100, 3});
  const std::vector<Light> b = MakeSyntheticLights(box, {100, 3});
  const std::vector<Light> more = MakeSyntheticLights(box, {300, 3});
  const std::vector<Light> other = MakeSyntheticLights(box, {100, 4});
  ASSERT_EQ(a.size(), 100u);
  int differ = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].position, b[i].position);
    EXPECT_EQ(a[i].position, more[i].position) << "light " << i << " changed with the count";
    EXPECT_EQ(a[i].range, more[i].range);
    differ += a[i].position != other[i].position;
    EXPECT_TRUE(glm::all(glm::greaterThanEqual(a[i].position, box.min)));
    EXPECT_TRUE(glm::all(glm::lessThanEqual(a[i].position, box.max)));
    EXPECT_GT(a[i].range, 0.0f);
    EXPECT_GT(a[i].intensity, 0.0f);
    EXPECT_EQ(a[i].type, LightType::kPoint);
  }
  EXPECT_GT(differ, 95) << "another seed must give other lights";
}

TEST(SyntheticLights, RadiusRangeAndAnimation) {
  Aabb box;
  box.extend(glm::vec3(0.0f));
  box.extend(glm::vec3(10.0f));
  for (const Light& l : MakeSyntheticLights(box, {500, 1, 0.25f, 0.5f})) {
    EXPECT_GE(l.range, 0.25f);
    EXPECT_LE(l.range, 0.5f);
  }
  SyntheticLightParams p{50, 2};
  p.animated = true;
  p.time = 1.0f;
  const std::vector<Light> t1 = MakeSyntheticLights(box, p), t1b = MakeSyntheticLights(box, p);
  p.time = 2.0f;
  const std::vector<Light> t2 = MakeSyntheticLights(box, p);
  p.animated = false;
  const std::vector<Light> still = MakeSyntheticLights(box, p);
  for (size_t i = 0; i < t1.size(); ++i) {
    EXPECT_EQ(t1[i].position, t1b[i].position) << "deterministic for a time";
    EXPECT_NE(t1[i].position, t2[i].position) << "moves with time";
    // On a circle of half its range around the still position.
    EXPECT_NEAR(glm::length(t1[i].position - still[i].position), 0.5f * still[i].range, 1e-4f);
  }
}

TEST(TileStats, AverageMedianP95MaxAndOverflows) {
  std::vector<uint32_t> counts;
  for (uint32_t i = 0; i < 100; ++i) counts.push_back(i);
  counts[99] = gpu::kMaxLightsPerTile | gpu::kTileOverflowBit;
  const TileStats s = ComputeTileStats(counts);
  EXPECT_EQ(s.max, gpu::kMaxLightsPerTile);
  EXPECT_EQ(s.overflows, 1u);
  EXPECT_EQ(s.p50, 49u);
  EXPECT_EQ(s.p95, 94u);
  EXPECT_NEAR(s.average, (99.0 * 98.0 / 2.0 + gpu::kMaxLightsPerTile) / 100.0, 1e-9);
}

// A light just inside a tile's corner must survive, one just outside must not: the frustum is
// the tile's (all four corners), not the wedge three corners would make.
TEST(TileFrustum, CornersAreTheTilesOwn) {
  const TileGrid grid{64, 64, 16};
  Camera cam;
  cam.eye = glm::vec3(0.0f);
  cam.target = glm::vec3(0.0f, 0.0f, -1.0f);
  const glm::mat4 view = ViewMatrix(cam), proj = ProjectionMatrix(cam, 1.0f);
  // Flat wall at view depth 10 everywhere.
  std::vector<float> depth(64 * 64, proj[3][2] / 10.0f - proj[2][2]);
  // The ray through the pixel corner (32, 32), shared by four tiles.
  const glm::vec3 corner_ray(0.0f / proj[0][0], 0.0f / proj[1][1], -1.0f);
  auto lists_for = [&](glm::vec3 p, float r) {
    Light l;
    l.position = glm::vec3(glm::inverse(view) * glm::vec4(p, 1.0f));
    l.range = r;
    std::vector<gpu::GpuLightBounds> b = {BoundLight(l, view, proj, cam.znear, grid)};
    TileLightLists t = CullLightsReference(b, depth, proj, grid);
    std::set<uint32_t> tiles;
    for (uint32_t i = 0; i < grid.tiles(); ++i)
      if (t.counts[i] > 0) tiles.insert(i);
    return tiles;
  };
  // A small light on the corner ray at the wall touches exactly the four tiles around it.
  EXPECT_EQ(lists_for(corner_ray * 10.0f, 0.05f), (std::set<uint32_t>{5, 6, 9, 10}));
  // With the tile rectangle opened to the whole grid, only the planes can reject: a sphere right
  // of the vertical corner plane (0.6 > r = 0.5 from it) and straddling the horizontal one
  // belongs to tiles 6 and 10 and no other.
  {
    Light l;
    l.position = glm::vec3(glm::inverse(view) *
                           glm::vec4(corner_ray * 10.0f + glm::vec3(0.6f, -0.3f, 0.0f), 1.0f));
    l.range = 0.5f;
    gpu::GpuLightBounds b = BoundLight(l, view, proj, cam.znear, grid);
    b.tiles = glm::ivec4(0, 0, 3, 3);
    const TileLightLists t = CullLightsReference({b}, depth, proj, grid);
    std::set<uint32_t> tiles;
    for (uint32_t i = 0; i < grid.tiles(); ++i)
      if (t.counts[i] > 0) tiles.insert(i);
    EXPECT_EQ(tiles, (std::set<uint32_t>{6, 10}));
  }
  // Far in front of the wall (depth 2) the light misses the wall's depth range entirely.
  EXPECT_TRUE(lists_for(corner_ray * 2.0f, 0.5f).empty());
}

// A tile whose pixels are half at depth 5 and half at depth 50: a light floating at depth 25
// passes the depth bounds but not the 2.5D mask; a light at depth 50 passes both.
TEST(TileMask, RejectsLightsInTheDepthGap) {
  const TileGrid grid{16, 16, 16};
  Camera cam;
  cam.eye = glm::vec3(0.0f);
  cam.target = glm::vec3(0.0f, 0.0f, -1.0f);
  const glm::mat4 view = ViewMatrix(cam), proj = ProjectionMatrix(cam, 1.0f);
  std::vector<float> depth(16 * 16);
  for (uint32_t y = 0; y < 16; ++y)
    for (uint32_t x = 0; x < 16; ++x)
      depth[y * 16 + x] = proj[3][2] / (x < 8 ? 5.0f : 50.0f) - proj[2][2];
  auto culled = [&](float z) {
    Light l;
    l.position = glm::vec3(0.0f, 0.0f, -z);  // view == world here
    l.range = 1.0f;
    const TileLightLists t =
        CullLightsReference({BoundLight(l, view, proj, cam.znear, grid)}, depth, proj, grid);
    return t.counts[0] == 0;
  };
  EXPECT_TRUE(culled(25.0f));
  EXPECT_FALSE(culled(50.0f));
  EXPECT_FALSE(culled(5.0f));
}

// --- the GPU pass ------------------------------------------------------------------------

struct Case {
  uint32_t lights;
  uint32_t tile_size;
  LightBinning binning = LightBinning::kCpu;
};

class CullingTest : public ::testing::TestWithParam<Case> {};

// Every light that reaches a pixel (within range, and inside the cone for spots) is in the
// pixel's tile list; the GPU lists equal the CPU reference up to lights within 1e-3 of a test
// boundary; lists are sorted.
TEST_P(CullingTest, NoFalseNegativesAndMatchesTheCpuReference) {
  const Case c = GetParam();
  // 384x216: tiles small enough in the world that 4096 lights stay under 256 per tile.
  const Settings s = LightSettings(384, 216, c.lights);
  Settings st = s;
  st.tile_size = c.tile_size;
  st.light_binning = c.binning;
  FrameCapture cap;
  absl::StatusOr<Frame> f = SharedRenderer().Render(*DemoScene(), DemoCamera(), st, &cap);
  ASSERT_TRUE(f.ok()) << f.status();
  EXPECT_EQ(f->settings.effective.light_binning, c.binning);
  const TileGrid grid{st.width, st.height, st.tile_size};
  ASSERT_EQ(cap.tile_counts.size(), grid.tiles());
  ASSERT_GE(cap.local_lights.size(), c.lights);
  EXPECT_EQ(f->stats.local_lights, cap.local_lights.size());
  EXPECT_EQ(f->stats.tile_overflows, 0u);

  TileLightLists gpu;
  gpu.grid = grid;
  gpu.counts = cap.tile_counts;
  gpu.lights = cap.tile_lights;

  // Ground truth, pixel by pixel.
  const glm::mat4& proj = cap.proj;
  std::vector<glm::vec3> pos(cap.local_lights.size()), dir(cap.local_lights.size());
  for (size_t i = 0; i < cap.local_lights.size(); ++i) {
    pos[i] = glm::vec3(cap.view * glm::vec4(cap.local_lights[i].position, 1.0f));
    dir[i] = glm::normalize(glm::mat3(cap.view) * cap.local_lights[i].direction);
  }
  uint64_t checked = 0;
  for (uint32_t y = 0; y < st.height; y += 2) {  // every other pixel: still every tile
    for (uint32_t x = (y / 2) % 2; x < st.width; x += 2) {
      const float d = cap.depth[size_t(y) * st.width + x];
      if (d <= 0.0f) continue;
      const float z = ViewDepth(d, proj[2][2], proj[3][2]);
      const glm::vec2 ndc(2.0f * (float(x) + 0.5f) / float(st.width) - 1.0f,
                          2.0f * (float(y) + 0.5f) / float(st.height) - 1.0f);
      const glm::vec3 p = glm::vec3(ndc.x / proj[0][0], ndc.y / proj[1][1], -1.0f) * z;
      const uint32_t tile = (y / st.tile_size) * grid.tiles_x() + x / st.tile_size;
      const std::vector<uint32_t> list = gpu.List(tile);
      for (size_t i = 0; i < pos.size(); ++i) {
        const Light& l = cap.local_lights[i];
        const glm::vec3 to_p = p - pos[i];
        const float dist = glm::length(to_p);
        if (dist >= l.range * 0.999f) continue;
        if (l.type == LightType::kSpot &&
            glm::dot(to_p / dist, dir[i]) <= std::cos(l.outer_cone_angle) + 1e-3f)
          continue;
        ++checked;
        ASSERT_TRUE(std::binary_search(list.begin(), list.end(), uint32_t(i)))
            << "light " << i << " reaches pixel (" << x << ", " << y << ") but is not in tile "
            << tile;
      }
    }
  }
  EXPECT_GT(checked, 0u) << "no light reached any pixel: the test proves nothing";

  // The CPU reference, bracketed against float differences at the edges.
  std::vector<gpu::GpuLightBounds> bounds;
  for (const Light& l : cap.local_lights)
    bounds.push_back(BoundLight(l, cap.view, proj, DemoCamera().znear, grid));
  const float eps = 1e-3f;
  const TileLightLists tight = CullLightsReference(bounds, cap.depth, proj, grid, -eps);
  const TileLightLists loose = CullLightsReference(bounds, cap.depth, proj, grid, +eps);
  const TileLightLists exact = CullLightsReference(bounds, cap.depth, proj, grid);
  size_t equal_tiles = 0;
  for (uint32_t t = 0; t < grid.tiles(); ++t) {
    const std::vector<uint32_t> g = gpu.List(t), lo = tight.List(t), hi = loose.List(t);
    ASSERT_TRUE(std::is_sorted(g.begin(), g.end())) << "tile " << t;
    EXPECT_TRUE(std::includes(g.begin(), g.end(), lo.begin(), lo.end())) << "tile " << t;
    EXPECT_TRUE(std::includes(hi.begin(), hi.end(), g.begin(), g.end())) << "tile " << t;
    equal_tiles += g == exact.List(t);
  }
  EXPECT_GE(equal_tiles, grid.tiles() * 99 / 100) << "GPU and CPU lists mostly identical";

  // Culling does something: far fewer lights per tile than lights.
  if (c.lights >= 100) EXPECT_LT(f->stats.tile_lights_avg, 0.25 * double(cap.local_lights.size()));
}

INSTANTIATE_TEST_SUITE_P(
    Lights, CullingTest,
    ::testing::Values(Case{1, 16}, Case{100, 16}, Case{4096, 16}, Case{4096, 8}, Case{100, 32},
                      Case{1, 16, LightBinning::kGpu}, Case{100, 16, LightBinning::kGpu},
                      Case{4096, 16, LightBinning::kGpu},
                      Case{4096, 8, LightBinning::kGpu}, Case{100, 32, LightBinning::kGpu}),
    [](const auto& info) {
      return "lights" + std::to_string(info.param.lights) + "_tile" +
             std::to_string(info.param.tile_size) + "_" +
             std::string(ToString(info.param.binning));
    });

// The rows a light's tile rectangle covers (none when it is off screen), as both binnings see it.
bool CoversRow(const gpu::GpuLightBounds& b, uint32_t row) {
  return b.tiles.x <= b.tiles.z && b.tiles.y <= int(row) && int(row) <= b.tiles.w;
}

// Row r's list from a captured row_lights array.
std::vector<uint32_t> RowList(const std::vector<uint32_t>& rows, uint32_t r) {
  return std::vector<uint32_t>(rows.begin() + rows[2 * r], rows.begin() + rows[2 * r + 1]);
}

// light_binning gpu: light_bounds.comp projects each light as BoundLight does (to float
// precision; a tile rectangle may differ by one tile where a projected edge falls on a tile
// border), light_bins.comp lists exactly the lights whose rectangle covers each row, in index
// order, and the frame shades the same picture as with the CPU's bins. Spots of narrow, 45
// degree (glTF's default) and wide cones are among the local lights, and some synthetic lights
// cross the near plane.
// The demo scene with spots of narrow, default (45 degrees) and wide outer cones.
const SceneHandle& SpotScene() {
  static const SceneHandle scene = [] {
    CpuScene cpu = BuildDemoScene();
    for (float angle : {0.3f, 0.7853982f, 1.2f}) {
      Light spot;
      spot.type = LightType::kSpot;
      spot.range = 4.0f;
      spot.intensity = 20.0f;
      spot.position = glm::vec3(-2.0f + 2.0f * angle, 2.5f, 0.5f);
      spot.direction = glm::normalize(glm::vec3(0.1f, -1.0f, -0.2f));
      spot.inner_cone_angle = 0.5f * angle;
      spot.outer_cone_angle = angle;
      cpu.lights.push_back(spot);
    }
    absl::StatusOr<SceneHandle> s = SharedRenderer().LoadScene(std::move(cpu));
    EXPECT_TRUE(s.ok()) << s.status();
    return s.ok() ? *s : SceneHandle{};
  }();
  return scene;
}

TEST(GpuLightBinning, BoundsAndBinsMatchTheCpu) {
  ASSERT_TRUE(SpotScene());
  Settings s = LightSettings(384, 216, 4096);
  s.tile_size = 8;
  s.light_binning = LightBinning::kGpu;
  FrameCapture gpu_cap, cpu_cap;
  absl::StatusOr<Frame> g = SharedRenderer().Render(*SpotScene(), DemoCamera(), s, &gpu_cap);
  ASSERT_TRUE(g.ok()) << g.status();
  s.light_binning = LightBinning::kCpu;
  absl::StatusOr<Frame> c = SharedRenderer().Render(*SpotScene(), DemoCamera(), s, &cpu_cap);
  ASSERT_TRUE(c.ok()) << c.status();
  EXPECT_EQ(g->settings.effective.light_binning, LightBinning::kGpu);
  EXPECT_EQ(c->settings.effective.light_binning, LightBinning::kCpu);
  const TileGrid grid{s.width, s.height, s.tile_size};
  const size_t n = gpu_cap.local_lights.size();
  ASSERT_EQ(gpu_cap.light_bounds.size(), n);
  ASSERT_EQ(cpu_cap.light_bounds.size(), n);

  size_t spots = 0, near_crossing = 0, off_screen = 0, rect_differs = 0;
  for (size_t i = 0; i < n; ++i) {
    const gpu::GpuLightBounds& a = gpu_cap.light_bounds[i];
    const gpu::GpuLightBounds b =
        BoundLight(gpu_cap.local_lights[i], gpu_cap.view, gpu_cap.proj, DemoCamera().znear, grid);
    const float scale = std::max(1.0f, glm::length(glm::vec3(b.sphere)) + b.sphere.w);
    ASSERT_LE(glm::length(a.sphere - b.sphere), 1e-5f * scale) << "light " << i;
    ASSERT_LE(glm::length(a.cone - b.cone), 1e-5f * scale) << "light " << i;
    if (b.cone.w > -1.5f) {
      ++spots;
      ASSERT_LE(glm::length(a.cone2 - b.cone2), 1e-5f * scale) << "light " << i;
    }
    const bool a_off = a.tiles.x > a.tiles.z, b_off = b.tiles.x > b.tiles.z;
    off_screen += b_off;
    near_crossing += b.tiles == glm::ivec4(0, 0, grid.tiles_x() - 1, grid.tiles_y() - 1);
    if (a.tiles != b.tiles) {
      ++rect_differs;
      ASSERT_EQ(a_off, b_off) << "light " << i;
      const glm::ivec4 d = glm::abs(a.tiles - b.tiles);
      ASSERT_LE(std::max(std::max(d.x, d.y), std::max(d.z, d.w)), 1) << "light " << i;
    }
    // What the CPU-binned frame read is BoundLight's.
    ASSERT_EQ(cpu_cap.light_bounds[i].tiles, b.tiles) << "light " << i;
  }
  EXPECT_EQ(spots, 4u) << "the demo scene's spot light and the three added";
  EXPECT_GE(near_crossing, 1u);
  EXPECT_GE(off_screen, 1u);
  EXPECT_LE(rect_differs, n / 100) << "rectangles differ only at tile borders";
  std::printf("gpu bounds: %zu lights (%zu spots, %zu crossing the near plane, %zu off screen), "
              "%zu rectangles differ from BoundLight's by one tile\n",
              n, spots, near_crossing, off_screen, rect_differs);

  // The row lists: exactly the lights covering each row, sorted; rows of the GPU layout.
  const uint32_t rows = grid.tiles_y();
  ASSERT_EQ(gpu_cap.row_lights.size(), (2 + n) * rows);
  for (uint32_t r = 0; r < rows; ++r) {
    std::vector<uint32_t> want;
    for (uint32_t i = 0; i < n; ++i)
      if (CoversRow(gpu_cap.light_bounds[i], r)) want.push_back(i);
    ASSERT_EQ(gpu_cap.row_lights[2 * r], 2 * rows + r * n) << "row " << r;
    ASSERT_EQ(RowList(gpu_cap.row_lights, r), want) << "row " << r;
    std::vector<uint32_t> cpu_want;
    for (uint32_t i = 0; i < n; ++i)
      if (CoversRow(cpu_cap.light_bounds[i], r)) cpu_want.push_back(i);
    ASSERT_EQ(RowList(cpu_cap.row_lights, r), cpu_want) << "row " << r << " (CPU bins)";
  }

  // The tile lists and the picture: the same but for lights at tile borders.
  size_t same_tiles = 0;
  for (uint32_t t = 0; t < grid.tiles(); ++t) {
    same_tiles += gpu_cap.tile_counts[t] == cpu_cap.tile_counts[t] &&
                  std::equal(gpu_cap.tile_lights.begin() + t * gpu::kMaxLightsPerTile,
                             gpu_cap.tile_lights.begin() + t * gpu::kMaxLightsPerTile +
                                 (cpu_cap.tile_counts[t] & ~gpu::kTileOverflowBit),
                             cpu_cap.tile_lights.begin() + t * gpu::kMaxLightsPerTile);
  }
  EXPECT_GE(same_tiles, grid.tiles() * 99 / 100);
  const double psnr = Psnr(g->image, c->image).value();
  std::printf("gpu vs cpu binning: %zu of %u tile lists equal, image %.1f dB\n", same_tiles,
              grid.tiles(), psnr);
  EXPECT_GE(psnr, 60.0);
  ExpectNoValidationMessages(SharedRenderer());
}

// Shading from the tile lists gives the brute-force image.
TEST(ForwardPlus, TiledImageEqualsBruteForce) {
  for (uint32_t lights : {1u, 100u, 4096u}) {
    SCOPED_TRACE(lights);
    Settings s = LightSettings(256, 144, lights);
    s.tile_size = 8;  // no tile overflows at 4096 lights in this small frame
    absl::StatusOr<Frame> tiled = SharedRenderer().Render(*DemoScene(), DemoCamera(), s);
    s.light_culling = false;
    absl::StatusOr<Frame> brute = SharedRenderer().Render(*DemoScene(), DemoCamera(), s);
    ASSERT_TRUE(tiled.ok() && brute.ok());
    EXPECT_EQ(tiled->stats.tile_overflows, 0u);
    // A culled light adds exactly zero (its range window is 0 there) and lists keep the index
    // order of the brute-force loop, so the sums are the same: the images must be identical.
    EXPECT_EQ(tiled->image.pixels, brute->image.pixels) << "tiled vs brute force";
    const bool has_cull = std::any_of(tiled->passes.begin(), tiled->passes.end(),
                                      [](const PassTiming& p) { return p.pass == "light_cull"; });
    const bool brute_cull = std::any_of(brute->passes.begin(), brute->passes.end(),
                                        [](const PassTiming& p) { return p.pass == "light_cull"; });
    EXPECT_TRUE(has_cull);
    EXPECT_FALSE(brute_cull);
  }
  // And the lights are visible at all: 100 lights change the picture.
  Settings none = LightSettings(128, 72, 0), some = LightSettings(128, 72, 100);
  absl::StatusOr<Frame> a = SharedRenderer().Render(*DemoScene(), DemoCamera(), none);
  absl::StatusOr<Frame> b = SharedRenderer().Render(*DemoScene(), DemoCamera(), some);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_LT(Psnr(a->image, b->image).value(), 45.0);
  ExpectNoValidationMessages(SharedRenderer());
}

// Without the 2.5D mask lists can only grow (the mask only rejects), and the image is the same.
TEST(ForwardPlus, DepthMaskOnlyRejects) {
  // Tiles on object edges hold a near surface and the floor far behind; lights floating in the
  // gap are what the mask rejects. (No tile overflows here, so both frames shade full lists.)
  Settings s = LightSettings(384, 216, 2000);
  s.tile_size = 16;
  FrameCapture with, without;
  absl::StatusOr<Frame> a = SharedRenderer().Render(*DemoScene(), DemoCamera(), s, &with);
  s.tile_depth_mask = false;
  absl::StatusOr<Frame> b = SharedRenderer().Render(*DemoScene(), DemoCamera(), s, &without);
  ASSERT_TRUE(a.ok() && b.ok());
  TileLightLists la, lb;
  la.counts = with.tile_counts;
  la.lights = with.tile_lights;
  lb.counts = without.tile_counts;
  lb.lights = without.tile_lights;
  uint64_t sum_a = 0, sum_b = 0;
  for (uint32_t t = 0; t < with.tile_counts.size(); ++t) {
    if ((with.tile_counts[t] | without.tile_counts[t]) & gpu::kTileOverflowBit) continue;
    const std::vector<uint32_t> x = la.List(t), y = lb.List(t);
    EXPECT_TRUE(std::includes(y.begin(), y.end(), x.begin(), x.end())) << "tile " << t;
    sum_a += x.size();
    sum_b += y.size();
  }
  EXPECT_LT(sum_a, sum_b) << "the mask rejects lights in depth gaps (object edges)";
  EXPECT_EQ(a->stats.tile_overflows, 0u);
  EXPECT_EQ(b->stats.tile_overflows, 0u);
  EXPECT_EQ(a->image.pixels, b->image.pixels);
}

TEST(ForwardPlus, FramesAreReproducibleBitForBit) {
  const Settings s = LightSettings(128, 72, 2000);
  absl::StatusOr<Frame> a = SharedRenderer().Render(*DemoScene(), DemoCamera(), s);
  absl::StatusOr<Frame> b = SharedRenderer().Render(*DemoScene(), DemoCamera(), s);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->image.pixels, b->image.pixels);
}

// More lights than a list holds: the tile keeps the 256 lowest indices, sorted, and the
// overflow is flagged and counted, not silently wrapped.
TEST(ForwardPlus, OverflowIsFlaggedAndCounted) {
  Settings s = LightSettings(64, 64, 65536);
  s.tile_size = 32;
  FrameCapture cap;
  Camera cam;
  cam.eye = glm::vec3(0.0f, 1.2f, 3.0f);
  cam.target = glm::vec3(0.0f, 0.3f, 0.0f);
  absl::StatusOr<Frame> f = SharedRenderer().Render(*DemoScene(), cam, s, &cap);
  ASSERT_TRUE(f.ok()) << f.status();
  EXPECT_GT(f->stats.tile_overflows, 0u);
  EXPECT_EQ(f->stats.tile_lights_max, gpu::kMaxLightsPerTile);
  const TileGrid grid{64, 64, 32};
  std::vector<gpu::GpuLightBounds> bounds;
  for (const Light& l : cap.local_lights)
    bounds.push_back(BoundLight(l, cap.view, cap.proj, cam.znear, grid));
  const TileLightLists ref = CullLightsReference(bounds, cap.depth, cap.proj, grid);
  uint32_t overflowed = 0;
  for (uint32_t t = 0; t < grid.tiles(); ++t) {
    if (!(cap.tile_counts[t] & gpu::kTileOverflowBit)) continue;
    ++overflowed;
    TileLightLists gpu;
    gpu.grid = grid;
    gpu.counts = cap.tile_counts;
    gpu.lights = cap.tile_lights;
    const std::vector<uint32_t> g = gpu.List(t);
    ASSERT_EQ(g.size(), gpu::kMaxLightsPerTile);
    EXPECT_TRUE(std::is_sorted(g.begin(), g.end()));
    EXPECT_TRUE(ref.counts[t] & gpu::kTileOverflowBit);
    // The 256 lowest indices, as the reference keeps them (a light on a test boundary may
    // differ, so allow a handful).
    const std::vector<uint32_t> r = ref.List(t);
    std::vector<uint32_t> common;
    std::set_intersection(g.begin(), g.end(), r.begin(), r.end(), std::back_inserter(common));
    EXPECT_GE(common.size(), gpu::kMaxLightsPerTile - 4) << "tile " << t;
  }
  for (uint32_t t = 0; t < grid.tiles(); ++t)
    if (ref.counts[t] & gpu::kTileOverflowBit)
      EXPECT_TRUE(cap.tile_counts[t] & gpu::kTileOverflowBit) << "tile " << t;
  EXPECT_EQ(overflowed, f->stats.tile_overflows);
}

// The heatmap's colour at a surface pixel is a function of its tile's count alone: pixels of
// tiles with equal counts have equal colours, and different counts give different colours.
TEST(ForwardPlus, HeatmapShowsTileCounts) {
  Settings s = LightSettings(128, 72, 1000);
  s.debug_view = DebugView::kLightHeatmap;
  s.tile_size = 8;
  FrameCapture cap;
  absl::StatusOr<Frame> f = SharedRenderer().Render(*DemoScene(), DemoCamera(), s, &cap);
  ASSERT_TRUE(f.ok());
  EXPECT_TRUE(f->settings.notes.empty()) << f->settings.notes[0].message;
  const TileGrid grid{128, 72, 8};
  std::map<uint32_t, uint32_t> colour_of_count;
  std::set<uint32_t> counts_seen;
  for (uint32_t y = 0; y < 72; ++y)
    for (uint32_t x = 0; x < 128; ++x) {
      if (cap.depth[y * 128 + x] <= 0.0f) continue;  // sky
      const uint32_t count = cap.tile_counts[(y / 8) * grid.tiles_x() + x / 8];
      const uint8_t* p = &f->image.pixels[(size_t(y) * 128 + x) * 4];
      const uint32_t colour = uint32_t(p[0]) << 16 | uint32_t(p[1]) << 8 | p[2];
      auto [it, inserted] = colour_of_count.emplace(count, colour);
      if (!inserted && it->second != colour) {
        // Blended surfaces (the glass sphere) draw over the heatmap; only opaque pixels count.
        continue;
      }
      counts_seen.insert(count);
    }
  EXPECT_GE(counts_seen.size(), 4u) << "the counts differ between tiles";
  std::set<uint32_t> colours;
  for (const auto& [count, colour] : colour_of_count) colours.insert(colour);
  EXPECT_GE(colours.size(), 4u) << "different counts show as different colours";
}

}  // namespace
}  // namespace tessera
