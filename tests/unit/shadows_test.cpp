// Shadow math on the CPU: the light basis, the sun's cascades (splits, bounding spheres, texel
// snapping while the camera moves and turns), spot and point-light views and their agreement with
// CubeFace, the choice of shadowed lights, the atlas transform, the atlas allocator with its
// cache and eviction, and the content hash. Pure math: nothing here touches Vulkan.
#include "renderer/shadows.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <glm/glm.hpp>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "renderer/camera.h"
#include "renderer/scene/cpu_scene.h"

namespace tessera {
namespace {

Aabb Box(const glm::vec3& min, const glm::vec3& max) {
  Aabb b;
  b.min = min;
  b.max = max;
  return b;
}

std::array<glm::vec3, 8> Corners(const Aabb& b) {
  std::array<glm::vec3, 8> out;
  for (int i = 0; i < 8; ++i) {
    out[i] = glm::vec3((i & 1) ? b.max.x : b.min.x, (i & 2) ? b.max.y : b.min.y,
                       (i & 4) ? b.max.z : b.min.z);
  }
  return out;
}

bool Inside(const Aabb& b, const glm::vec3& p) {
  return glm::all(glm::greaterThanEqual(p, b.min)) && glm::all(glm::lessThanEqual(p, b.max));
}

// NDC x, y and depth of a world point (after the divide by w).
glm::vec3 Ndc(const glm::mat4& m, const glm::vec3& p) {
  const glm::vec4 c = m * glm::vec4(p, 1.0f);
  return glm::vec3(c) / c.w;
}

// Twice the signed area of a triangle in NDC: its sign is the winding the rasterizer sees.
float SignedArea(const glm::mat4& m, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  const glm::vec2 pa(Ndc(m, a)), pb(Ndc(m, b)), pc(Ndc(m, c));
  const glm::vec2 u = pb - pa, v = pc - pa;
  return u.x * v.y - u.y * v.x;
}

// The main camera's view-projection for a camera at `eye` looking along `dir`.
glm::mat4 CameraViewProj(const glm::vec3& eye, const glm::vec3& dir, const glm::vec3& up) {
  Camera cam;
  cam.eye = eye;
  cam.target = eye + dir;
  cam.up = up;
  cam.znear = 0.01f;
  return ProjectionMatrix(cam, 1.0f) * ViewMatrix(cam);
}

// How far `x` is from the nearest integer, allowing for float rounding of large values.
bool NearInteger(double x) { return std::abs(x - std::round(x)) <= 1e-3 + 1e-6 * std::abs(x); }

// The eight corners of the camera's view slice between view distances a and b, rebuilt from the
// camera's eye/target/up independently of the code under test.
std::array<glm::vec3, 8> SliceCorners(const Camera& cam, float aspect, float a, float b) {
  const glm::vec3 f = glm::normalize(cam.target - cam.eye);
  const glm::vec3 r = glm::normalize(glm::cross(f, cam.up));
  const glm::vec3 u = glm::cross(r, f);
  const float ty = std::tan(cam.yfov * 0.5f), tx = ty * aspect;
  std::array<glm::vec3, 8> out;
  for (int i = 0; i < 8; ++i) {
    const float d = (i & 4) ? b : a;
    out[i] = cam.eye + f * d + r * (d * tx * ((i & 1) ? 1.0f : -1.0f)) +
             u * (d * ty * ((i & 2) ? 1.0f : -1.0f));
  }
  return out;
}

const glm::vec3 kSun = glm::normalize(glm::vec3(0.4f, -1.0f, 0.25f));
const Aabb kScene = Box({-50, -5, -50}, {50, 20, 50});

// The properties every cascade must have whatever the camera: the texel snapping, a map that
// holds the camera's slice with its filter border to spare, and a depth range over the scene.
void CheckCascades(const Camera& cam, float aspect, const std::vector<Cascade>& cascades,
                   uint32_t resolution, const std::string& what) {
  const glm::mat3 basis = LightBasis(kSun);
  for (size_t i = 0; i < cascades.size(); ++i) {
    const Cascade& c = cascades[i];
    const std::string tag = what + " cascade " + std::to_string(i);
    ASSERT_GT(c.texel_world, 0.0f) << tag;
    EXPECT_TRUE(NearInteger(double(c.light_origin.x) / c.texel_world)) << tag;
    EXPECT_TRUE(NearInteger(double(c.light_origin.y) / c.texel_world)) << tag;
    // The centre is the snapped origin in the light's basis.
    const glm::vec3 lc = basis * c.center;
    EXPECT_NEAR(lc.x, c.light_origin.x, 1e-4f * (1.0f + std::abs(lc.x))) << tag;
    EXPECT_NEAR(lc.y, c.light_origin.y, 1e-4f * (1.0f + std::abs(lc.y))) << tag;
    // The centre maps to the middle of the face.
    const glm::vec3 mid = Ndc(c.view_proj, c.center);
    EXPECT_NEAR(mid.x, 0.0f, 1e-4f) << tag;
    EXPECT_NEAR(mid.y, 0.0f, 1e-4f) << tag;
    // The texel size is the face's world size over its resolution.
    const float half = c.radius + float(kShadowBorderTexels) * c.texel_world;
    EXPECT_NEAR(2.0f * half / c.texel_world, float(resolution), 1e-2f) << tag;

    for (const glm::vec3& p : SliceCorners(cam, aspect, c.split_near, c.split_far)) {
      // Snapping moves the centre by at most half a texel on each axis.
      EXPECT_LE(glm::length(p - c.center), c.radius + c.texel_world) << tag;
      const glm::vec3 ndc = Ndc(c.view_proj, p);
      // Inside the face with at least 1.5 texels of border left for the filter.
      const float limit = 1.0f - 1.4f * c.texel_world / half;
      EXPECT_LE(std::abs(ndc.x), limit) << tag;
      EXPECT_LE(std::abs(ndc.y), limit) << tag;
      if (Inside(kScene, p)) {
        EXPECT_GE(ndc.z, 0.0f) << tag;
        EXPECT_LE(ndc.z, 1.0f) << tag;
      }
    }
    // Every caster of the scene is within the depth range, strictly (the range is padded).
    for (const glm::vec3& p : Corners(kScene)) {
      const float z = Ndc(c.view_proj, p).z;
      EXPECT_GT(z, 0.0f) << tag;
      EXPECT_LT(z, 1.0f) << tag;
    }
  }
}

TEST(LightBasisTest, OrthonormalRightHandedRowsWithDirectionLast) {
  const std::vector<glm::vec3> dirs = {{0, 0, -1}, {0, -1, 0},        {0, 1, 0},  {0.001f, -1, 0},
                                       {1, 0, 0},  {0.4f, -1, 0.25f}, {-3, 2, 7}, {0, -1, 0.2f}};
  for (const glm::vec3& d : dirs) {
    const glm::mat3 b = LightBasis(d);
    const glm::mat3 rows = glm::transpose(b);  // columns of `rows` are the rows of b
    const glm::vec3 x = rows[0], y = rows[1], z = rows[2];
    EXPECT_NEAR(glm::length(x), 1.0f, 1e-5f);
    EXPECT_NEAR(glm::length(y), 1.0f, 1e-5f);
    EXPECT_NEAR(glm::dot(x, y), 0.0f, 1e-5f);
    EXPECT_NEAR(glm::dot(x, z), 0.0f, 1e-5f);
    EXPECT_NEAR(glm::dot(y, z), 0.0f, 1e-5f);
    EXPECT_NEAR(glm::distance(z, glm::normalize(d)), 0.0f, 1e-5f);
    EXPECT_NEAR(glm::determinant(b), 1.0f, 1e-5f);
    // b * v gives the light-space coordinates.
    EXPECT_NEAR((b * glm::normalize(d)).z, 1.0f, 1e-5f);
    EXPECT_NEAR((b * x).x, 1.0f, 1e-5f);
    // The direction alone decides: its length does not matter.
    const glm::mat3 scaled = LightBasis(d * 7.5f);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(glm::distance(scaled[c], b[c]), 0.0f, 1e-6f);
  }
}

TEST(CascadeTest, SplitsIncreaseFromNearToShadowDistance) {
  Camera cam;
  cam.znear = 0.1f;
  for (float lambda : {0.0f, 0.5f, 0.75f, 1.0f}) {
    for (uint32_t count = 1; count <= kMaxCascades; ++count) {
      CascadeParams params;
      params.count = count;
      params.split_lambda = lambda;
      const auto cs = ComputeCascades(cam, 1.5f, kSun, kScene, 80.0f, params);
      ASSERT_EQ(cs.size(), count);
      EXPECT_FLOAT_EQ(cs.front().split_near, 0.1f);
      EXPECT_FLOAT_EQ(cs.back().split_far, 80.0f);
      for (uint32_t i = 0; i < count; ++i) {
        EXPECT_LT(cs[i].split_near, cs[i].split_far);
        if (i > 0) {
          EXPECT_EQ(cs[i].split_near, cs[i - 1].split_far);
        }
        // The practical split formula.
        const float s = float(i + 1) / float(count);
        const float expected =
            lambda * 0.1f * std::pow(800.0f, s) + (1.0f - lambda) * (0.1f + (80.0f - 0.1f) * s);
        EXPECT_NEAR(cs[i].split_far, expected, 1e-4f * expected) << lambda << " " << i;
      }
    }
  }
  // The count is clamped to 1..kMaxCascades; a shadow distance before the near plane still
  // gives a valid, non-empty slice.
  CascadeParams params;
  params.count = 0;
  EXPECT_EQ(ComputeCascades(cam, 1.0f, kSun, kScene, 80.0f, params).size(), 1u);
  params.count = 9;
  EXPECT_EQ(ComputeCascades(cam, 1.0f, kSun, kScene, 80.0f, params).size(), kMaxCascades);
  params.count = 2;
  const auto tiny = ComputeCascades(cam, 1.0f, kSun, kScene, 0.01f, params);
  ASSERT_EQ(tiny.size(), 2u);
  EXPECT_GT(tiny.back().split_far, cam.znear);
  EXPECT_GT(tiny.front().radius, 0.0f);
}

TEST(CascadeTest, SnapsToWholeTexelsWhileTheCameraMoves) {
  CascadeParams params;
  params.resolution = 1024;
  const float aspect = 16.0f / 9.0f;
  Camera cam;
  cam.yfov = 0.9f;
  cam.znear = 0.1f;
  const glm::vec3 look(1.0f, -0.2f, 0.3f);
  // A probe fixed in the world: where it falls inside a texel must not change as the camera
  // moves, only which texel (the map slides by whole texels, so edges do not shimmer).
  const glm::vec3 probe(1.3f, 0.7f, -2.1f);
  std::vector<Cascade> first, prev;
  std::vector<glm::vec2> probe_frac;
  for (int frame = 0; frame < 150; ++frame) {
    // Steps that are not multiples of any texel size.
    cam.eye = glm::vec3(-5.0f, 3.0f, -4.0f) + float(frame) * glm::vec3(0.0731f, 0.0123f, 0.0517f);
    cam.target = cam.eye + look;
    const auto cs = ComputeCascades(cam, aspect, kSun, kScene, 80.0f, params);
    ASSERT_EQ(cs.size(), 4u);
    CheckCascades(cam, aspect, cs, params.resolution, "frame " + std::to_string(frame));
    if (frame == 0) first = cs;
    for (size_t i = 0; i < cs.size(); ++i) {
      // Moving does not change the size of the map.
      EXPECT_EQ(cs[i].radius, first[i].radius);
      EXPECT_EQ(cs[i].texel_world, first[i].texel_world);
      EXPECT_EQ(cs[i].split_near, first[i].split_near);
      if (frame > 0) {
        EXPECT_TRUE(NearInteger((double(cs[i].light_origin.x) - prev[i].light_origin.x) /
                                cs[i].texel_world));
        EXPECT_TRUE(NearInteger((double(cs[i].light_origin.y) - prev[i].light_origin.y) /
                                cs[i].texel_world));
      }
      const glm::vec3 ndc = Ndc(cs[i].view_proj, probe);
      const glm::vec2 texel = (glm::vec2(ndc) * 0.5f + 0.5f) * float(params.resolution);
      const glm::vec2 frac = texel - glm::floor(texel);
      if (frame == 0) {
        probe_frac.push_back(frac);
      } else {
        // Compared on the circle: 0.999 and 0.001 are neighbours.
        for (int k = 0; k < 2; ++k) {
          const float d = std::abs(frac[k] - probe_frac[i][k]);
          EXPECT_LT(std::min(d, 1.0f - d), 0.02f) << "frame " << frame << " cascade " << i;
        }
      }
    }
    prev = cs;
  }
  // The path is long enough that every cascade actually moved.
  for (size_t i = 0; i < first.size(); ++i)
    EXPECT_NE(prev[i].light_origin, first[i].light_origin) << i;
}

TEST(CascadeTest, SizeDoesNotChangeAsTheCameraTurns) {
  CascadeParams params;
  params.resolution = 2048;
  params.count = 3;
  const float aspect = 1.6f;
  Camera cam;
  cam.yfov = 1.1f;
  cam.znear = 0.25f;
  cam.eye = glm::vec3(3.0f, 2.0f, 1.0f);
  std::vector<Cascade> first;
  for (int step = 0; step < 97; ++step) {
    const float yaw = 0.0713f * float(step), pitch = 0.6f * std::sin(0.31f * float(step));
    const glm::vec3 dir(std::cos(pitch) * std::cos(yaw), std::sin(pitch),
                        std::cos(pitch) * std::sin(yaw));
    cam.target = cam.eye + dir;
    const auto cs = ComputeCascades(cam, aspect, kSun, kScene, 60.0f, params);
    ASSERT_EQ(cs.size(), 3u);
    CheckCascades(cam, aspect, cs, params.resolution, "step " + std::to_string(step));
    if (step == 0) first = cs;
    for (size_t i = 0; i < cs.size(); ++i) {
      EXPECT_EQ(cs[i].radius, first[i].radius) << step;
      EXPECT_EQ(cs[i].texel_world, first[i].texel_world) << step;
    }
  }
  // The same camera given by an explicit view matrix (rotated about its eye) agrees.
  Camera by_view = cam;
  by_view.view = ViewMatrix(cam);
  const auto cs = ComputeCascades(by_view, aspect, kSun, kScene, 60.0f, params);
  for (size_t i = 0; i < cs.size(); ++i) {
    EXPECT_NEAR(cs[i].radius, first[i].radius, 1e-5f * first[i].radius);
    EXPECT_NEAR(cs[i].texel_world, first[i].texel_world, 1e-5f * first[i].texel_world);
  }
}

TEST(CascadeTest, FaceIsOrientedLikeACameraLookingAlongTheLight) {
  Camera cam;
  cam.znear = 0.1f;
  CascadeParams params;
  params.count = 1;
  const auto cs = ComputeCascades(cam, 1.0f, kSun, kScene, 30.0f, params);
  ASSERT_EQ(cs.size(), 1u);
  const Cascade& c = cs[0];
  const float half = c.radius + float(kShadowBorderTexels) * c.texel_world;
  // Right and up of a camera looking along the sun with world up: right is +x of the face, up
  // is its top row (NDC y -1), as the viewport puts it.
  const glm::vec3 right = glm::normalize(glm::cross(kSun, glm::vec3(0, 1, 0)));
  const glm::vec3 up = glm::cross(right, kSun);
  const glm::vec3 r = Ndc(c.view_proj, c.center + right * c.radius);
  EXPECT_NEAR(r.x, c.radius / half, 1e-4f);
  EXPECT_NEAR(r.y, 0.0f, 1e-4f);
  const glm::vec3 u = Ndc(c.view_proj, c.center + up * c.radius);
  EXPECT_NEAR(u.x, 0.0f, 1e-4f);
  EXPECT_NEAR(u.y, -c.radius / half, 1e-4f);
  // Depth grows along the light.
  EXPECT_LT(Ndc(c.view_proj, c.center).z, Ndc(c.view_proj, c.center + kSun).z);
  // Triangles keep the winding they have for such a camera.
  const glm::vec3 a = c.center, b = c.center + right, d = c.center + up * 0.5f + right * 0.2f;
  const glm::mat4 camera = CameraViewProj(c.center - kSun * 50.0f, kSun, glm::vec3(0, 1, 0));
  EXPECT_GT(SignedArea(c.view_proj, a, b, d) * SignedArea(camera, a, b, d), 0.0f);
}

TEST(ShadowPlanesTest, NearAndFar) {
  Light l;
  l.range = 10.0f;
  EXPECT_FLOAT_EQ(ShadowNear(l), 0.02f);
  EXPECT_FLOAT_EQ(ShadowFar(l, kScene), 10.0f);
  l.range = 0.1f;
  EXPECT_FLOAT_EQ(ShadowNear(l), 1e-3f);
  l.range = 0.0f;  // unbounded: the farthest corner of the scene
  l.position = glm::vec3(50, 20, 50);
  EXPECT_FLOAT_EQ(ShadowNear(l), 0.01f);
  EXPECT_NEAR(ShadowFar(l, kScene), glm::length(glm::vec3(100, 25, 100)), 1e-3f);
  EXPECT_FLOAT_EQ(ShadowFar(l, Aabb{}), 0.02f);  // no scene: still after the near plane
}

TEST(CubeFaceTest, AxesAndTies) {
  EXPECT_EQ(CubeFace({1, 0, 0}), 0u);
  EXPECT_EQ(CubeFace({-1, 0, 0}), 1u);
  EXPECT_EQ(CubeFace({0, 1, 0}), 2u);
  EXPECT_EQ(CubeFace({0, -1, 0}), 3u);
  EXPECT_EQ(CubeFace({0, 0, 1}), 4u);
  EXPECT_EQ(CubeFace({0, 0, -1}), 5u);
  // Ties go to the earlier axis, positive before negative.
  EXPECT_EQ(CubeFace({1, 1, 1}), 0u);
  EXPECT_EQ(CubeFace({-1, 1, -1}), 1u);
  EXPECT_EQ(CubeFace({0.5f, -2, 2}), 3u);
  EXPECT_EQ(CubeFace({0, 2, -2}), 2u);
  EXPECT_EQ(CubeFace({0, 0.1f, -0.2f}), 5u);
  EXPECT_EQ(CubeFace({0, 0, 0}), 0u);
}

TEST(PointFaceTest, EachFaceCoversExactlyTheDirectionsCubeFaceGivesIt) {
  Light l;
  l.position = glm::vec3(1, 2, 3);
  l.range = 10.0f;
  const uint32_t res = 256;
  const float t = float(res) / float(res - 2 * kShadowBorderTexels);
  const float n = ShadowNear(l), f = ShadowFar(l, kScene);
  std::array<glm::mat4, kCubeFaces> faces;
  for (uint32_t i = 0; i < kCubeFaces; ++i) faces[i] = PointFaceViewProj(l, i, res, kScene);
  std::mt19937 rng(7);
  std::normal_distribution<float> gauss;
  std::uniform_real_distribution<float> dist(n * 1.01f, f * 0.99f);
  for (int k = 0; k < 3000; ++k) {
    glm::vec3 d(gauss(rng), gauss(rng), gauss(rng));
    if (k % 5 == 0) d.y = d.x;  // exact ties between axes
    if (k % 7 == 0) d.z = -d.y;
    if (glm::length(d) < 1e-3f) continue;
    d = glm::normalize(d);
    const uint32_t face = CubeFace(d);
    const float axis = glm::abs(d)[face / 2];
    const glm::vec3 p = l.position + d * (dist(rng) / axis);
    const glm::vec4 c = faces[face] * glm::vec4(p, 1.0f);
    ASSERT_GT(c.w, 0.0f);
    const glm::vec3 ndc = glm::vec3(c) / c.w;
    EXPECT_LE(std::abs(ndc.x), 1.0f / t + 1e-5f) << k;
    EXPECT_LE(std::abs(ndc.y), 1.0f / t + 1e-5f) << k;
    EXPECT_GT(ndc.z, 0.0f) << k;
    EXPECT_LT(ndc.z, 1.0f) << k;
    // No other face's 90-degree square holds it (at most on its edge).
    for (uint32_t o = 0; o < kCubeFaces; ++o) {
      if (o == face) continue;
      const glm::vec4 co = faces[o] * glm::vec4(p, 1.0f);
      if (co.w <= 0.0f) continue;
      EXPECT_GE(std::max(std::abs(co.x), std::abs(co.y)) / co.w, 1.0f / t - 1e-5f)
          << k << " face " << face << " other " << o;
    }
  }
}

TEST(PointFaceTest, AxisPointAtCentreDepthMonotonicWindingKept) {
  Light l;
  l.position = glm::vec3(-2, 0.5f, 4);
  l.range = 12.0f;
  const float n = ShadowNear(l), f = ShadowFar(l, kScene);
  const std::array<glm::vec3, kCubeFaces> axes = {glm::vec3(1, 0, 0), glm::vec3(-1, 0, 0),
                                                  glm::vec3(0, 1, 0), glm::vec3(0, -1, 0),
                                                  glm::vec3(0, 0, 1), glm::vec3(0, 0, -1)};
  for (uint32_t face = 0; face < kCubeFaces; ++face) {
    const glm::mat4 m = PointFaceViewProj(l, face, 512, kScene);
    const glm::vec3 axis = axes[face];
    const glm::vec3 centre = Ndc(m, l.position + axis * 5.0f);
    EXPECT_NEAR(centre.x, 0.0f, 1e-5f) << face;
    EXPECT_NEAR(centre.y, 0.0f, 1e-5f) << face;
    EXPECT_NEAR(Ndc(m, l.position + axis * n).z, 0.0f, 1e-4f) << face;
    EXPECT_NEAR(Ndc(m, l.position + axis * f).z, 1.0f, 1e-4f) << face;
    // Depth depends on the distance along the axis only, and grows with it.
    const glm::vec3 side = face < 2 ? glm::vec3(0, 0.3f, -0.2f) : glm::vec3(0.3f, 0, 0);
    float last = -1.0f;
    for (float s = n * 1.5f; s < f; s *= 1.3f) {
      const float z = Ndc(m, l.position + axis * s).z;
      EXPECT_GT(z, last) << face << " " << s;
      EXPECT_NEAR(Ndc(m, l.position + axis * s + side * s).z, z, 1e-5f) << face;
      last = z;
    }
    // The same winding as a camera at the light looking down the axis.
    const glm::vec3 up = face == 2 || face == 3 ? glm::vec3(0, 0, 1) : glm::vec3(0, 1, 0);
    const glm::mat4 camera = CameraViewProj(l.position, axis, up);
    const glm::vec3 a = l.position + axis * 3.0f;
    const glm::vec3 b = a + glm::cross(axis, up) * 0.5f, c = a + up * 0.4f;
    EXPECT_GT(SignedArea(m, a, b, c) * SignedArea(camera, a, b, c), 0.0f) << face;
  }
}

TEST(SpotTest, AxisAtCentreConeEdgeAtTheBorder) {
  Light l;
  l.type = LightType::kSpot;
  l.position = glm::vec3(0, 5, 0);
  l.direction = glm::normalize(glm::vec3(0.2f, -1.0f, 0.1f));
  l.outer_cone_angle = 0.6f;
  l.inner_cone_angle = 0.4f;
  l.range = 20.0f;
  const uint32_t res = 512;
  const glm::mat4 m = SpotViewProj(l, res, kScene);
  const glm::vec3 centre = Ndc(m, l.position + l.direction * 7.0f);
  EXPECT_NEAR(centre.x, 0.0f, 1e-5f);
  EXPECT_NEAR(centre.y, 0.0f, 1e-5f);
  EXPECT_NEAR(Ndc(m, l.position + l.direction * ShadowNear(l)).z, 0.0f, 1e-4f);
  EXPECT_NEAR(Ndc(m, l.position + l.direction * 20.0f).z, 1.0f, 1e-4f);
  // The outer cone's edge is a circle touching the inner (res - 2 * border) square: inside the
  // face, the border texels outside it.
  const float inner = float(res - 2 * kShadowBorderTexels) / float(res);
  const glm::mat3 rows = glm::transpose(LightBasis(l.direction));
  for (int k = 0; k < 16; ++k) {
    const float phi = 6.2831853f * float(k) / 16.0f;
    const glm::vec3 side = std::cos(phi) * rows[0] + std::sin(phi) * rows[1];
    const glm::vec3 edge =
        std::cos(l.outer_cone_angle) * l.direction + std::sin(l.outer_cone_angle) * side;
    const glm::vec3 ndc = Ndc(m, l.position + edge * 9.0f);
    EXPECT_NEAR(glm::length(glm::vec2(ndc)), inner, 1e-4f) << k;
    EXPECT_LT(std::max(std::abs(ndc.x), std::abs(ndc.y)), inner + 1e-4f) << k;
    if (k % 4 == 0) {
      EXPECT_NEAR(std::max(std::abs(ndc.x), std::abs(ndc.y)), inner, 1e-4f);
    }
    EXPECT_GT(ndc.z, 0.0f);
    EXPECT_LT(ndc.z, 1.0f);
  }
}

TEST(SpotTest, OrientedLikeACameraAndWideConesClamped) {
  Light l;
  l.type = LightType::kSpot;
  l.position = glm::vec3(1, 2, 3);
  l.direction = glm::vec3(0, 0, -1);
  l.range = 10.0f;
  // A spot pointing down -Z with world up is the default camera: +X to the right, +Y at the
  // top row (NDC y < 0).
  const glm::mat4 m = SpotViewProj(l, 256, kScene);
  const glm::vec3 ahead = l.position + glm::vec3(0, 0, -4);
  EXPECT_GT(Ndc(m, ahead + glm::vec3(1, 0, 0)).x, 0.1f);
  EXPECT_LT(Ndc(m, ahead + glm::vec3(0, 1, 0)).y, -0.1f);
  const glm::mat4 camera = CameraViewProj(l.position, l.direction, glm::vec3(0, 1, 0));
  EXPECT_GT(Ndc(camera, ahead + glm::vec3(1, 0, 0)).x, 0.1f);
  EXPECT_LT(Ndc(camera, ahead + glm::vec3(0, 1, 0)).y, -0.1f);
  // Winding for any direction.
  for (const glm::vec3& dir :
       {glm::vec3(0.3f, -1, 0.2f), glm::vec3(0, -1, 0), glm::vec3(1, 0.1f, 0)}) {
    l.direction = glm::normalize(dir);
    const glm::mat4 s = SpotViewProj(l, 256, kScene);
    const glm::vec3 up = std::abs(l.direction.y) > 0.9f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0);
    const glm::mat4 c = CameraViewProj(l.position, l.direction, up);
    const glm::vec3 a = l.position + l.direction * 3.0f;
    const glm::vec3 b = a + glm::normalize(glm::cross(l.direction, up)) * 0.3f;
    const glm::vec3 d = a + up * 0.3f;
    EXPECT_GT(SignedArea(s, a, b, d) * SignedArea(c, a, b, d), 0.0f);
  }
  // A cone wider than a hemisphere still gives a finite matrix; an unbounded spot reaches the
  // farthest corner of the scene.
  l.outer_cone_angle = 1.7f;
  l.range = 0.0f;
  const glm::mat4 wide = SpotViewProj(l, 256, kScene);
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) EXPECT_TRUE(std::isfinite(wide[c][r]));
  EXPECT_NEAR(Ndc(wide, l.position + l.direction * ShadowFar(l, kScene)).z, 1.0f, 1e-4f);
}

TEST(ChooseShadowedLightsTest, FiltersAndOrdersByImportance) {
  Camera cam;
  cam.eye = glm::vec3(0.0f);
  cam.target = glm::vec3(0, 0, -1);
  cam.yfov = 0.8f;
  cam.zfar = 100.0f;
  const Frustum frustum = FrustumFromViewProj(ProjectionMatrix(cam, 1.0f) * ViewMatrix(cam));
  auto point = [](glm::vec3 p, float range, float intensity) {
    Light l;
    l.type = LightType::kPoint;
    l.position = p;
    l.range = range;
    l.intensity = intensity;
    return l;
  };
  std::vector<Light> lights;
  Light sun = point({0, 0, -5}, 0.0f, 100.0f);
  sun.type = LightType::kDirectional;
  lights.push_back(sun);                               // 0: directional
  lights.push_back(point({0, 0, -5}, 0.0f, 100.0f));   // 1: unbounded point
  lights.push_back(point({0, 0, -10}, 2.0f, 1.0f));    // 2: 4 / 64
  lights.push_back(point({0, 0, 20}, 2.0f, 1000.0f));  // 3: behind the camera
  Light spot = point({0, 0, -5}, 3.0f, 1.0f);          // 4: 9 / 4
  spot.type = LightType::kSpot;
  lights.push_back(spot);
  lights.push_back(point({0, 0, -10}, 2.0f, 1.0f));      // 5: ties with 2
  lights.push_back(point({30, 0, -10}, 2.0f, 1000.0f));  // 6: far right of the frustum
  lights.push_back(point({5, 0, -10}, 2.0f, 1.0f));      // 7: outside, sphere reaches in
  lights.push_back(point({0, 0, 0.5f}, 1.0f, 0.5f));     // 8: around the camera: 0.5 / 0.01
  lights.push_back(point({0, 0, -150}, 5.0f, 1000.0f));  // 9: beyond the far plane

  const std::vector<uint32_t> all = ChooseShadowedLights(lights, frustum, cam.eye, 100);
  EXPECT_EQ(all, (std::vector<uint32_t>{8, 4, 2, 5, 7}));
  EXPECT_EQ(ChooseShadowedLights(lights, frustum, cam.eye, 3), (std::vector<uint32_t>{8, 4, 2}));
  EXPECT_TRUE(ChooseShadowedLights(lights, frustum, cam.eye, 0).empty());
  EXPECT_EQ(ChooseShadowedLights(lights, frustum, cam.eye, 100), all);  // deterministic
  // Brighter wins at the same place; closer wins at the same brightness.
  lights[5].intensity = 2.0f;
  EXPECT_EQ(ChooseShadowedLights(lights, frustum, cam.eye, 100),
            (std::vector<uint32_t>{8, 4, 5, 2, 7}));
  lights[7].position = glm::vec3(0, 0, -3.0f);  // 4 / 1: ahead of the spot's 9 / 4
  EXPECT_EQ(ChooseShadowedLights(lights, frustum, cam.eye, 2), (std::vector<uint32_t>{8, 7}));
  EXPECT_TRUE(ChooseShadowedLights({}, frustum, cam.eye, 4).empty());
}

TEST(AtlasTransformTest, NdcCornersMapToTheRectCorners) {
  const AtlasRect rect{256, 512, 128};
  const glm::mat4 a = AtlasTransform(rect, 1024);
  struct Case {
    glm::vec2 ndc, uv;
  };
  const std::vector<Case> cases = {
      {{-1, -1}, {256, 512}},  // top left: the face's first texel row
      {{1, -1}, {384, 512}},  {{-1, 1}, {256, 640}}, {{1, 1}, {384, 640}}, {{0, 0}, {320, 576}},
  };
  for (const Case& c : cases) {
    for (float w : {1.0f, 3.5f}) {  // perspective views have w != 1
      const glm::vec4 clip(c.ndc * w, 0.25f * w, w);
      const glm::vec4 out = a * clip;
      EXPECT_NEAR(out.x / out.w, c.uv.x / 1024.0f, 1e-6f);
      EXPECT_NEAR(out.y / out.w, c.uv.y / 1024.0f, 1e-6f);
      EXPECT_NEAR(out.z / out.w, 0.25f, 1e-6f);
      EXPECT_EQ(out.w, w);
    }
  }
  // world_to_atlas of a spot: its axis lands on the centre of its rect.
  Light l;
  l.type = LightType::kSpot;
  l.range = 5.0f;
  const glm::mat4 world_to_atlas = a * SpotViewProj(l, rect.size, kScene);
  const glm::vec3 uv = Ndc(world_to_atlas, l.position + l.direction * 2.0f);
  EXPECT_NEAR(uv.x, 320.0f / 1024.0f, 1e-6f);
  EXPECT_NEAR(uv.y, 576.0f / 1024.0f, 1e-6f);
}

bool Overlap(const AtlasRect& a, const AtlasRect& b) {
  return a.x < b.x + b.size && b.x < a.x + a.size && a.y < b.y + b.size && b.y < a.y + a.size;
}

bool Same(const AtlasRect& a, const AtlasRect& b) {
  return a.x == b.x && a.y == b.y && a.size == b.size;
}

TEST(ShadowAtlasTest, CachedWhenTheContentIsUnchanged) {
  ShadowAtlas atlas(1024, 64);
  atlas.BeginFrame();
  const auto a = atlas.Acquire(1, 256, 111);
  ASSERT_TRUE(a);
  EXPECT_FALSE(a->cached);
  EXPECT_EQ(a->rect.size, 256u);
  atlas.BeginFrame();
  const auto b = atlas.Acquire(1, 256, 111);
  ASSERT_TRUE(b);
  EXPECT_TRUE(b->cached);
  EXPECT_TRUE(Same(a->rect, b->rect));
  // Changed content: rendered again, in the same place.
  atlas.BeginFrame();
  const auto c = atlas.Acquire(1, 256, 222);
  ASSERT_TRUE(c);
  EXPECT_FALSE(c->cached);
  EXPECT_TRUE(Same(a->rect, c->rect));
  const auto again = atlas.Acquire(1, 256, 222);
  ASSERT_TRUE(again);
  EXPECT_TRUE(again->cached);
  // Another size: placed again, not cached.
  atlas.BeginFrame();
  const auto d = atlas.Acquire(1, 512, 222);
  ASSERT_TRUE(d);
  EXPECT_FALSE(d->cached);
  EXPECT_EQ(d->rect.size, 512u);
  EXPECT_EQ(atlas.faces(), 1u);
  EXPECT_EQ(atlas.texels_used(), 512u * 512u);
  // Sizes round up to a power of two within [min_face, atlas size].
  EXPECT_EQ(atlas.Acquire(2, 200, 5)->rect.size, 256u);
  EXPECT_EQ(atlas.Acquire(3, 10, 5)->rect.size, 64u);
  EXPECT_EQ(atlas.faces(), 3u);
  EXPECT_EQ(atlas.texels_used(), 512u * 512u + 256u * 256u + 64u * 64u);
  EXPECT_FALSE(atlas.Acquire(4, 5000, 5));  // the whole atlas: this frame's faces are in it
  EXPECT_EQ(atlas.evictions(), 0u);
}

TEST(ShadowAtlasTest, FacesNeverOverlapAndCachedFacesWereNotOverwritten) {
  ShadowAtlas atlas(2048, 32);
  std::mt19937 rng(42);
  std::uniform_int_distribution<uint32_t> key_dist(0, 60), size_dist(1, 700), content_dist(0, 3);
  // Every rendering (non-cached placement) so far: a cached face must not have been drawn over
  // since its own rendering.
  struct Render {
    uint64_t key;
    AtlasRect rect;
  };
  std::vector<Render> renders;
  std::map<uint64_t, size_t> last_render;  // key -> index in `renders`
  uint32_t cached = 0, failed = 0;
  for (int frame = 0; frame < 60; ++frame) {
    atlas.BeginFrame();
    std::map<uint64_t, AtlasRect> this_frame;
    for (int k = 0; k < 25; ++k) {
      const uint64_t key = key_dist(rng);
      const uint32_t size = size_dist(rng);
      const auto p = atlas.Acquire(key, size, content_dist(rng));
      if (!p) {  // a face that was held at another size is gone too
        ++failed;
        this_frame.erase(key);
        continue;
      }
      const AtlasRect& r = p->rect;
      ASSERT_GE(r.size, std::max(32u, std::min(size, 2048u)));
      ASSERT_EQ(r.size & (r.size - 1), 0u);
      ASSERT_EQ(r.x % r.size, 0u);
      ASSERT_EQ(r.y % r.size, 0u);
      ASSERT_LE(r.x + r.size, 2048u);
      ASSERT_LE(r.y + r.size, 2048u);
      if (p->cached) {
        ++cached;
        ASSERT_TRUE(last_render.count(key));
        EXPECT_TRUE(Same(renders[last_render[key]].rect, r));
        for (size_t i = last_render[key] + 1; i < renders.size(); ++i)
          EXPECT_FALSE(Overlap(renders[i].rect, r))
              << "frame " << frame << ": cached key " << key << " drawn over by " << renders[i].key;
      } else {
        last_render[key] = renders.size();
        renders.push_back({key, r});
      }
      this_frame[key] = r;
    }
    // The faces of a frame are all in the atlas at once: no two may overlap.
    for (auto i = this_frame.begin(); i != this_frame.end(); ++i)
      for (auto j = std::next(i); j != this_frame.end(); ++j)
        EXPECT_FALSE(Overlap(i->second, j->second)) << "frame " << frame;
    EXPECT_LE(atlas.texels_used(), 2048ull * 2048ull);
  }
  // The run exercised every path.
  EXPECT_GT(cached, 0u);
  EXPECT_GT(atlas.evictions(), 0u);
  EXPECT_GT(failed, 0u);
}

TEST(ShadowAtlasTest, EvictsTheLeastRecentlyUsedFaceOfAnEarlierFrame) {
  ShadowAtlas atlas(256, 64);  // 16 faces of 64
  atlas.BeginFrame();          // frame 1: fill it
  std::map<uint64_t, AtlasRect> rects;
  for (uint64_t k = 0; k < 16; ++k) {
    const auto p = atlas.Acquire(k, 64, k);
    ASSERT_TRUE(p);
    rects[k] = p->rect;
  }
  EXPECT_EQ(atlas.texels_used(), 256u * 256u);
  atlas.BeginFrame();  // frame 2 uses 8..15
  for (uint64_t k = 8; k < 16; ++k) EXPECT_TRUE(atlas.Acquire(k, 64, k)->cached);
  atlas.BeginFrame();  // frame 3 uses 0..3, then needs room: 4..7 are the oldest, 4 first
  for (uint64_t k = 0; k < 4; ++k) EXPECT_TRUE(atlas.Acquire(k, 64, k)->cached);
  const auto added = atlas.Acquire(100, 64, 1);
  ASSERT_TRUE(added);
  EXPECT_FALSE(added->cached);
  EXPECT_TRUE(Same(added->rect, rects[4]));
  EXPECT_EQ(atlas.evictions(), 1u);
  EXPECT_EQ(atlas.faces(), 16u);
  // This frame's faces are untouched.
  for (uint64_t k = 0; k < 4; ++k) {
    const auto p = atlas.Acquire(k, 64, k);
    EXPECT_TRUE(p->cached);
    EXPECT_TRUE(Same(p->rect, rects[k]));
  }
  atlas.BeginFrame();  // frame 4: 5..7 survived; 4 did not
  for (uint64_t k = 5; k < 8; ++k) {
    const auto p = atlas.Acquire(k, 64, k);
    EXPECT_TRUE(p->cached) << k;
    EXPECT_TRUE(Same(p->rect, rects[k])) << k;
  }
  const auto back = atlas.Acquire(4, 64, 4);
  ASSERT_TRUE(back);
  EXPECT_FALSE(back->cached);
  // It took the place of the oldest face left (frame 2: the lowest key, 8).
  EXPECT_TRUE(Same(back->rect, rects[8]));
  EXPECT_EQ(atlas.evictions(), 2u);
}

TEST(ShadowAtlasTest, FailsWhenTheFrameAloneFillsTheAtlas) {
  ShadowAtlas atlas(256, 64);
  atlas.BeginFrame();
  std::map<uint64_t, AtlasRect> rects;
  for (uint64_t k = 0; k < 16; ++k) rects[k] = atlas.Acquire(k, 64, k)->rect;
  EXPECT_FALSE(atlas.Acquire(99, 64, 0));
  EXPECT_FALSE(atlas.Acquire(99, 256, 0));
  EXPECT_EQ(atlas.faces(), 16u);
  EXPECT_EQ(atlas.evictions(), 0u);

  // Next frame, one face of each 128 quadrant is used again: no 128 block can be freed, so a
  // 128 face fails without evicting anything; a 64 face evicts one.
  atlas.BeginFrame();
  std::set<std::pair<uint32_t, uint32_t>> quadrants;
  for (uint64_t k = 0; k < 16; ++k) {
    const auto q = std::make_pair(rects[k].x / 128, rects[k].y / 128);
    if (quadrants.insert(q).second) {
      EXPECT_TRUE(atlas.Acquire(k, 64, k)->cached);
    }
  }
  ASSERT_EQ(quadrants.size(), 4u);
  EXPECT_FALSE(atlas.Acquire(99, 128, 0));
  EXPECT_EQ(atlas.evictions(), 0u);
  EXPECT_EQ(atlas.faces(), 16u);
  EXPECT_TRUE(atlas.Acquire(99, 64, 0));
  EXPECT_EQ(atlas.evictions(), 1u);
}

TEST(ShadowAtlasTest, BuddiesMergeSoTheWholeAtlasFitsAgain) {
  ShadowAtlas atlas(512, 64);
  atlas.BeginFrame();
  // Mixed sizes in an order that interleaves the levels, then 64s until the atlas is full.
  uint64_t key = 0;
  uint64_t texels = 0;
  for (uint32_t size : {64u, 256u, 128u, 64u, 64u, 128u, 64u}) {
    ASSERT_TRUE(atlas.Acquire(key++, size, 0));
    texels += uint64_t(size) * size;
  }
  while (texels < 512u * 512u) {
    ASSERT_TRUE(atlas.Acquire(key++, 64, 0));
    texels += 64 * 64;
  }
  EXPECT_EQ(atlas.texels_used(), 512u * 512u);
  EXPECT_FALSE(atlas.Acquire(key, 64, 0));
  atlas.BeginFrame();
  const auto whole = atlas.Acquire(1000, 512, 7);
  ASSERT_TRUE(whole);
  EXPECT_TRUE(Same(whole->rect, AtlasRect{0, 0, 512}));
  EXPECT_EQ(atlas.evictions(), uint32_t(key));
  EXPECT_EQ(atlas.faces(), 1u);
  // Shrinking a face gives back the rest: the freed blocks merge as well.
  const auto small = atlas.Acquire(1000, 64, 7);
  ASSERT_TRUE(small);
  EXPECT_FALSE(small->cached);
  EXPECT_TRUE(atlas.Acquire(1001, 256, 0));
  EXPECT_TRUE(atlas.Acquire(1002, 256, 0));
  EXPECT_TRUE(atlas.Acquire(1003, 128, 0));
}

TEST(ShadowAtlasTest, ClearForgetsEverything) {
  ShadowAtlas atlas(512, 64);
  atlas.BeginFrame();
  for (uint64_t k = 0; k < 10; ++k) ASSERT_TRUE(atlas.Acquire(k, 64, k));
  atlas.Clear();
  EXPECT_EQ(atlas.faces(), 0u);
  EXPECT_EQ(atlas.texels_used(), 0u);
  // The same frame can now place a whole-atlas face, and old keys are not cached.
  const auto whole = atlas.Acquire(50, 512, 0);
  ASSERT_TRUE(whole);
  EXPECT_TRUE(Same(whole->rect, AtlasRect{0, 0, 512}));
  atlas.Clear();
  const auto old = atlas.Acquire(3, 64, 3);
  ASSERT_TRUE(old);
  EXPECT_FALSE(old->cached);
  EXPECT_EQ(atlas.evictions(), 0u);
}

// A released face is forgotten: its space is free at once, and asking for it again is not a
// cache hit (its contents were never rendered).
TEST(ShadowAtlasTest, ReleaseFreesAndForgets) {
  ShadowAtlas atlas(512, 64);
  atlas.BeginFrame();
  ASSERT_TRUE(atlas.Acquire(1, 256, 7));
  atlas.Release(1);
  atlas.Release(99);  // unknown: nothing happens
  EXPECT_EQ(atlas.faces(), 0u);
  const auto whole = atlas.Acquire(2, 512, 0);  // the same frame: all space is back
  ASSERT_TRUE(whole);
  atlas.BeginFrame();
  atlas.Release(2);
  const auto again = atlas.Acquire(1, 256, 7);
  ASSERT_TRUE(again);
  EXPECT_FALSE(again->cached);
}

TEST(ShadowAtlasTest, PlacementIsDeterministic) {
  auto run = [] {
    ShadowAtlas atlas(1024, 32);
    std::mt19937 rng(3);
    std::vector<uint32_t> out;
    for (int frame = 0; frame < 20; ++frame) {
      atlas.BeginFrame();
      for (int k = 0; k < 12; ++k) {
        const auto p = atlas.Acquire(rng() % 30, 16u << (rng() % 5), rng() % 2);
        out.push_back(p ? p->rect.x * 4096 + p->rect.y * 4 + p->cached : ~0u);
      }
    }
    return out;
  };
  EXPECT_EQ(run(), run());
}

TEST(HashBytesTest, Fnv1a64) {
  // The published FNV-1a test vectors, from the FNV-64 offset basis.
  constexpr uint64_t kOffsetBasis = 0xcbf29ce484222325ull;
  EXPECT_EQ(HashBytes("", 0, kOffsetBasis), 0xcbf29ce484222325ull);
  EXPECT_EQ(HashBytes("a", 1, kOffsetBasis), 0xaf63dc4c8601ec8cull);
  EXPECT_EQ(HashBytes("foobar", 6, kOffsetBasis), 0x85944171f73967e8ull);
  // Chaining through the seed hashes the concatenation.
  EXPECT_EQ(HashBytes("bar", 3, HashBytes("foo", 3)), HashBytes("foobar", 6));
  EXPECT_NE(HashBytes("foobar", 6), HashBytes("foobaz", 6));
  const glm::mat4 m(2.0f);
  glm::mat4 n = m;
  EXPECT_EQ(HashBytes(&m, sizeof(m)), HashBytes(&n, sizeof(n)));
  n[3][1] = 1e-6f;
  EXPECT_NE(HashBytes(&m, sizeof(m)), HashBytes(&n, sizeof(n)));
}

}  // namespace
}  // namespace tessera
