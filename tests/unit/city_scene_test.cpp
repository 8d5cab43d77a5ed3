// The generated city scene: size, determinism, consistent buffers and bounds, outward winding,
// and the layout promises (buildings on their own lots, streets clear).
#include "renderer/scene/city_scene.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <glm/glm.hpp>
#include <set>
#include <string>
#include <vector>

namespace tessera {
namespace {

constexpr float kEps = 1e-3f;  // metres; the city is ~1 km across

bool Contains(const Aabb& outer, const Aabb& inner, float eps = kEps) {
  return glm::all(glm::lessThanEqual(outer.min, inner.min + eps)) &&
         glm::all(glm::greaterThanEqual(outer.max, inner.max - eps));
}

bool Contains(const Aabb& box, const glm::vec3& p, float eps = kEps) {
  return glm::all(glm::lessThanEqual(box.min, p + eps)) &&
         glm::all(glm::greaterThanEqual(box.max, p - eps));
}

bool IsBuilding(const CpuScene& s, const Drawable& d) {
  return s.meshes[d.mesh].name.rfind("Building", 0) == 0;
}

std::vector<const Drawable*> Buildings(const CpuScene& s) {
  std::vector<const Drawable*> out;
  for (const Drawable& d : s.drawables) {
    if (IsBuilding(s, d)) out.push_back(&d);
  }
  return out;
}

// The block (between streets i and i + 1) that coordinate v lies in, or -1.
int BlockOf(float v, uint32_t blocks, float (*street)(const CityParams&, uint32_t),
            const CityParams& p) {
  for (uint32_t i = 0; i < blocks; ++i) {
    if (v > street(p, i) && v < street(p, i + 1)) return static_cast<int>(i);
  }
  return -1;
}

// Open intervals overlap (touching is fine).
bool Overlap(float a0, float a1, float b0, float b1) { return a0 < b1 && b0 < a1; }

class CityScene : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { scene_ = new CpuScene(BuildCityScene()); }
  static void TearDownTestSuite() {
    delete scene_;
    scene_ = nullptr;
  }
  static const CpuScene& scene() { return *scene_; }

 private:
  static CpuScene* scene_;
};

CpuScene* CityScene::scene_ = nullptr;

TEST_F(CityScene, HasContent) {
  const CpuScene& s = scene();
  EXPECT_EQ(s.name, "city");
  EXPECT_GE(s.drawables.size(), 10000u);
  EXPECT_EQ(Buildings(s).size(), 10u * 10u * 100u);
  EXPECT_TRUE(s.warnings.empty());
  EXPECT_TRUE(s.textures.empty());
  // Instancing keeps the vertex buffer tiny whatever the city size.
  EXPECT_LT(s.vertices.size(), 2000u);
  EXPECT_LE(s.meshes.size(), 32u);
}

TEST_F(CityScene, IsDeterministic) {
  const CpuScene& a = scene();
  const CpuScene b = BuildCityScene();
  ASSERT_EQ(a.vertices.size(), b.vertices.size());
  EXPECT_EQ(std::memcmp(a.vertices.data(), b.vertices.data(), a.vertices.size() * sizeof(Vertex)),
            0);
  EXPECT_EQ(a.indices, b.indices);
  ASSERT_EQ(a.drawables.size(), b.drawables.size());
  for (size_t d = 0; d < a.drawables.size(); ++d) {
    ASSERT_EQ(std::memcmp(&a.drawables[d].world, &b.drawables[d].world, sizeof(glm::mat4)), 0)
        << "drawable " << d;
    ASSERT_EQ(a.drawables[d].primitive, b.drawables[d].primitive) << "drawable " << d;
  }
  EXPECT_EQ(a.counts.triangles, b.counts.triangles);
}

TEST_F(CityScene, SeedChangesTheCity) {
  CityParams p;
  p.seed = 2;
  const CpuScene other = BuildCityScene(p);
  const std::vector<const Drawable*> a = Buildings(scene()), b = Buildings(other);
  ASSERT_EQ(a.size(), b.size());
  size_t different = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    different += std::memcmp(&a[i]->world, &b[i]->world, sizeof(glm::mat4)) != 0;
  }
  EXPECT_GT(different, a.size() / 2);
}

TEST_F(CityScene, CountsMatchArrays) {
  const CpuScene& s = scene();
  EXPECT_EQ(s.counts.nodes, s.drawables.size());
  EXPECT_EQ(s.counts.meshes, s.meshes.size());
  EXPECT_EQ(s.counts.primitives, s.primitives.size());
  EXPECT_EQ(s.counts.materials, s.materials.size());
  EXPECT_EQ(s.counts.textures, 0u);
  EXPECT_EQ(s.counts.images, 0u);
  EXPECT_EQ(s.counts.lights, s.lights.size());
  EXPECT_EQ(s.counts.cameras, s.cameras.size());
  uint64_t triangles = 0;
  for (const Drawable& d : s.drawables) {
    ASSERT_LT(d.primitive, s.primitives.size());
    triangles += s.primitives[d.primitive].index_count / 3;
  }
  EXPECT_EQ(s.counts.triangles, triangles);
  EXPECT_GT(triangles, 500000u);
}

TEST_F(CityScene, PrimitivesAndIndicesInRange) {
  const CpuScene& s = scene();
  for (size_t p = 0; p < s.primitives.size(); ++p) {
    const Primitive& prim = s.primitives[p];
    SCOPED_TRACE(testing::Message() << "primitive " << p);
    ASSERT_GT(prim.index_count, 0u);
    ASSERT_EQ(prim.index_count % 3, 0u);
    ASSERT_LE(uint64_t{prim.first_index} + prim.index_count, s.indices.size());
    ASSERT_LE(uint64_t{prim.first_vertex} + prim.vertex_count, s.vertices.size());
    EXPECT_LT(prim.material, s.materials.size());
    for (uint32_t i = prim.first_index; i < prim.first_index + prim.index_count; ++i) {
      ASSERT_LT(s.indices[i], prim.vertex_count) << "index " << i;
    }
    for (uint32_t i = 0; i < prim.vertex_count; ++i) {
      ASSERT_TRUE(Contains(prim.bounds, s.vertices[prim.first_vertex + i].position, 0.0f));
    }
  }
  for (size_t i = 0; i < s.drawables.size(); ++i) {
    const Drawable& d = s.drawables[i];
    ASSERT_LT(d.mesh, s.meshes.size());
    const auto& prims = s.meshes[d.mesh].primitives;
    EXPECT_NE(std::find(prims.begin(), prims.end(), d.primitive), prims.end());
    EXPECT_EQ(d.node, i);
  }
}

TEST_F(CityScene, VertexFramesAreOrthonormal) {
  const CpuScene& s = scene();
  for (size_t i = 0; i < s.vertices.size(); ++i) {
    const Vertex& v = s.vertices[i];
    SCOPED_TRACE(testing::Message() << "vertex " << i);
    ASSERT_NEAR(glm::length(v.normal), 1.0f, 1e-5f);
    const glm::vec3 t(v.tangent);
    ASSERT_NEAR(glm::length(t), 1.0f, 1e-5f);
    ASSERT_NEAR(glm::dot(t, v.normal), 0.0f, 1e-5f);
    ASSERT_EQ(v.tangent.w, 1.0f);
    ASSERT_TRUE(glm::all(glm::greaterThanEqual(v.uv0, glm::vec2(-1e-5f))));
    ASSERT_TRUE(glm::all(glm::lessThanEqual(v.uv0, glm::vec2(1.0f + 1e-5f))));
  }
}

TEST_F(CityScene, TrianglesWindOutward) {
  // Counter-clockwise front faces (glTF): the geometric normal agrees with the (flat) vertex
  // normals, and on the closed convex solids (buildings, canopies) points away from the centre.
  const CpuScene& s = scene();
  int solids = 0;
  for (size_t p = 0; p < s.primitives.size(); ++p) {
    const Primitive& prim = s.primitives[p];
    const glm::vec3 extent = prim.bounds.extent();
    const bool solid = extent.x > 0.0f && extent.y > 0.0f && extent.z > 0.0f;
    solids += solid;
    const glm::vec3 centre = prim.bounds.center();
    const Vertex* v = s.vertices.data() + prim.first_vertex;
    for (uint32_t i = prim.first_index; i < prim.first_index + prim.index_count; i += 3) {
      SCOPED_TRACE(testing::Message()
                   << "primitive " << p << " triangle " << (i - prim.first_index) / 3);
      const Vertex &a = v[s.indices[i]], &b = v[s.indices[i + 1]], &c = v[s.indices[i + 2]];
      const glm::vec3 n = glm::cross(b.position - a.position, c.position - a.position);
      ASSERT_GT(glm::length(n), 1e-6f);
      const glm::vec3 nn = glm::normalize(n);
      for (const Vertex* x : {&a, &b, &c}) ASSERT_GT(glm::dot(nn, x->normal), 0.9999f);
      if (solid) {
        const glm::vec3 centroid = (a.position + b.position + c.position) / 3.0f;
        ASSERT_GT(glm::dot(nn, centroid - centre), 0.0f);
      }
    }
  }
  EXPECT_GE(solids, 5);  // four building variants and the canopy
}

TEST_F(CityScene, WorldBoundsContainGeometry) {
  const CpuScene& s = scene();
  ASSERT_FALSE(s.bounds.empty());
  for (size_t i = 0; i < s.drawables.size(); ++i) {
    const Drawable& d = s.drawables[i];
    const Aabb& b = s.primitives[d.primitive].bounds;
    SCOPED_TRACE(testing::Message() << "drawable " << i);
    ASSERT_TRUE(Contains(s.bounds, d.world_bounds, 0.0f));
    for (int corner = 0; corner < 8; ++corner) {
      const glm::vec3 p((corner & 1) ? b.max.x : b.min.x, (corner & 2) ? b.max.y : b.min.y,
                        (corner & 4) ? b.max.z : b.min.z);
      ASSERT_TRUE(Contains(d.world_bounds, glm::vec3(d.world * glm::vec4(p, 1.0f))));
    }
    // Everything stands on the ground.
    ASSERT_GT(d.world_bounds.min.y, -kEps);
  }
  EXPECT_NEAR(s.bounds.min.y, 0.0f, kEps);
  EXPECT_LE(s.bounds.max.y, 64.0f + kEps);  // 60 m towers and their signs
  EXPECT_GT(s.bounds.extent().x, 1000.0f);
  EXPECT_GT(s.bounds.extent().z, 1000.0f);
}

TEST_F(CityScene, BuildingSizes) {
  const CpuScene& s = scene();
  float tallest = 0.0f, lowest = 1e9f;
  for (const Drawable* d : Buildings(s)) {
    const glm::vec3 e = d->world_bounds.extent();
    ASSERT_GE(e.x, 7.0f - kEps);
    ASSERT_LE(e.x, 9.0f + kEps);
    ASSERT_GE(e.z, 7.0f - kEps);
    ASSERT_LE(e.z, 9.0f + kEps);
    ASSERT_GE(e.y, 8.0f - kEps);
    ASSERT_LE(e.y, 60.0f + kEps);
    tallest = std::max(tallest, e.y);
    lowest = std::min(lowest, e.y);
  }
  EXPECT_GT(tallest, 45.0f);
  EXPECT_LT(lowest, 10.0f);
}

TEST_F(CityScene, BuildingsDoNotOverlap) {
  // Compare buildings within each block (streets separate the blocks, see StreetsAreClear).
  const CpuScene& s = scene();
  const CityParams p;
  std::vector<std::vector<const Drawable*>> blocks(p.blocks_x * p.blocks_z);
  for (const Drawable* d : Buildings(s)) {
    const glm::vec3 c = d->world_bounds.center();
    const int bx = BlockOf(c.x, p.blocks_x, CityStreetX, p);
    const int bz = BlockOf(c.z, p.blocks_z, CityStreetZ, p);
    ASSERT_GE(bx, 0);
    ASSERT_GE(bz, 0);
    blocks[bz * p.blocks_x + bx].push_back(d);
  }
  for (size_t b = 0; b < blocks.size(); ++b) {
    const auto& in = blocks[b];
    ASSERT_EQ(in.size(), p.buildings_per_side * p.buildings_per_side) << "block " << b;
    for (size_t i = 0; i < in.size(); ++i) {
      for (size_t j = i + 1; j < in.size(); ++j) {
        const Aabb &u = in[i]->world_bounds, &v = in[j]->world_bounds;
        ASSERT_FALSE(Overlap(u.min.x, u.max.x, v.min.x, v.max.x) &&
                     Overlap(u.min.z, u.max.z, v.min.z, v.max.z))
            << "block " << b << ": drawables " << in[i]->node << " and " << in[j]->node;
      }
    }
  }
}

TEST_F(CityScene, StreetsAreClear) {
  const CpuScene& s = scene();
  const CityParams p;
  // Streets are ~16 m wide: nothing but ground and canopies within 5 m of a street centre.
  constexpr float kHalf = 5.0f;
  for (uint32_t i = 0; i < p.blocks_x; ++i) {
    EXPECT_GT(CityStreetX(p, i + 1) - CityStreetX(p, i), 100.0f);
  }
  for (uint32_t i = 0; i < p.blocks_z; ++i) {
    EXPECT_GT(CityStreetZ(p, i + 1) - CityStreetZ(p, i), 100.0f);
  }
  for (const Drawable* d : Buildings(s)) {
    const Aabb& b = d->world_bounds;
    for (uint32_t i = 0; i <= p.blocks_x; ++i) {
      const float x = CityStreetX(p, i);
      ASSERT_FALSE(Overlap(b.min.x, b.max.x, x - kHalf, x + kHalf)) << "drawable " << d->node;
    }
    for (uint32_t i = 0; i <= p.blocks_z; ++i) {
      const float z = CityStreetZ(p, i);
      ASSERT_FALSE(Overlap(b.min.z, b.max.z, z - kHalf, z + kHalf)) << "drawable " << d->node;
    }
  }
  // The outer streets run around the city: everything lies within them (plus half a street).
  EXPECT_NEAR(s.bounds.min.x, CityStreetX(p, 0) - 8.0f, 1.0f);
  EXPECT_NEAR(s.bounds.max.x, CityStreetX(p, p.blocks_x) + 8.0f, 1.0f);
  EXPECT_NEAR(s.bounds.min.z, CityStreetZ(p, 0) - 8.0f, 1.0f);
  EXPECT_NEAR(s.bounds.max.z, CityStreetZ(p, p.blocks_z) + 8.0f, 1.0f);
}

TEST_F(CityScene, MaterialsCoverEveryRenderGroup) {
  const CpuScene& s = scene();
  std::vector<int> uses(s.materials.size(), 0);
  for (const Drawable& d : s.drawables) ++uses[s.primitives[d.primitive].material];
  int opaque = 0, double_sided = 0, blend = 0;
  for (size_t i = 0; i < s.materials.size(); ++i) {
    const Material& m = s.materials[i];
    SCOPED_TRACE(m.name);
    EXPECT_GT(uses[i], 0) << "not drawn";
    EXPECT_EQ(m.metallic_factor, 0.0f);
    EXPECT_GT(m.roughness_factor, 0.0f);
    EXPECT_LE(m.roughness_factor, 1.0f);
    EXPECT_EQ(m.base_color.texture, -1);
    EXPECT_EQ(m.normal.texture, -1);
    EXPECT_NE(m.alpha_mode, AlphaMode::kMask);
    if (m.alpha_mode == AlphaMode::kBlend) {
      ++blend;
      EXPECT_FALSE(m.double_sided);
      EXPECT_FLOAT_EQ(m.base_color_factor.a, 0.5f);
      EXPECT_GE(uses[i], 1);
      EXPECT_LE(uses[i], 64);
    } else if (m.double_sided) {
      ++double_sided;
      EXPECT_GE(uses[i], 100);
      EXPECT_LE(uses[i], 1000);
    } else {
      ++opaque;
      EXPECT_EQ(m.base_color_factor.a, 1.0f);
    }
  }
  EXPECT_GE(opaque, 4);
  EXPECT_LE(opaque, 6);
  EXPECT_EQ(double_sided, 1);
  EXPECT_EQ(blend, 1);
}

TEST_F(CityScene, SunAndStreetCamera) {
  const CpuScene& s = scene();
  ASSERT_EQ(s.lights.size(), 1u);
  const Light& sun = s.lights[0];
  EXPECT_EQ(sun.type, LightType::kDirectional);
  EXPECT_NEAR(glm::length(sun.direction), 1.0f, 1e-5f);
  EXPECT_LT(sun.direction.y, -0.5f);
  EXPECT_GT(std::abs(sun.direction.x) + std::abs(sun.direction.z), 0.1f);
  EXPECT_GT(sun.intensity, 1.0f);

  ASSERT_EQ(s.cameras.size(), 1u);
  const SceneCamera& cam = s.cameras[0];
  EXPECT_EQ(cam.name, "street");
  EXPECT_GT(cam.znear, 0.0f);
  EXPECT_TRUE(cam.zfar == 0.0f || cam.zfar > 1000.0f);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(glm::length(glm::vec3(cam.world[c])), 1.0f, 1e-5f);
  const glm::vec3 eye(cam.world[3]);
  EXPECT_GT(eye.y, 1.0f);
  EXPECT_LT(eye.y, 3.0f);
  // On a street centre line, looking along it (the camera looks down its local -Z).
  const CityParams p;
  bool on_street = false;
  for (uint32_t i = 0; i <= p.blocks_x; ++i)
    on_street |= std::abs(eye.x - CityStreetX(p, i)) < 1.0f;
  EXPECT_TRUE(on_street);
  const glm::vec3 forward = -glm::vec3(cam.world[2]);
  EXPECT_GT(std::abs(forward.z), 0.99f);
  // Not inside a building, and most of the city is ahead.
  for (const Drawable* d : Buildings(s)) {
    const Aabb& b = d->world_bounds;
    ASSERT_FALSE(eye.x > b.min.x && eye.x < b.max.x && eye.z > b.min.z && eye.z < b.max.z);
  }
  EXPECT_GT(glm::dot(s.bounds.center() - eye, forward), 0.0f);
}

TEST(CitySceneParams, SmallCity) {
  CityParams p;
  p.blocks_x = 2;
  p.blocks_z = 3;
  p.buildings_per_side = 4;
  p.facade_detail = 1;
  p.seed = 7;
  const CpuScene s = BuildCityScene(p);
  EXPECT_EQ(Buildings(s).size(), 2u * 3u * 16u);
  size_t ground = 0;
  for (const Drawable& d : s.drawables) ground += d.world_bounds.extent().y == 0.0f;
  EXPECT_EQ(ground, (2u * 2u + 1u) * (2u * 3u + 1u));
  // Fewer facade quads than the default detail.
  const CpuScene def = BuildCityScene();
  EXPECT_LT(s.vertices.size(), def.vertices.size());
  // Streets: 16 m wide around 40 m blocks.
  EXPECT_NEAR(CityStreetX(p, 1) - CityStreetX(p, 0), 56.0f, 1e-3f);
  EXPECT_NEAR(CityStreetZ(p, 3) - CityStreetZ(p, 0), 3.0f * 56.0f, 1e-3f);
  EXPECT_NEAR(CityStreetX(p, 0) + CityStreetX(p, 2), 0.0f, 1e-3f);  // centred on the origin
  EXPECT_EQ(s.counts.nodes, s.drawables.size());
}

TEST(CitySceneParams, ZerosAreClampedToOne) {
  CityParams p;
  p.blocks_x = 0;
  p.blocks_z = 0;
  p.buildings_per_side = 0;
  p.facade_detail = 0;
  const CpuScene s = BuildCityScene(p);
  EXPECT_EQ(Buildings(s).size(), 1u);
  EXPECT_FALSE(s.bounds.empty());
  for (const Primitive& prim : s.primitives) EXPECT_GT(prim.index_count, 0u);
}

}  // namespace
}  // namespace tessera
