// The anti-aliasing edge scene: exact pixel coverage of polygons, the coverage image against
// the shapes, the half-plane and wire layout, and that the geometry projects back onto the
// pixel polygons through the camera the scene is made for.
#include "renderer/scene/edge_scene.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <glm/glm.hpp>
#include <vector>

namespace tessera {
namespace {

constexpr uint32_t kColumns = 13;
constexpr uint32_t kHalfPlanes = 91;
// The wires as edge_scene.cpp documents them: (width px, degrees), one per wire cell.
constexpr struct {
  double width;
  int degrees;
} kWires[] = {{0.25, 3},  {0.5, 20}, {1.0, 45}, {1.5, 70},
              {0.25, 45}, {0.5, 70}, {1.0, 3},  {1.5, 20}};
constexpr uint32_t kWireCount = sizeof(kWires) / sizeof(kWires[0]);
constexpr double kPi = 3.14159265358979323846;

double Area(const std::vector<PixelPoint>& poly) {
  double sum = 0.0;
  for (size_t i = 0; i < poly.size(); ++i) {
    const PixelPoint& p = poly[i];
    const PixelPoint& q = poly[(i + 1) % poly.size()];
    sum += p.x * q.y - q.x * p.y;
  }
  return 0.5 * sum;  // negative: counter-clockwise on screen (y down)
}

std::vector<PixelPoint> Reversed(std::vector<PixelPoint> p) {
  std::reverse(p.begin(), p.end());
  return p;
}

// World -> pixel through the camera of the scene, written out independently of the renderer:
// view = identity (eye at the origin looking down -Z, +Y up), a perspective projection with
// clip y flipped for Vulkan, then the viewport (NDC -1..1 -> 0..size, y down).
PixelPoint Project(const EdgeScene& e, const glm::vec3& world) {
  const double f = 1.0 / std::tan(0.5 * double(e.yfov));
  const double aspect = double(e.width) / double(e.height);
  const double w = -double(world.z);
  const double ndc_x = f / aspect * double(world.x) / w;
  const double ndc_y = -f * double(world.y) / w;
  return {(ndc_x + 1.0) * 0.5 * e.width, (ndc_y + 1.0) * 0.5 * e.height};
}

class EdgeSceneTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { edges_ = new EdgeScene(BuildEdgeScene()); }
  static void TearDownTestSuite() {
    delete edges_;
    edges_ = nullptr;
  }
  static const EdgeScene& edges() { return *edges_; }
  static float Coverage(int x, int y) {
    return edges_->coverage[size_t(y) * edges_->width + size_t(x)];
  }

 private:
  static EdgeScene* edges_;
};

EdgeScene* EdgeSceneTest::edges_ = nullptr;

TEST(PolygonPixelCoverage, KnownCases) {
  const std::vector<PixelPoint> big = {{-1, -1}, {-1, 3}, {3, 3}, {3, -1}};
  const std::vector<PixelPoint> exact = {{5, 7}, {5, 8}, {6, 8}, {6, 7}};
  // The lower-left half of pixel (2, 3): the diagonal cuts it in two.
  const std::vector<PixelPoint> half = {{2, 3}, {2, 4}, {3, 4}};
  const std::vector<PixelPoint> quarter = {{10.5, 0.5}, {10.5, 5}, {15, 5}, {15, 0.5}};
  const std::vector<PixelPoint> away = {{4, 4}, {4, 6}, {6, 6}};
  for (bool reverse : {false, true}) {
    auto p = [reverse](const std::vector<PixelPoint>& v) { return reverse ? Reversed(v) : v; };
    EXPECT_NEAR(PolygonPixelCoverage(p(big), 0, 0), 1.0, 1e-12);
    EXPECT_NEAR(PolygonPixelCoverage(p(big), 2, 2), 1.0, 1e-12);
    EXPECT_NEAR(PolygonPixelCoverage(p(big), -1, 1), 1.0, 1e-12);
    EXPECT_NEAR(PolygonPixelCoverage(p(exact), 5, 7), 1.0, 1e-12);
    EXPECT_EQ(PolygonPixelCoverage(p(exact), 4, 7), 0.0);  // shares an edge only
    EXPECT_EQ(PolygonPixelCoverage(p(exact), 6, 8), 0.0);  // shares a corner only
    EXPECT_NEAR(PolygonPixelCoverage(p(half), 2, 3), 0.5, 1e-12);
    EXPECT_NEAR(PolygonPixelCoverage(p(quarter), 10, 0), 0.25, 1e-12);
    EXPECT_NEAR(PolygonPixelCoverage(p(quarter), 11, 0), 0.5, 1e-12);
    EXPECT_NEAR(PolygonPixelCoverage(p(quarter), 11, 1), 1.0, 1e-12);
    EXPECT_EQ(PolygonPixelCoverage(p(away), 0, 0), 0.0);
    EXPECT_EQ(PolygonPixelCoverage(p(away), 5, 4), 0.0);  // beyond the hypotenuse
    EXPECT_NEAR(PolygonPixelCoverage(p(away), 4, 5), 1.0, 1e-12);
    EXPECT_NEAR(PolygonPixelCoverage(p(away), 4, 4), 0.5, 1e-12);
  }
  EXPECT_EQ(PolygonPixelCoverage({}, 0, 0), 0.0);
  EXPECT_EQ(PolygonPixelCoverage({{0, 0}, {1, 1}}, 0, 0), 0.0);
}

TEST(PolygonPixelCoverage, RotatedSquareMatchesAnalyticArea) {
  // A square of side 2 rotated 45 degrees, centred on pixel (0, 0)'s centre: the pixel lies
  // inside it (its corners are at distance 0.5 * sqrt(2) < sqrt(2) along the diagonals).
  const double r = std::sqrt(2.0);
  const std::vector<PixelPoint> diamond = {
      {0.5, 0.5 - r}, {0.5 - r, 0.5}, {0.5, 0.5 + r}, {0.5 + r, 0.5}};
  EXPECT_NEAR(PolygonPixelCoverage(diamond, 0, 0), 1.0, 1e-12);
  // The neighbour to the right: the part with x + |y - 0.5| <= 0.5 + r, x in [1, 2]; the area
  // of the pixel minus the two corner triangles cut off by the diamond's right edges.
  const double a = 0.5 + r - 1.0;  // how far the diamond reaches past x = 1 at y = 0.5
  // For x in [1, 1 + a], |y - 0.5| <= a - (x - 1), clipped to |y - 0.5| <= 0.5.
  double expected = 0.0;
  const int steps = 200000;
  for (int i = 0; i < steps; ++i) {
    const double x = 1.0 + (i + 0.5) / steps;
    expected += 2.0 * std::clamp(a - (x - 1.0), 0.0, 0.5) / steps;
  }
  EXPECT_NEAR(PolygonPixelCoverage(diamond, 1, 0), expected, 1e-6);
  EXPECT_NEAR(PolygonPixelCoverage(Reversed(diamond), 1, 0), expected, 1e-6);
}

TEST_F(EdgeSceneTest, Layout) {
  const EdgeScene& e = edges();
  EXPECT_EQ(e.width, 13u * (24u + 8u) + 8u);
  EXPECT_EQ(e.height, 8u * (24u + 8u) + 8u);
  EXPECT_EQ(e.coverage.size(), size_t{e.width} * e.height);
  ASSERT_EQ(e.shapes.size(), kHalfPlanes + kWireCount);
  EXPECT_EQ(e.eye, glm::vec3(0.0f));
  EXPECT_EQ(e.target, glm::vec3(0.0f, 0.0f, -1.0f));
  EXPECT_EQ(e.yfov, 0.5f);
  EXPECT_EQ(e.znear, 0.1f);
  // Every shape is a convex polygon counter-clockwise on screen, inside its cell with at least
  // the gap of background to every other shape.
  for (size_t i = 0; i < e.shapes.size(); ++i) {
    const auto& poly = e.shapes[i];
    ASSERT_GE(poly.size(), 3u) << i;
    EXPECT_LT(Area(poly), 0.0) << i;
    for (size_t j = 0; j < poly.size(); ++j) {
      const PixelPoint& a = poly[j];
      const PixelPoint& b = poly[(j + 1) % poly.size()];
      const PixelPoint& c = poly[(j + 2) % poly.size()];
      const double cross = (b.x - a.x) * (c.y - b.y) - (b.y - a.y) * (c.x - b.x);
      EXPECT_LE(cross, 1e-9) << "shape " << i << " is not convex at vertex " << j;
    }
    double x0, y0, w, h;
    if (i < kHalfPlanes) {
      x0 = 8 + 32.0 * (i % kColumns);
      y0 = 8 + 32.0 * (i / kColumns);
      w = h = 24;
    } else {
      x0 = 8 + 52.0 * (i - kHalfPlanes);  // wire cells: (424 - 9 * 8) / 8 = 44 px wide
      y0 = 8 + 32.0 * 7;
      w = 44;
      h = 24;
    }
    for (const PixelPoint& p : poly) {
      EXPECT_GE(p.x, x0 - 1e-9) << i;
      EXPECT_LE(p.x, x0 + w + 1e-9) << i;
      EXPECT_GE(p.y, y0 - 1e-9) << i;
      EXPECT_LE(p.y, y0 + h + 1e-9) << i;
    }
  }
  // The last wire cell ends inside the image with the gap to spare.
  EXPECT_LE(8 + 52.0 * (kWireCount - 1) + 44 + 8, double(e.width));
}

TEST_F(EdgeSceneTest, HalfPlanesFollowTheirAngle) {
  const EdgeScene& e = edges();
  for (uint32_t k = 0; k < kHalfPlanes; ++k) {
    const double x0 = 8 + 32.0 * (k % kColumns), y0 = 8 + 32.0 * (k / kColumns);
    const PixelPoint p = {x0 + 12.3, y0 + 12.3};
    const double s = std::sin(k * kPi / 180.0), c = std::cos(k * kPi / 180.0);
    int on_edge = 0;
    double cx = 0.0, cy = 0.0;
    for (const PixelPoint& v : e.shapes[k]) {
      const double d = s * (v.x - p.x) + c * (v.y - p.y);
      EXPECT_GE(d, -1e-9) << "cell " << k;
      if (std::abs(d) < 1e-9) ++on_edge;
      cx += v.x / e.shapes[k].size();
      cy += v.y / e.shapes[k].size();
    }
    EXPECT_EQ(on_edge, 2) << "cell " << k;
    EXPECT_GT(s * (cx - p.x) + c * (cy - p.y), 0.0) << "cell " << k;
  }
  // 0 degrees: filled below y = 12.3 in the cell; 90: right of x = 12.3. Both 24 x 11.7.
  EXPECT_NEAR(-Area(e.shapes[0]), 24 * 11.7, 1e-9);
  EXPECT_NEAR(-Area(e.shapes[90]), 24 * 11.7, 1e-9);
}

TEST_F(EdgeSceneTest, AxisAlignedEdgesCoverPartialRowAndColumn) {
  // Cell 0 at (8, 8): the edge at y = 8 + 12.3 leaves 0.7 of row 20 covered.
  for (int x = 8; x < 32; ++x) {
    for (int y = 8; y < 32; ++y) {
      const float want = y < 20 ? 0.0f : y == 20 ? 0.7f : 1.0f;
      EXPECT_NEAR(Coverage(x, y), want, 1e-6) << x << "," << y;
    }
  }
  // Cell 90 (column 12, row 6): the edge at x = x0 + 12.3 leaves 0.7 of that column.
  const int x0 = 8 + 32 * 12, y0 = 8 + 32 * 6;
  for (int x = x0; x < x0 + 24; ++x) {
    for (int y = y0; y < y0 + 24; ++y) {
      const float want = x < x0 + 12 ? 0.0f : x == x0 + 12 ? 0.7f : 1.0f;
      EXPECT_NEAR(Coverage(x, y), want, 1e-6) << x << "," << y;
    }
  }
}

TEST_F(EdgeSceneTest, FortyFiveDegreeCellIsSymmetric) {
  // Cell 45 (column 6, row 3): covered where x + y >= 24.6 in cell pixels, so the pattern is
  // symmetric about the cell's diagonal and depends on x + y only. Pixel (i, j) spans
  // x + y in [i + j, i + j + 2]: 0.08 covered when i + j = 23 (a corner triangle, legs 0.4),
  // 0.82 when i + j = 24 (all but a corner triangle of legs 0.6), 1 beyond, 0 before.
  const int x0 = 8 + 32 * 6, y0 = 8 + 32 * 3;
  for (int i = 0; i < 24; ++i) {
    for (int j = 0; j < 24; ++j) {
      EXPECT_NEAR(Coverage(x0 + i, y0 + j), Coverage(x0 + j, y0 + i), 1e-6) << i << "," << j;
      const float want = i + j < 23 ? 0.0f : i + j == 23 ? 0.08f : i + j == 24 ? 0.82f : 1.0f;
      EXPECT_NEAR(Coverage(x0 + i, y0 + j), want, 1e-6) << i << "," << j;
    }
  }
}

TEST_F(EdgeSceneTest, WiresHaveTheirWidthAndAngle) {
  const EdgeScene& e = edges();
  for (uint32_t i = 0; i < kWireCount; ++i) {
    const auto& poly = e.shapes[kHalfPlanes + i];
    const double a = kWires[i].degrees * kPi / 180.0;
    const double s = std::sin(a), c = std::cos(a), w = kWires[i].width;
    const PixelPoint centre = {8 + 52.0 * i + 22.3, 8 + 32.0 * 7 + 12.3};
    for (const PixelPoint& v : poly) {
      EXPECT_LE(std::abs(s * (v.x - centre.x) + c * (v.y - centre.y)), 0.5 * w + 1e-9) << i;
    }
    // At these angles every wire crosses its 44 x 24 cell from side to side or from top to
    // bottom without touching a corner: a parallelogram, width times the shorter crossing.
    EXPECT_NEAR(-Area(poly), w * std::min(44.0 / c, 24.0 / s), 1e-9) << i;
  }
}

TEST_F(EdgeSceneTest, CoverageMatchesShapes) {
  const EdgeScene& e = edges();
  double total = 0.0, areas = 0.0;
  size_t partial = 0;
  for (float v : e.coverage) {
    ASSERT_GE(v, 0.0f);
    ASSERT_LE(v, 1.0f);
    total += v;
    if (v > 0.0f && v < 1.0f) ++partial;
  }
  for (const auto& poly : e.shapes) areas += -Area(poly);
  EXPECT_NEAR(total, areas, 1e-6 * areas);
  // Every edge and wire leaves partly covered pixels; the gaps and cell interiors do not.
  EXPECT_GT(partial, 91u * 24u);
  // The border and the gaps are background.
  for (uint32_t x = 0; x < e.width; ++x) {
    for (uint32_t y = 0; y < 8; ++y) EXPECT_EQ(Coverage(x, y), 0.0f);
    for (uint32_t y = e.height - 8; y < e.height; ++y) EXPECT_EQ(Coverage(x, y), 0.0f);
  }
}

TEST_F(EdgeSceneTest, SceneStructure) {
  const EdgeScene& e = edges();
  const CpuScene& s = e.scene;
  EXPECT_EQ(s.name, "edges");
  ASSERT_EQ(s.drawables.size(), 1 + e.shapes.size());
  EXPECT_EQ(s.drawables.size(), 1u + 91u + kWireCount);
  EXPECT_TRUE(s.lights.empty());
  EXPECT_TRUE(s.textures.empty());
  EXPECT_TRUE(s.warnings.empty());
  ASSERT_EQ(s.materials.size(), 2u);
  ASSERT_EQ(s.cameras.size(), 1u);
  EXPECT_EQ(s.cameras[0].yfov, e.yfov);
  EXPECT_EQ(s.cameras[0].znear, e.znear);
  EXPECT_FLOAT_EQ(s.cameras[0].aspect, float(e.width) / float(e.height));
  EXPECT_EQ(s.cameras[0].world, glm::mat4(1.0f));

  EXPECT_EQ(s.counts.nodes, s.drawables.size());
  EXPECT_EQ(s.counts.meshes, s.meshes.size());
  EXPECT_EQ(s.counts.primitives, s.primitives.size());
  EXPECT_EQ(s.counts.materials, 2u);
  EXPECT_EQ(s.counts.cameras, 1u);
  uint64_t triangles = 0;
  for (const auto& poly : e.shapes) triangles += poly.size() - 2;
  EXPECT_EQ(s.counts.triangles, 2u + triangles);

  const Material& bg = s.materials[s.primitives[s.drawables[0].primitive].material];
  EXPECT_EQ(bg.base_color_factor, glm::vec4(0.0f, 0.0f, 0.0f, 1.0f));
  for (size_t i = 1; i < s.drawables.size(); ++i) {
    const Material& m = s.materials[s.primitives[s.drawables[i].primitive].material];
    EXPECT_EQ(m.base_color_factor, glm::vec4(1.0f));
    EXPECT_EQ(m.metallic_factor, 0.0f);
    EXPECT_EQ(m.roughness_factor, 1.0f);
    EXPECT_FALSE(m.double_sided);
    EXPECT_EQ(m.alpha_mode, AlphaMode::kOpaque);
  }

  Aabb all;
  for (const Drawable& d : s.drawables) {
    const Primitive& p = s.primitives[d.primitive];
    EXPECT_EQ(d.world, glm::mat4(1.0f));
    EXPECT_LE(p.first_vertex + p.vertex_count, s.vertices.size());
    EXPECT_LE(p.first_index + p.index_count, s.indices.size());
    for (uint32_t i = 0; i < p.index_count; ++i)
      EXPECT_LT(s.indices[p.first_index + i], p.vertex_count);
    for (uint32_t v = 0; v < p.vertex_count; ++v) {
      const glm::vec3& pos = s.vertices[p.first_vertex + v].position;
      EXPECT_TRUE(glm::all(glm::lessThanEqual(d.world_bounds.min, pos)));
      EXPECT_TRUE(glm::all(glm::greaterThanEqual(d.world_bounds.max, pos)));
    }
    all.extend(d.world_bounds);
  }
  EXPECT_EQ(all.min, s.bounds.min);
  EXPECT_EQ(all.max, s.bounds.max);
}

TEST_F(EdgeSceneTest, GeometryProjectsOntoThePixelPolygons) {
  const EdgeScene& e = edges();
  const CpuScene& s = e.scene;
  for (size_t i = 0; i < e.shapes.size(); ++i) {
    const auto& poly = e.shapes[i];
    const Primitive& p = s.primitives[s.drawables[1 + i].primitive];
    ASSERT_EQ(p.vertex_count, poly.size()) << i;
    ASSERT_EQ(p.index_count, 3 * (poly.size() - 2)) << i;
    for (uint32_t v = 0; v < p.vertex_count; ++v) {
      const Vertex& vert = s.vertices[p.first_vertex + v];
      EXPECT_FLOAT_EQ(vert.position.z, -10.0f);
      EXPECT_EQ(vert.normal, glm::vec3(0.0f, 0.0f, 1.0f));
      const PixelPoint px = Project(e, vert.position);
      EXPECT_NEAR(px.x, poly[v].x, 1e-3) << "shape " << i << " vertex " << v;
      EXPECT_NEAR(px.y, poly[v].y, 1e-3) << "shape " << i << " vertex " << v;
    }
    // Each triangle faces the camera (counter-clockwise seen from it, the glTF front face),
    // and the triangles add up to the polygon.
    double area = 0.0;
    for (uint32_t t = 0; t < p.index_count; t += 3) {
      const glm::vec3 a = s.vertices[p.first_vertex + s.indices[p.first_index + t]].position;
      const glm::vec3 b = s.vertices[p.first_vertex + s.indices[p.first_index + t + 1]].position;
      const glm::vec3 c = s.vertices[p.first_vertex + s.indices[p.first_index + t + 2]].position;
      const glm::vec3 n = glm::cross(b - a, c - a);
      EXPECT_GE(glm::dot(n, e.eye - a), 0.0f) << "shape " << i << " triangle " << t / 3;
      area += -Area({Project(e, a), Project(e, b), Project(e, c)});
    }
    EXPECT_NEAR(area, -Area(poly), 1e-3 * poly.size()) << i;
  }
}

TEST_F(EdgeSceneTest, BackgroundFillsTheViewBehindTheShapes) {
  const EdgeScene& e = edges();
  const CpuScene& s = e.scene;
  const Primitive& p = s.primitives[s.drawables[0].primitive];
  ASSERT_EQ(p.vertex_count, 4u);
  ASSERT_EQ(p.index_count, 6u);
  double min_x = 1e30, max_x = -1e30, min_y = 1e30, max_y = -1e30;
  for (uint32_t v = 0; v < 4; ++v) {
    const glm::vec3& pos = s.vertices[p.first_vertex + v].position;
    EXPECT_FLOAT_EQ(pos.z, -20.0f);
    const PixelPoint px = Project(e, pos);
    min_x = std::min(min_x, px.x);
    max_x = std::max(max_x, px.x);
    min_y = std::min(min_y, px.y);
    max_y = std::max(max_y, px.y);
  }
  EXPECT_LT(min_x, -double(e.width));
  EXPECT_GT(max_x, 2.0 * e.width);
  EXPECT_LT(min_y, -double(e.height));
  EXPECT_GT(max_y, 2.0 * e.height);
  for (uint32_t t = 0; t < 6; t += 3) {
    const glm::vec3 a = s.vertices[p.first_vertex + s.indices[p.first_index + t]].position;
    const glm::vec3 b = s.vertices[p.first_vertex + s.indices[p.first_index + t + 1]].position;
    const glm::vec3 c = s.vertices[p.first_vertex + s.indices[p.first_index + t + 2]].position;
    EXPECT_GT(glm::cross(b - a, c - a).z, 0.0f);
  }
}

TEST(EdgeScene, Deterministic) {
  const EdgeScene a = BuildEdgeScene(), b = BuildEdgeScene();
  ASSERT_EQ(a.scene.vertices.size(), b.scene.vertices.size());
  EXPECT_EQ(0, std::memcmp(a.scene.vertices.data(), b.scene.vertices.data(),
                           a.scene.vertices.size() * sizeof(Vertex)));
  EXPECT_EQ(a.scene.indices, b.scene.indices);
  EXPECT_EQ(a.coverage, b.coverage);
  ASSERT_EQ(a.shapes.size(), b.shapes.size());
  for (size_t i = 0; i < a.shapes.size(); ++i) {
    ASSERT_EQ(a.shapes[i].size(), b.shapes[i].size());
    for (size_t j = 0; j < a.shapes[i].size(); ++j) {
      EXPECT_EQ(a.shapes[i][j].x, b.shapes[i][j].x);
      EXPECT_EQ(a.shapes[i][j].y, b.shapes[i][j].y);
    }
  }
}

TEST(EdgeScene, OtherSizes) {
  for (const EdgeSceneParams params : {EdgeSceneParams{8, 0}, EdgeSceneParams{16, 3},
                                       EdgeSceneParams{64, 16}, EdgeSceneParams{2, 1}}) {
    const EdgeScene e = BuildEdgeScene(params);
    const uint32_t cell = std::max(params.cell, 8u);  // smaller cells are treated as 8
    EXPECT_EQ(e.width, 13 * (cell + params.gap) + params.gap);
    EXPECT_EQ(e.height, 8 * (cell + params.gap) + params.gap);
    ASSERT_EQ(e.shapes.size(), kHalfPlanes + kWireCount);
    EXPECT_EQ(e.scene.drawables.size(), 1 + e.shapes.size());
    double total = 0.0, areas = 0.0;
    for (float v : e.coverage) {
      EXPECT_GE(v, 0.0f);
      EXPECT_LE(v, 1.0f);
      total += v;
    }
    for (const auto& poly : e.shapes) {
      EXPECT_LT(Area(poly), 0.0);
      areas += -Area(poly);
    }
    EXPECT_NEAR(total, areas, 1e-6 * areas) << params.cell << "/" << params.gap;
    // Every vertex still projects onto its pixel coordinates.
    for (size_t i = 0; i < e.shapes.size(); ++i) {
      const Primitive& p = e.scene.primitives[e.scene.drawables[1 + i].primitive];
      for (uint32_t v = 0; v < p.vertex_count; ++v) {
        const PixelPoint px = Project(e, e.scene.vertices[p.first_vertex + v].position);
        EXPECT_NEAR(px.x, e.shapes[i][v].x, 1e-3);
        EXPECT_NEAR(px.y, e.shapes[i][v].y, 1e-3);
      }
    }
  }
}

}  // namespace
}  // namespace tessera
