// TriangleAdjacency (renderer/scene/adjacency.h): the triangle across each edge, matched by
// position, for vis_mlaa_coverage analytic's resolve.
#include "renderer/scene/adjacency.h"

#include <gtest/gtest.h>

#include <cmath>
#include <glm/gtc/matrix_transform.hpp>

#include "renderer/scene/demo_scene.h"
#include "renderer/scene/gpu_scene.h"

namespace tessera {
namespace {

// A unit square as two triangles whose shared edge's vertices are split (a seam: the same
// positions, other indices), then a lone triangle after it in the same scene.
CpuScene Square() {
  CpuScene s;
  for (glm::vec3 p : {glm::vec3(0, 0, 0), glm::vec3(1, 0, 0), glm::vec3(1, 1, 0),  // triangle 0
                      glm::vec3(0, 0, 0), glm::vec3(1, 1, 0), glm::vec3(0, 1, 0)}) {
    Vertex v;
    v.position = p;
    s.vertices.push_back(v);
  }
  s.indices = {0, 1, 2, 3, 4, 5};
  Primitive square;
  square.first_index = 0;
  square.index_count = 6;
  square.vertex_count = 6;
  s.primitives.push_back(square);
  // A second primitive over the same vertices, its indices after the square's: its triangle is
  // the square's first, but adjacency stays within a primitive.
  s.indices.insert(s.indices.end(), {0, 1, 2});
  Primitive lone;
  lone.first_index = 6;
  lone.index_count = 3;
  lone.vertex_count = 6;
  s.primitives.push_back(lone);
  return s;
}

TEST(AdjacencyTest, SharedEdgesByPosition) {
  const std::vector<uint32_t> a = TriangleAdjacency(Square());
  ASSERT_EQ(a.size(), 9u);
  // Triangle 0: edges 0-1, 1-2 (the diagonal, shared with triangle 1), 2-0.
  EXPECT_EQ(a[0], kNoNeighbour);
  EXPECT_EQ(a[1], kNoNeighbour);
  EXPECT_EQ(a[2], 1u);
  // Triangle 1: edges 3-4 (the diagonal), 4-5, 5-3.
  EXPECT_EQ(a[3], 0u);
  EXPECT_EQ(a[4], kNoNeighbour);
  EXPECT_EQ(a[5], kNoNeighbour);
  for (size_t i = 6; i < 9; ++i) EXPECT_EQ(a[i], kNoNeighbour) << i;
}

// A mirrored drawable (negative determinant) draws a copy of its primitive wound the other way,
// appended once per primitive whatever its instances; each copied triangle keeps its neighbour
// across each (now reversed) edge.
TEST(AdjacencyTest, MirroredCopiesKeepTheirNeighbours) {
  CpuScene s = Square();
  Drawable plain, mirrored, mirrored_again, lone;
  plain.primitive = mirrored.primitive = mirrored_again.primitive = 0;
  lone.primitive = 1;
  mirrored.world = mirrored_again.world = glm::scale(glm::mat4(1.0f), glm::vec3(1.0f, -2.0f, 1.0f));
  lone.world = glm::scale(glm::mat4(1.0f), glm::vec3(-1.0f, -1.0f, 1.0f));  // a turn, not a mirror
  s.drawables = {plain, mirrored, mirrored_again, lone};
  EXPECT_FALSE(MirrorsWinding(plain.world));
  EXPECT_TRUE(MirrorsWinding(mirrored.world));
  EXPECT_FALSE(MirrorsWinding(lone.world));
  const MirrorPlan plan = PlanMirroredRanges(s);
  ASSERT_EQ(plan.first.size(), 2u);
  EXPECT_EQ(plan.first[0], 9u);  // after the scene's nine indices
  EXPECT_EQ(plan.first[1], kNotMirrored);
  EXPECT_EQ(plan.indices, 6u);
  std::vector<uint32_t> indices = s.indices, adjacency = TriangleAdjacency(s),
                        surfaces = SurfaceIndices(s);
  AppendMirroredRanges(s, plan, indices, adjacency, surfaces);
  ASSERT_EQ(indices.size(), 15u);
  ASSERT_EQ(adjacency.size(), 15u);
  for (uint32_t t = 0; t < 2; ++t) {
    const uint32_t o = 3 * t, c = 9 + 3 * t;
    EXPECT_EQ(indices[c], indices[o]);
    EXPECT_EQ(indices[c + 1], indices[o + 2]);
    EXPECT_EQ(indices[c + 2], indices[o + 1]);
  }
  // The diagonal was triangle 0's edge 2 (2-0) and triangle 1's edge 0 (3-4); in the copies,
  // (0, 2, 1) and (3, 5, 4), it is edge 0 (0-2) and edge 2 (4-3), still shared.
  EXPECT_EQ(adjacency[9], 1u);
  EXPECT_EQ(adjacency[12 + 2], 0u);
  for (uint32_t i : {10u, 11u, 12u, 13u}) EXPECT_EQ(adjacency[i], kNoNeighbour) << i;

  // A skinned primitive keeps its winding (glTF ignores its node's transform), and so does one
  // whose indices lie outside the index buffer.
  s.drawables[3].world = mirrored.world;
  EXPECT_EQ(PlanMirroredRanges(s).first[1], 9u + 6u);
  s.primitives[1].skinned = true;
  EXPECT_EQ(PlanMirroredRanges(s).first[1], kNotMirrored);
  s.primitives[1].skinned = false;
  s.primitives[1].index_count = 6;  // past the end
  EXPECT_EQ(PlanMirroredRanges(s).first[1], kNotMirrored);
  EXPECT_EQ(PlanMirroredRanges(s).indices, 6u);
}

// The demo scene's sphere, a closed surface: every edge of it has a neighbour across it (its
// seam's vertices, computed at 0 and 2 pi, meet on the grid), except the zero-length edges of
// the triangles at its poles; and each neighbour has both ends of the edge.
TEST(AdjacencyTest, DemoSpheresAreClosed) {
  const CpuScene scene = BuildDemoScene();
  const std::vector<uint32_t> a = TriangleAdjacency(scene);
  ASSERT_EQ(a.size(), scene.indices.size());
  size_t edges = 0, joined = 0;
  for (const Drawable& d : scene.drawables) {
    const Primitive& p = scene.primitives[d.primitive];
    if (scene.meshes[d.mesh].name != "Red plastic sphere") continue;
    auto at = [&](uint32_t i) {
      return scene.vertices[p.first_vertex + scene.indices[p.first_index + i]].position;
    };
    for (uint32_t i = 0; i < p.index_count; ++i) {
      const uint32_t t = i / 3, e = i % 3;
      if (at(3 * t + e) == at(3 * t + (e + 1) % 3)) continue;  // a pole's degenerate edge
      ++edges;
      const uint32_t n = a[p.first_index + i];
      if (n == kNoNeighbour) continue;
      ++joined;
      ASSERT_LT(n, p.index_count / 3);
      // The neighbour has both ends of the edge among its corners (to the grid's precision).
      for (const glm::vec3 end : {at(3 * t + e), at(3 * t + (e + 1) % 3)}) {
        bool found = false;
        for (uint32_t k = 0; k < 3; ++k) found = found || glm::distance(at(3 * n + k), end) < 1e-5f;
        EXPECT_TRUE(found) << "triangle " << t << " edge " << e << " -> " << n;
      }
    }
    break;  // the spheres share one range
  }
  ASSERT_GT(edges, 0u);
  std::printf("demo sphere: %zu of %zu edges joined\n", joined, edges);
  EXPECT_EQ(joined, edges);
}

// SurfaceIndices: each index's vertex, or the first at its position with the same normal and
// the texture coordinates the material reads, for vis_mlaa's surface test.
TEST(SurfaceIndicesTest, SplitVerticesStandForOneAnotherUnlessTheyDiffer) {
  // The square's diagonal vertices 3 and 4 are 0's and 2's split copies, nothing else apart:
  // they stand for 0 and 2; the second primitive's indices are its own.
  EXPECT_EQ(SurfaceIndices(Square()), (std::vector<uint32_t>{0, 1, 2, 0, 2, 5, 0, 1, 2}));

  CpuScene hard = Square();  // a crease: vertex 3's normal 45 degrees off
  hard.vertices[3].normal = glm::normalize(glm::vec3(1, 0, 1));
  EXPECT_EQ(SurfaceIndices(hard), (std::vector<uint32_t>{0, 1, 2, 3, 2, 5, 0, 1, 2}));
  hard.vertices[3].normal = glm::normalize(glm::vec3(0.1f, 0, 1));  // 5.7 degrees: one surface
  EXPECT_EQ(SurfaceIndices(hard)[3], 0u);

  // A colour edge: vertex 3's COLOR_0 differs.
  CpuScene colored = Square();
  colored.vertices[3].color = PackVertexColor(glm::vec4(1.0f, 0.0f, 0.0f, 1.0f));
  EXPECT_EQ(SurfaceIndices(colored), (std::vector<uint32_t>{0, 1, 2, 3, 2, 5, 0, 1, 2}));

  // A texture seam: vertex 4's coordinates differ, where a texture reads them.
  auto image = std::make_shared<Image>();
  image->width = image->height = 1;
  image->rgba8 = {255, 255, 255, 255};
  CpuScene seam = Square();
  seam.textures = {Texture{image, true, WrapMode::kClampToEdge, WrapMode::kClampToEdge}};
  seam.materials.resize(1);
  seam.materials[0].base_color.texture = 0;
  seam.vertices[4].uv0 = glm::vec2(0.5f, 0.0f);
  EXPECT_EQ(SurfaceIndices(seam), (std::vector<uint32_t>{0, 1, 2, 0, 4, 5, 0, 1, 2}));
  // A whole unit apart under a clamping texture: a seam; under a repeating one: the same texels.
  seam.vertices[4].uv0 = glm::vec2(1.0f, 0.0f);
  EXPECT_EQ(SurfaceIndices(seam)[4], 4u);
  seam.textures[0].wrap_s = seam.textures[0].wrap_t = WrapMode::kRepeat;
  EXPECT_EQ(SurfaceIndices(seam)[4], 2u);
  // Apart in set 0 while the texture reads set 1: no seam; apart in set 1 then is one.
  seam.vertices[4].uv0 = glm::vec2(0.5f, 0.0f);
  seam.materials[0].base_color.texcoord = 1;
  EXPECT_EQ(SurfaceIndices(seam)[4], 2u);
  seam.vertices[4].uv1 = glm::vec2(0.0f, 0.25f);
  EXPECT_EQ(SurfaceIndices(seam)[4], 4u);
  // Untextured: the coordinates are not looked at.
  seam.materials[0].base_color.texture = -1;
  EXPECT_EQ(SurfaceIndices(seam)[4], 2u);
  // ... unless another primitive draws the same index range with a material that does.
  seam.materials.resize(2);
  seam.materials[1].base_color.texture = 0;
  seam.materials[1].base_color.texcoord = 1;
  Primitive textured = seam.primitives[0];
  textured.material = 1;
  seam.primitives.push_back(textured);
  EXPECT_EQ(SurfaceIndices(seam)[4], 4u);

  // The same position within half a cell of the grid (2^-20 of the square's size), across a cell
  // border too; further apart, two positions.
  CpuScene near = Square();
  const float cell = std::ldexp(1.0f, -20);
  near.vertices[0].position.x = 0.45f * cell;
  near.vertices[3].position.x = 0.55f * cell;  // the next cell
  EXPECT_EQ(SurfaceIndices(near)[3], 0u);
  near.vertices[3].position.x = 1.1f * cell;
  EXPECT_EQ(SurfaceIndices(near)[3], 3u);
}

// A mirrored drawable's copy of its primitive's indices carries their surface indices, corner for
// corner.
TEST(SurfaceIndicesTest, MirroredCopiesFollowTheirIndices) {
  CpuScene s = Square();
  s.vertices[3].normal = glm::normalize(glm::vec3(1, 0, 1));  // so the corners differ
  Drawable d;
  d.primitive = 0;
  d.world = glm::scale(glm::mat4(1.0f), glm::vec3(-1, 1, 1));
  s.drawables.push_back(d);
  const MirrorPlan plan = PlanMirroredRanges(s);
  ASSERT_EQ(plan.indices, 6u);
  std::vector<uint32_t> indices = s.indices, adjacency = TriangleAdjacency(s);
  std::vector<uint32_t> surfaces = SurfaceIndices(s);
  AppendMirroredRanges(s, plan, indices, adjacency, surfaces);
  ASSERT_EQ(surfaces.size(), indices.size());
  for (uint32_t t = 0; t < 2; ++t) {
    const uint32_t o = 3 * t, c = plan.first[0] + 3 * t;
    EXPECT_EQ(surfaces[c], surfaces[o]);
    EXPECT_EQ(surfaces[c + 1], surfaces[o + 2]);
    EXPECT_EQ(surfaces[c + 2], surfaces[o + 1]);
  }
  EXPECT_EQ(surfaces[plan.first[0] + 3], 3u);  // the copy of (3, 4, 5) is (3, 5, 4)
  EXPECT_EQ(surfaces[plan.first[0] + 4], 5u);
  EXPECT_EQ(surfaces[plan.first[0] + 5], 2u);
}

// UvSeamSets (adjacency.h): which texture coordinate sets vis_mlaa's surface test compares, and
// where whole-unit jumps are no seam.
TEST(UvSeamSetsTest, TheSetsTheTexturesReadAndTheirPeriods) {
  auto image = std::make_shared<Image>();
  image->width = image->height = 1;
  image->rgba8 = {255, 255, 255, 255};
  std::vector<Texture> textures = {
      Texture{image, true, WrapMode::kRepeat, WrapMode::kRepeat},
      Texture{image, false, WrapMode::kClampToEdge, WrapMode::kRepeat},
      Texture{image, false, WrapMode::kRepeat, WrapMode::kMirroredRepeat}};
  Material untextured;
  EXPECT_EQ(UvSeamSets(untextured, textures), 0u);

  Material base;
  base.base_color.texture = 0;
  EXPECT_EQ(UvSeamSets(base, textures), kUvSeamSet0 | kUvSeamPeriodic0);
  // A whole-number scale (and a 90-degree turn) keeps whole steps whole; half a scale does not.
  base.base_color.scale = glm::vec2(3.0f, 2.0f);
  base.base_color.offset = glm::vec2(0.3f, 0.7f);
  EXPECT_EQ(UvSeamSets(base, textures), kUvSeamSet0 | kUvSeamPeriodic0);
  base.base_color.rotation = 1.5707963f;
  EXPECT_EQ(UvSeamSets(base, textures), kUvSeamSet0 | kUvSeamPeriodic0);
  base.base_color.rotation = 0.3f;
  EXPECT_EQ(UvSeamSets(base, textures), kUvSeamSet0);
  base.base_color.rotation = 0.0f;
  base.base_color.scale = glm::vec2(0.5f, 1.0f);
  EXPECT_EQ(UvSeamSets(base, textures), kUvSeamSet0);

  // Set 1 read by an occlusion map that clamps on one axis: compared, not periodic; set 0 stays
  // periodic. Another texture on set 0 that mirrors makes set 0 aperiodic too.
  Material both;
  both.base_color.texture = 0;
  both.occlusion.texture = 1;
  both.occlusion.texcoord = 1;
  EXPECT_EQ(UvSeamSets(both, textures),
            kUvSeamSet0 | kUvSeamPeriodic0 | kUvSeamSet1);
  both.normal.texture = 2;
  EXPECT_EQ(UvSeamSets(both, textures), kUvSeamSet0 | kUvSeamSet1);
  // KHR_materials_specular's textures are read like the others: set 1 by the specular colour,
  // aperiodic (it clamps), set 0 by the strength.
  Material specular;
  specular.specular_color.texture = 1;
  specular.specular_color.texcoord = 1;
  EXPECT_EQ(UvSeamSets(specular, textures), kUvSeamSet1);
  specular.specular.texture = 0;
  EXPECT_EQ(UvSeamSets(specular, textures), kUvSeamSet0 | kUvSeamPeriodic0 | kUvSeamSet1);
  // A texture index out of range reads nothing.
  Material dangling;
  dangling.emissive.texture = 7;
  EXPECT_EQ(UvSeamSets(dangling, textures), 0u);
}

}  // namespace
}  // namespace tessera
