#include "renderer/scene/demo_scene.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <glm/glm.hpp>
#include <set>
#include <vector>

namespace tessera {
namespace {

constexpr float kEps = 1e-4f;

bool Contains(const Aabb& outer, const Aabb& inner, float eps = kEps) {
  return glm::all(glm::lessThanEqual(outer.min, inner.min + eps)) &&
         glm::all(glm::greaterThanEqual(outer.max, inner.max - eps));
}

bool Contains(const Aabb& box, const glm::vec3& p, float eps = kEps) {
  return glm::all(glm::lessThanEqual(box.min, p + eps)) &&
         glm::all(glm::greaterThanEqual(box.max, p - eps));
}

template <glm::length_t N>
bool Finite(const glm::vec<N, float>& v) {
  return !glm::any(glm::isnan(v)) && !glm::any(glm::isinf(v));
}

class DemoScene : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { scene_ = new CpuScene(BuildDemoScene()); }
  static void TearDownTestSuite() {
    delete scene_;
    scene_ = nullptr;
  }
  static const CpuScene& scene() { return *scene_; }

 private:
  static CpuScene* scene_;
};

CpuScene* DemoScene::scene_ = nullptr;

TEST_F(DemoScene, HasContent) {
  const CpuScene& s = scene();
  EXPECT_FALSE(s.name.empty());
  EXPECT_GE(s.drawables.size(), 7u);
  EXPECT_GE(s.materials.size(), 7u);
  EXPECT_GE(s.textures.size(), 3u);
  EXPECT_EQ(s.cameras.size(), 1u);
  EXPECT_TRUE(s.warnings.empty());
}

TEST_F(DemoScene, CountsMatchArrays) {
  const CpuScene& s = scene();
  EXPECT_EQ(s.counts.nodes, s.drawables.size());
  EXPECT_EQ(s.counts.meshes, s.meshes.size());
  EXPECT_EQ(s.counts.primitives, s.primitives.size());
  EXPECT_EQ(s.counts.materials, s.materials.size());
  EXPECT_EQ(s.counts.textures, s.textures.size());
  EXPECT_EQ(s.counts.lights, s.lights.size());
  EXPECT_EQ(s.counts.cameras, s.cameras.size());
  std::set<const Image*> images;
  for (const Texture& t : s.textures) images.insert(t.image.get());
  EXPECT_EQ(s.counts.images, images.size());
  uint64_t triangles = 0;
  for (const Drawable& d : s.drawables) {
    ASSERT_LT(d.primitive, s.primitives.size());
    triangles += s.primitives[d.primitive].index_count / 3;
  }
  EXPECT_EQ(s.counts.triangles, triangles);
  EXPECT_GT(triangles, 1000u);
}

TEST_F(DemoScene, PrimitivesAndIndicesInRange) {
  const CpuScene& s = scene();
  ASSERT_FALSE(s.primitives.empty());
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
  }
  for (const Mesh& mesh : s.meshes) {
    EXPECT_FALSE(mesh.primitives.empty()) << mesh.name;
    for (uint32_t p : mesh.primitives) EXPECT_LT(p, s.primitives.size()) << mesh.name;
  }
  for (const Drawable& d : s.drawables) {
    ASSERT_LT(d.mesh, s.meshes.size());
    const auto& prims = s.meshes[d.mesh].primitives;
    EXPECT_NE(std::find(prims.begin(), prims.end(), d.primitive), prims.end());
    EXPECT_LT(d.node, s.counts.nodes);
  }
}

TEST_F(DemoScene, VertexFramesAreOrthonormal) {
  const CpuScene& s = scene();
  static_assert(sizeof(Vertex) == 64);
  for (size_t i = 0; i < s.vertices.size(); ++i) {
    const Vertex& v = s.vertices[i];
    SCOPED_TRACE(testing::Message() << "vertex " << i);
    ASSERT_TRUE(Finite(v.position));
    ASSERT_NEAR(glm::length(v.normal), 1.0f, 1e-4f);
    const glm::vec3 t(v.tangent);
    ASSERT_NEAR(glm::length(t), 1.0f, 1e-4f);
    ASSERT_NEAR(glm::dot(t, v.normal), 0.0f, 1e-4f);
    ASSERT_TRUE(v.tangent.w == 1.0f || v.tangent.w == -1.0f);
    ASSERT_TRUE(Finite(v.uv0));
    ASSERT_TRUE(Finite(v.uv1));
    ASSERT_EQ(UnpackVertexColor(v.color), glm::vec4(1.0f));  // the demo has no vertex colours
  }
}

TEST_F(DemoScene, TrianglesFaceTheirNormals) {
  // glTF front faces are counter-clockwise; a triangle wound against its vertex normals
  // would be culled or lit from behind.
  const CpuScene& s = scene();
  for (size_t p = 0; p < s.primitives.size(); ++p) {
    const Primitive& prim = s.primitives[p];
    const Vertex* v = s.vertices.data() + prim.first_vertex;
    for (uint32_t i = prim.first_index; i < prim.first_index + prim.index_count; i += 3) {
      const Vertex &a = v[s.indices[i]], &b = v[s.indices[i + 1]], &c = v[s.indices[i + 2]];
      const glm::vec3 n = glm::cross(b.position - a.position, c.position - a.position);
      ASSERT_GT(glm::length(n), 0.0f) << "degenerate triangle in primitive " << p;
      ASSERT_GT(glm::dot(n, a.normal + b.normal + c.normal), 0.0f)
          << "primitive " << p << " triangle " << (i - prim.first_index) / 3;
    }
  }
}

TEST_F(DemoScene, TangentHandednessIsUpright) {
  // Every surface maps its textures without mirroring, so with glTF's convention
  // (bitangent = cross(N, T) * w points towards decreasing v) every w is +1; and the
  // bitangent really does point against the v gradient across each triangle.
  const CpuScene& s = scene();
  for (const Primitive& prim : s.primitives) {
    const Vertex* v = s.vertices.data() + prim.first_vertex;
    for (uint32_t i = prim.first_index; i < prim.first_index + prim.index_count; i += 3) {
      const Vertex &a = v[s.indices[i]], &b = v[s.indices[i + 1]], &c = v[s.indices[i + 2]];
      ASSERT_EQ(a.tangent.w, 1.0f);
      // Solve for dP/dv over the triangle.
      const glm::vec3 e1 = b.position - a.position, e2 = c.position - a.position;
      const glm::vec2 d1 = b.uv0 - a.uv0, d2 = c.uv0 - a.uv0;
      const float det = d1.x * d2.y - d2.x * d1.y;
      if (std::abs(det) < 1e-12f) continue;
      const glm::vec3 dpdu = (e1 * d2.y - e2 * d1.y) / det;
      const glm::vec3 dpdv = (e2 * d1.x - e1 * d2.x) / det;
      const glm::vec3 bitangent = glm::cross(a.normal, glm::vec3(a.tangent)) * a.tangent.w;
      ASSERT_GT(glm::dot(glm::vec3(a.tangent), dpdu), 0.0f);
      ASSERT_LT(glm::dot(bitangent, dpdv), 0.0f);
    }
  }
}

TEST_F(DemoScene, BoundsContainGeometry) {
  const CpuScene& s = scene();
  ASSERT_FALSE(s.bounds.empty());
  for (const Primitive& prim : s.primitives) {
    ASSERT_FALSE(prim.bounds.empty());
    for (uint32_t i = 0; i < prim.vertex_count; ++i) {
      ASSERT_TRUE(Contains(prim.bounds, s.vertices[prim.first_vertex + i].position));
    }
  }
  for (const Drawable& d : s.drawables) {
    const Primitive& prim = s.primitives[d.primitive];
    EXPECT_TRUE(Contains(s.bounds, d.world_bounds));
    for (uint32_t i = 0; i < prim.vertex_count; ++i) {
      const glm::vec3 p =
          glm::vec3(d.world * glm::vec4(s.vertices[prim.first_vertex + i].position, 1.0f));
      ASSERT_TRUE(Contains(d.world_bounds, p, 1e-3f)) << "drawable " << d.node;
    }
    // Objects rest on or above the floor (y = 0).
    EXPECT_GT(d.world_bounds.min.y, -1e-3f) << "drawable " << d.node;
  }
  EXPECT_NEAR(s.bounds.min.y, 0.0f, 1e-3f);
  // Scale: a floor of about 12 m, objects about 1 m.
  EXPECT_GT(s.bounds.extent().x, 10.0f);
  EXPECT_LT(s.bounds.extent().x, 20.0f);
  EXPECT_LT(s.bounds.max.y, 3.0f);
}

TEST_F(DemoScene, TexturesAreValid) {
  const CpuScene& s = scene();
  uint32_t width = 0, height = 0;
  for (size_t t = 0; t < s.textures.size(); ++t) {
    const Texture& tex = s.textures[t];
    SCOPED_TRACE(testing::Message() << "texture " << t);
    ASSERT_NE(tex.image, nullptr);
    const Image& img = *tex.image;
    EXPECT_FALSE(img.name.empty());
    ASSERT_GT(img.width, 0u);
    EXPECT_EQ(img.width & (img.width - 1), 0u) << "not a power of two";
    EXPECT_EQ(img.height & (img.height - 1), 0u) << "not a power of two";
    EXPECT_EQ(img.rgba8.size(), size_t{img.width} * img.height * 4);
    if (width == 0) {
      width = img.width;
      height = img.height;
    }
    EXPECT_EQ(img.width, width);
    EXPECT_EQ(img.height, height);
  }
  // Every texture is used, with the colour space its slot needs.
  std::set<int32_t> used;
  for (const Material& m : s.materials) {
    for (const TextureRef* ref : m.TextureSlots()) {
      ASSERT_GE(ref->texture, -1) << m.name;
      ASSERT_LT(ref->texture, static_cast<int32_t>(s.textures.size())) << m.name;
      ASSERT_LE(ref->texcoord, 1u) << m.name;
      if (ref->texture >= 0) used.insert(ref->texture);
    }
    if (m.base_color.texture >= 0) {
      EXPECT_TRUE(s.textures[m.base_color.texture].srgb);
    }
    if (m.metallic_roughness.texture >= 0) {
      EXPECT_FALSE(s.textures[m.metallic_roughness.texture].srgb);
    }
    if (m.normal.texture >= 0) {
      EXPECT_FALSE(s.textures[m.normal.texture].srgb);
    }
  }
  EXPECT_EQ(used.size(), s.textures.size());
}

TEST_F(DemoScene, NormalAndMetallicRoughnessMapsAreSane) {
  const CpuScene& s = scene();
  bool has_normal_map = false, has_mr_map = false;
  for (const Material& m : s.materials) {
    if (m.normal.texture >= 0) {
      has_normal_map = true;
      const Image& img = *s.textures[m.normal.texture].image;
      bool tilted = false;
      for (size_t i = 0; i < img.rgba8.size(); i += 4) {
        const glm::vec3 n =
            glm::vec3(img.rgba8[i], img.rgba8[i + 1], img.rgba8[i + 2]) / 255.0f * 2.0f - 1.0f;
        ASSERT_NEAR(glm::length(n), 1.0f, 0.02f) << "texel " << i / 4;
        ASSERT_GT(n.z, 0.0f);
        tilted |= n.z < 0.95f;
      }
      EXPECT_TRUE(tilted) << "normal map is flat";
    }
    if (m.metallic_roughness.texture >= 0) {
      has_mr_map = true;
      const Image& img = *s.textures[m.metallic_roughness.texture].image;
      std::set<uint8_t> roughness, metallic;
      for (size_t i = 0; i < img.rgba8.size(); i += 4) {
        roughness.insert(img.rgba8[i + 1]);
        metallic.insert(img.rgba8[i + 2]);
      }
      EXPECT_GT(roughness.size(), 10u);
      EXPECT_TRUE(metallic.count(0) && metallic.count(255));
    }
  }
  EXPECT_TRUE(has_normal_map);
  EXPECT_TRUE(has_mr_map);
}

TEST_F(DemoScene, HasMaskAndBlendMaterials) {
  const CpuScene& s = scene();
  int mask = 0, blend = 0;
  std::set<uint32_t> drawn;
  for (const Drawable& d : s.drawables) drawn.insert(s.primitives[d.primitive].material);
  for (uint32_t i = 0; i < s.materials.size(); ++i) {
    const Material& m = s.materials[i];
    EXPECT_GE(m.metallic_factor, 0.0f);
    EXPECT_LE(m.metallic_factor, 1.0f);
    EXPECT_GE(m.roughness_factor, 0.0f);
    EXPECT_LE(m.roughness_factor, 1.0f);
    EXPECT_TRUE(drawn.count(i)) << m.name << " is not drawn";
    if (m.alpha_mode == AlphaMode::kMask) {
      ++mask;
      EXPECT_TRUE(m.double_sided);
      EXPECT_FLOAT_EQ(m.alpha_cutoff, 0.5f);
      // The cutout must actually cut: some texels below the cutoff, some above.
      ASSERT_GE(m.base_color.texture, 0);
      const Image& img = *s.textures[m.base_color.texture].image;
      int holes = 0, solid = 0;
      for (size_t p = 3; p < img.rgba8.size(); p += 4) (img.rgba8[p] < 128 ? holes : solid)++;
      EXPECT_GT(holes, 0);
      EXPECT_GT(solid, 0);
    }
    if (m.alpha_mode == AlphaMode::kBlend) {
      ++blend;
      EXPECT_LT(m.base_color_factor.a, 1.0f);
      EXPECT_GT(m.base_color_factor.a, 0.0f);
    }
  }
  EXPECT_GE(mask, 1);
  EXPECT_GE(blend, 1);
}

TEST_F(DemoScene, LightsAreValid) {
  const CpuScene& s = scene();
  ASSERT_GE(s.lights.size(), 3u);
  int directional = 0, point = 0;
  for (const Light& l : s.lights) {
    SCOPED_TRACE(l.name);
    EXPECT_GT(l.intensity, 0.0f);
    EXPECT_GE(l.range, 0.0f);
    EXPECT_NEAR(glm::length(l.direction), 1.0f, 1e-4f);
    EXPECT_TRUE(glm::all(glm::greaterThanEqual(l.color, glm::vec3(0.0f))));
    if (l.type == LightType::kDirectional) {
      ++directional;
      EXPECT_LT(l.direction.y, -0.5f) << "the sun should shine down";
    }
    if (l.type == LightType::kPoint) {
      ++point;
      EXPECT_GT(l.position.y, 0.5f);
      EXPECT_TRUE(Contains(s.bounds, glm::vec3(l.position.x, 0.0f, l.position.z)));
    }
    if (l.type == LightType::kSpot) {
      EXPECT_GE(l.inner_cone_angle, 0.0f);
      EXPECT_LT(l.inner_cone_angle, l.outer_cone_angle);
      EXPECT_LE(l.outer_cone_angle, 1.5707964f);
    }
  }
  EXPECT_GE(directional, 1);
  EXPECT_GE(point, 3);
}

TEST_F(DemoScene, CameraLooksAtTheObjects) {
  const CpuScene& s = scene();
  ASSERT_EQ(s.cameras.size(), 1u);
  const SceneCamera& cam = s.cameras[0];
  EXPECT_GT(cam.yfov, 0.2f);
  EXPECT_LT(cam.yfov, 2.0f);
  EXPECT_GT(cam.znear, 0.0f);
  EXPECT_TRUE(cam.zfar == 0.0f || cam.zfar > cam.znear);
  // A rigid transform (no scale), above the floor.
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(glm::length(glm::vec3(cam.world[c])), 1.0f, 1e-4f);
  const glm::vec3 eye(cam.world[3]);
  EXPECT_GT(eye.y, 0.5f);
  // Every object except the floor is in front of the camera and inside the vertical fov.
  const glm::mat4 view = glm::inverse(cam.world);
  for (size_t i = 1; i < s.drawables.size(); ++i) {
    const glm::vec3 c = glm::vec3(view * glm::vec4(s.drawables[i].world_bounds.center(), 1.0f));
    EXPECT_LT(c.z, -1.0f) << "drawable " << i;
    EXPECT_LT(std::abs(c.y / -c.z), std::tan(cam.yfov * 0.5f)) << "drawable " << i;
  }
}

TEST_F(DemoScene, IsDeterministic) {
  const CpuScene& a = scene();
  const CpuScene b = BuildDemoScene();
  ASSERT_EQ(a.vertices.size(), b.vertices.size());
  EXPECT_EQ(std::memcmp(a.vertices.data(), b.vertices.data(), a.vertices.size() * sizeof(Vertex)),
            0);
  EXPECT_EQ(a.indices, b.indices);
  ASSERT_EQ(a.textures.size(), b.textures.size());
  for (size_t t = 0; t < a.textures.size(); ++t) {
    EXPECT_EQ(a.textures[t].image->rgba8, b.textures[t].image->rgba8) << "texture " << t;
  }
  ASSERT_EQ(a.drawables.size(), b.drawables.size());
  for (size_t d = 0; d < a.drawables.size(); ++d) {
    EXPECT_EQ(std::memcmp(&a.drawables[d].world, &b.drawables[d].world, sizeof(glm::mat4)), 0);
  }
  EXPECT_EQ(a.materials.size(), b.materials.size());
  EXPECT_EQ(a.lights.size(), b.lights.size());
}

}  // namespace
}  // namespace tessera
