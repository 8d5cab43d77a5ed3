// Camera math: view and reverse-Z projection matrices, scene framing, camera validation,
// frustum culling against a brute-force reference, and the bounds / uv transform helpers of the
// CPU scene. Pure math: nothing here touches Vulkan.
#include "renderer/camera.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "renderer/scene/cpu_scene.h"

namespace tessera {
namespace {

constexpr float kPi = 3.14159265358979f;

// Clip-space position of a view-space point.
glm::vec4 Clip(const glm::mat4& proj, const glm::vec3& view_pos) {
  return proj * glm::vec4(view_pos, 1.0f);
}

// Depth after the perspective divide (what the depth buffer stores).
float Depth(const glm::mat4& proj, float distance) {
  const glm::vec4 c = Clip(proj, glm::vec3(0.0f, 0.0f, -distance));
  return c.z / c.w;
}

std::array<glm::vec3, 8> Corners(const Aabb& b) {
  std::array<glm::vec3, 8> out;
  for (int i = 0; i < 8; ++i) {
    out[i] = glm::vec3((i & 1) ? b.max.x : b.min.x, (i & 2) ? b.max.y : b.min.y,
                       (i & 4) ? b.max.z : b.min.z);
  }
  return out;
}

Aabb Box(const glm::vec3& min, const glm::vec3& max) {
  Aabb b;
  b.min = min;
  b.max = max;
  return b;
}

void ExpectNear3(const glm::vec3& actual, const glm::vec3& expected, float tol,
                 const std::string& what) {
  EXPECT_NEAR(actual.x, expected.x, tol) << what;
  EXPECT_NEAR(actual.y, expected.y, tol) << what;
  EXPECT_NEAR(actual.z, expected.z, tol) << what;
}

bool Contains(const absl::Status& status, const std::string& needle) {
  return std::string(status.message()).find(needle) != std::string::npos;
}

// ---------------------------------------------------------------------------------------------
// ViewMatrix / CameraPosition

TEST(ViewMatrixTest, MapsEyeToOriginAndTargetOntoNegativeZ) {
  struct Case {
    glm::vec3 eye, target, up;
  };
  const std::vector<Case> cases = {
      {{0, 0, 5}, {0, 0, 0}, {0, 1, 0}},
      {{3, -2, 7}, {-1, 4, 0.5f}, {0, 1, 0}},
      {{10, 10, 10}, {0, 0, 0}, {0, 0, 1}},
      {{0.1f, 50, 0}, {0, 0, 0}, {1, 0, 0}},
  };
  for (const Case& c : cases) {
    Camera cam;
    cam.eye = c.eye;
    cam.target = c.target;
    cam.up = c.up;
    ASSERT_TRUE(ValidateCamera(cam).ok());
    const glm::mat4 v = ViewMatrix(cam);
    const float dist = glm::length(c.target - c.eye);
    ExpectNear3(glm::vec3(v * glm::vec4(c.eye, 1.0f)), glm::vec3(0.0f), 1e-4f, "eye");
    // Right-handed, looking down -Z: the target is straight ahead at its distance.
    ExpectNear3(glm::vec3(v * glm::vec4(c.target, 1.0f)), glm::vec3(0.0f, 0.0f, -dist),
                1e-4f * dist, "target");
    // "Up" stays up: a point displaced along `up` (off the view axis) has positive view y.
    const glm::vec3 dir = glm::normalize(c.target - c.eye);
    const glm::vec3 up_perp = glm::normalize(c.up - glm::dot(c.up, dir) * dir);
    EXPECT_GT((v * glm::vec4(c.eye + up_perp, 1.0f)).y, 0.99f);
    // A rigid transform: lengths are preserved.
    EXPECT_NEAR(std::abs(glm::determinant(v)), 1.0f, 1e-4f);
  }
}

TEST(ViewMatrixTest, ExplicitViewMatrixWins) {
  Camera cam;
  cam.view = glm::translate(glm::mat4(1.0f), glm::vec3(1, 2, 3));
  cam.eye = glm::vec3(100.0f);  // ignored when `view` is set
  EXPECT_EQ(ViewMatrix(cam), *cam.view);
}

TEST(CameraPositionTest, FromEyeAndFromViewMatrix) {
  Camera cam;
  cam.eye = glm::vec3(3, -4, 12);
  cam.target = glm::vec3(1, 1, 1);
  EXPECT_EQ(CameraPosition(cam), cam.eye);

  // The same camera expressed by its view matrix: the position comes from the inverse.
  Camera by_view;
  by_view.view = glm::lookAtRH(cam.eye, cam.target, cam.up);
  ExpectNear3(CameraPosition(by_view), cam.eye, 1e-4f, "from view");

  // A view with rotation and translation that did not come from lookAt.
  const glm::mat4 world = glm::translate(glm::mat4(1.0f), glm::vec3(-7, 2, 9)) *
                          glm::rotate(glm::mat4(1.0f), 1.1f, glm::normalize(glm::vec3(1, 2, 3)));
  by_view.view = glm::inverse(world);
  ExpectNear3(CameraPosition(by_view), glm::vec3(-7, 2, 9), 1e-4f, "from rotated view");
}

// ---------------------------------------------------------------------------------------------
// ProjectionMatrix (reverse Z, Y down)

TEST(ProjectionMatrixTest, NearPlaneMapsToDepthOne) {
  for (float zfar : {0.0f, 100.0f}) {
    Camera cam;
    cam.znear = 0.1f;
    cam.zfar = zfar;
    const glm::mat4 p = ProjectionMatrix(cam, 1.5f);
    EXPECT_NEAR(Depth(p, cam.znear), 1.0f, 1e-5f) << "zfar " << zfar;
    // Off-axis points on the near plane too: depth depends on view z only.
    const glm::vec4 c = Clip(p, glm::vec3(0.03f, -0.02f, -cam.znear));
    EXPECT_NEAR(c.z / c.w, 1.0f, 1e-5f) << "zfar " << zfar;
  }
}

TEST(ProjectionMatrixTest, FiniteFarPlaneMapsToDepthZero) {
  Camera cam;
  cam.znear = 0.5f;
  cam.zfar = 250.0f;
  const glm::mat4 p = ProjectionMatrix(cam, 1.0f);
  EXPECT_NEAR(Depth(p, cam.zfar), 0.0f, 1e-6f);
  // Beyond the far plane the depth is negative: clipped by Vulkan's 0 <= z <= w.
  EXPECT_LT(Depth(p, cam.zfar * 1.5f), 0.0f);
}

TEST(ProjectionMatrixTest, InfiniteFarApproachesZero) {
  Camera cam;
  cam.znear = 0.05f;
  cam.zfar = 0.0f;
  const glm::mat4 p = ProjectionMatrix(cam, 1.0f);
  float previous = 1.0f;
  for (float d : {1.0f, 10.0f, 1e3f, 1e5f, 1e7f}) {
    const float depth = Depth(p, d);
    EXPECT_GT(depth, 0.0f) << d;  // never reaches the far "plane": nothing is far-clipped
    EXPECT_LT(depth, previous) << d;
    previous = depth;
  }
  EXPECT_LT(Depth(p, 1e7f), 1e-7f);
}

TEST(ProjectionMatrixTest, DepthDecreasesMonotonicallyWithDistance) {
  for (float zfar : {0.0f, 50.0f}) {
    Camera cam;
    cam.znear = 0.1f;
    cam.zfar = zfar;
    const glm::mat4 p = ProjectionMatrix(cam, 1.0f);
    const float last = zfar == 0.0f ? 1e6f : zfar;
    float previous = 2.0f;
    // Log-spaced distances from the near plane out to the far plane (or very far away).
    for (float d = cam.znear; d <= last; d *= 1.25f) {
      const float depth = Depth(p, d);
      EXPECT_LT(depth, previous) << "distance " << d << " zfar " << zfar;
      EXPECT_GE(depth, 0.0f) << "distance " << d << " zfar " << zfar;
      EXPECT_LE(depth, 1.0f + 1e-6f) << "distance " << d << " zfar " << zfar;
      previous = depth;
    }
  }
}

TEST(ProjectionMatrixTest, ClipSpaceYIsFlippedXIsNot) {
  Camera cam;
  const glm::mat4 p = ProjectionMatrix(cam, 1.0f);
  // Vulkan's clip space has +Y down: a point above the view axis lands in the upper half of
  // the image, i.e. negative y/w.
  const glm::vec4 above = Clip(p, glm::vec3(0.0f, 1.0f, -5.0f));
  EXPECT_GT(above.w, 0.0f);
  EXPECT_LT(above.y / above.w, 0.0f);
  const glm::vec4 below = Clip(p, glm::vec3(0.0f, -1.0f, -5.0f));
  EXPECT_GT(below.y / below.w, 0.0f);
  // X keeps its direction: right of the axis is positive.
  const glm::vec4 right = Clip(p, glm::vec3(1.0f, 0.0f, -5.0f));
  EXPECT_GT(right.x / right.w, 0.0f);
}

TEST(ProjectionMatrixTest, FieldOfViewAndAspectMapFrustumEdgesToNdcEdges) {
  for (float yfov : {0.3f, 0.8f, 1.6f}) {
    for (float aspect : {0.5f, 1.0f, 2.0f, 16.0f / 9.0f}) {
      Camera cam;
      cam.yfov = yfov;
      const glm::mat4 p = ProjectionMatrix(cam, aspect);
      const float d = 7.0f;
      const float half_h = std::tan(yfov * 0.5f) * d;
      const float half_w = half_h * aspect;
      const glm::vec4 top = Clip(p, glm::vec3(0.0f, half_h, -d));
      EXPECT_NEAR(top.y / top.w, -1.0f, 1e-5f) << yfov << " " << aspect;
      const glm::vec4 side = Clip(p, glm::vec3(half_w, 0.0f, -d));
      EXPECT_NEAR(side.x / side.w, 1.0f, 1e-5f) << yfov << " " << aspect;
      // w is the view distance: the perspective divide is by the distance in front.
      EXPECT_NEAR(top.w, d, 1e-5f);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// PixelRaysFor

// The affine rays hit the pixel they are for: eye + t * ray(x, y), cast from the camera's
// position as the shaders cast it, projects to framebuffer pixel (x, y), with TAA's sub-pixel
// jitter in the projection, at 1 m and 150 m. They are the per-pixel unprojection (through the
// inverse of the same matrix, in double, less the matrix's centre of projection: affine in the
// pixel to float precision) and end on the near plane. 1.2 km out the float view-projection's
// centre is about 0.1 mm off the eye: the rays are aimed from that centre, so a hit 1 m away
// lands within a few tenths of a pixel (aimed from the eye, as the unprojection was, they missed
// by 2-6 pixels at every distance).
TEST(PixelRaysTest, RaysProjectBackOntoTheirPixels) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (const glm::vec3 eye : {glm::vec3(0.0f, 0.0f, 3.0f), glm::vec3(9.0f, 1.6f, -0.4f),
                              glm::vec3(-250.0f, 40.0f, 1200.0f)}) {
    const bool far = std::abs(eye.z) > 100.0f;
    for (const auto& [width, height] : {std::pair{1280u, 720u}, std::pair{3840u, 2160u},
                                        std::pair{97u, 301u}}) {
      Camera cam;
      cam.eye = eye;
      cam.target = eye + glm::vec3(-14.0f, 1.9f, 0.7f);
      cam.znear = 0.05f;
      cam.yfov = 0.9f;
      glm::mat4 proj = ProjectionMatrix(cam, float(width) / float(height));
      proj[2][0] += 2.0f * 0.37f / float(width);  // jitter, as TAA applies it
      proj[2][1] += 2.0f * -0.21f / float(height);
      const glm::mat4 view_proj = proj * ViewMatrix(cam);
      const glm::dmat4 vp(view_proj), inv = glm::inverse(vp);
      const glm::dvec4 centre_h = inv * glm::dvec4(0.0, 0.0, 1.0, 0.0);  // clip w = 0
      const glm::dvec3 centre = glm::dvec3(centre_h) / centre_h.w;
      EXPECT_LT(glm::length(centre - glm::dvec3(eye)), far ? 1e-3 : 1e-5);
      const PixelRays rays = PixelRaysFor(view_proj, width, height);
      double worst_rel = 0.0, worst_depth = 0.0, worst_near_px = 0.0, worst_far_px = 0.0;
      for (int i = 0; i < 50; ++i) {
        const glm::vec2 pixel(unit(rng) * float(width), unit(rng) * float(height));
        // As the shaders evaluate it, in float.
        const glm::vec3 dir = rays.origin + pixel.x * rays.dx + pixel.y * rays.dy;
        for (double t : {20.0, 3000.0}) {  // 1 m and 150 m out
          const glm::dvec4 c = vp * glm::dvec4(glm::dvec3(eye) + t * glm::dvec3(dir), 1.0);
          const glm::dvec2 at((c.x / c.w * 0.5 + 0.5) * width, (c.y / c.w * 0.5 + 0.5) * height);
          double& worst = t < 100.0 ? worst_near_px : worst_far_px;
          worst = std::max(worst, glm::length(at - glm::dvec2(pixel)));
        }
        const glm::dvec4 p = inv * glm::dvec4(pixel.x / width * 2.0 - 1.0,
                                              pixel.y / height * 2.0 - 1.0, 1.0, 1.0);
        const glm::dvec3 unprojected = glm::dvec3(p) / p.w - centre;
        worst_rel = std::max(worst_rel, glm::length(glm::dvec3(dir) - unprojected) /
                                            glm::length(unprojected));
        const glm::dvec4 near = vp * glm::dvec4(centre + glm::dvec3(dir), 1.0);
        worst_depth = std::max(worst_depth, std::abs(near.z / near.w - 1.0));
      }
      const std::string what = "eye z " + std::to_string(eye.z) + ", " + std::to_string(width);
      EXPECT_LT(worst_far_px, 0.02) << what << ": 150 m out";
      EXPECT_LT(worst_near_px, far ? 0.5 : 0.05) << what << ": 1 m out";
      EXPECT_LT(worst_rel, 1e-5) << what;
      EXPECT_LT(worst_depth, 1e-4) << what << ": the rays end on the near plane";
    }
  }
}

// ---------------------------------------------------------------------------------------------
// FrameBounds

// Every corner of `bounds` must be in front of the near plane and inside the NDC square.
void ExpectFramed(const Camera& cam, const Aabb& bounds, float aspect, const std::string& what) {
  ASSERT_TRUE(ValidateCamera(cam).ok()) << what << ": " << ValidateCamera(cam);
  const glm::mat4 v = ViewMatrix(cam);
  const glm::mat4 p = ProjectionMatrix(cam, aspect);
  for (const glm::vec3& corner : Corners(bounds)) {
    const glm::vec4 vp = v * glm::vec4(corner, 1.0f);
    EXPECT_LT(vp.z, -cam.znear) << what << " corner behind the near plane";
    const glm::vec4 c = p * vp;
    ASSERT_GT(c.w, 0.0f) << what;
    EXPECT_LE(std::abs(c.x / c.w), 1.0f + 1e-5f) << what;
    EXPECT_LE(std::abs(c.y / c.w), 1.0f + 1e-5f) << what;
    EXPECT_GT(c.z / c.w, 0.0f) << what;
    EXPECT_LE(c.z / c.w, 1.0f) << what;
  }
}

// True when some corner of `bounds` is outside the view of `cam` (off the image or behind it).
bool SomeCornerOutOfView(const Camera& cam, const Aabb& bounds, float aspect) {
  const glm::mat4 vp = ProjectionMatrix(cam, aspect) * ViewMatrix(cam);
  for (const glm::vec3& corner : Corners(bounds)) {
    const glm::vec4 c = vp * glm::vec4(corner, 1.0f);
    if (c.w <= 0.0f || std::abs(c.x / c.w) > 1.0f || std::abs(c.y / c.w) > 1.0f) return true;
  }
  return false;
}

TEST(FrameBoundsTest, WholeBoxInsideTheImage) {
  const std::vector<Aabb> boxes = {
      Box({-1, -1, -1}, {1, 1, 1}),
      Box({0, 0, 0}, {10, 0.5f, 0.5f}),     // long and thin along x
      Box({-0.2f, -30, 2}, {0.2f, 30, 3}),  // tall
      Box({100, 200, -50}, {104, 201, -47}),
  };
  const std::vector<glm::vec3> directions = {
      glm::vec3(0.55f, 0.45f, 0.70f),  // the default
      glm::vec3(0, 0, 1),
      glm::vec3(1, 0, 0),
      glm::vec3(-1, -2, 0.5f),
      glm::vec3(0, 1, 0),   // straight down: up must be replaced
      glm::vec3(0, -1, 0),  // straight up
  };
  for (const Aabb& box : boxes) {
    for (float yfov : {0.3f, 0.8f, 1.2f, 2.0f}) {
      for (float aspect : {0.5f, 1.0f, 2.0f}) {
        for (const glm::vec3& dir : directions) {
          const Camera cam = FrameBounds(box, yfov, aspect, dir);
          const std::string what = "yfov " + std::to_string(yfov) + " aspect " +
                                   std::to_string(aspect) + " dir " + std::to_string(dir.x) + "," +
                                   std::to_string(dir.y) + "," + std::to_string(dir.z);
          EXPECT_FLOAT_EQ(cam.yfov, yfov) << what;
          ExpectNear3(cam.target, box.center(), 1e-4f, what);
          ExpectFramed(cam, box, aspect, what);
          // And it is the nearest such distance plus a small margin: 8% closer, some corner
          // leaves the image. A loose sphere fit or a runaway distance would not.
          Camera closer = cam;
          closer.eye = cam.target + (cam.eye - cam.target) * 0.92f;
          EXPECT_TRUE(SomeCornerOutOfView(closer, box, aspect)) << what << ": camera too far";
        }
      }
    }
  }
}

TEST(FrameBoundsTest, DefaultDirectionFramesTheBox) {
  const Aabb box = Box({-3, 0, -2}, {3, 4, 2});
  for (float aspect : {0.5f, 1.0f, 2.0f}) {
    ExpectFramed(FrameBounds(box, 0.8f, aspect), box, aspect, "default direction");
  }
}

TEST(FrameBoundsTest, DegenerateBoundsGiveAValidCamera) {
  // Empty (nothing to draw), a single point, a flat quad and a line: each must still give a
  // camera the renderer accepts, or an empty scene could not be rendered at all.
  const std::vector<Aabb> boxes = {
      Aabb{},
      Box({0, 0, 0}, {0, 0, 0}),
      Box({2, -1, 3}, {2, -1, 3}),
      Box({-1, 0, -1}, {1, 0, 1}),
      Box({0, 0, 0}, {0, 5, 0}),
      Box({50, 50, 50}, {50, 50, 50}),
  };
  for (size_t i = 0; i < boxes.size(); ++i) {
    for (float aspect : {0.5f, 1.0f, 2.0f}) {
      const Camera cam = FrameBounds(boxes[i], 0.8f, aspect);
      const absl::Status st = ValidateCamera(cam);
      EXPECT_TRUE(st.ok()) << "box " << i << ": " << st;
      EXPECT_TRUE(std::isfinite(cam.eye.x) && std::isfinite(cam.eye.y) && std::isfinite(cam.eye.z))
          << "box " << i;
      if (!boxes[i].empty()) ExpectFramed(cam, boxes[i], aspect, "box " + std::to_string(i));
    }
  }
}

TEST(FrameBoundsTest, SmallBoundsFarFromTheOriginGiveAValidCamera) {
  // Georeferenced files put geometry 1e5..1e6 units from the origin. A point (or a tiny box)
  // there must still give a camera whose eye differs from its target in float precision.
  for (float offset : {1e3f, 1e5f, 1e6f}) {
    Aabb point;
    point.extend(glm::vec3(offset, -offset, offset));
    Aabb tiny = point;
    tiny.extend(glm::vec3(offset, -offset, offset) + glm::vec3(1e-4f));
    for (const Aabb& box : {point, tiny}) {
      const Camera cam = FrameBounds(box, 0.8f, 1.0f);
      const absl::Status st = ValidateCamera(cam);
      EXPECT_TRUE(st.ok()) << "offset " << offset << " extent " << box.extent().x << ": " << st;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// FromSceneCamera

TEST(FromSceneCameraTest, RoundTripsTheNodeTransform) {
  SceneCamera sc;
  sc.name = "cam";
  const glm::vec3 position(4, -1, 9);
  sc.world = glm::translate(glm::mat4(1.0f), position) *
             glm::rotate(glm::mat4(1.0f), 0.7f, glm::normalize(glm::vec3(0.3f, 1, -0.2f)));
  sc.yfov = 0.9f;
  sc.znear = 0.2f;
  sc.zfar = 300.0f;
  const Camera cam = FromSceneCamera(sc);
  ASSERT_TRUE(ValidateCamera(cam).ok()) << ValidateCamera(cam);
  EXPECT_FLOAT_EQ(cam.yfov, sc.yfov);
  EXPECT_FLOAT_EQ(cam.znear, sc.znear);
  EXPECT_FLOAT_EQ(cam.zfar, sc.zfar);
  ExpectNear3(CameraPosition(cam), position, 1e-4f, "position");

  // View * world is the identity: the camera node's frame is the view frame.
  const glm::mat4 id = ViewMatrix(cam) * sc.world;
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) EXPECT_NEAR(id[c][r], c == r ? 1.0f : 0.0f, 1e-5f);

  // glTF cameras look down their local -Z with +Y up.
  const glm::vec3 ahead = glm::vec3(sc.world * glm::vec4(0, 0, -5, 1));
  ExpectNear3(glm::vec3(ViewMatrix(cam) * glm::vec4(ahead, 1.0f)), glm::vec3(0, 0, -5), 1e-4f,
              "ahead");
}

TEST(FromSceneCameraTest, MissingOrBadClipPlanesGiveAValidCamera) {
  SceneCamera sc;
  sc.znear = 0.0f;  // not given / invalid
  sc.zfar = 0.0f;   // infinite
  Camera cam = FromSceneCamera(sc);
  EXPECT_GT(cam.znear, 0.0f);
  EXPECT_EQ(cam.zfar, 0.0f);
  EXPECT_TRUE(ValidateCamera(cam).ok()) << ValidateCamera(cam);

  sc.znear = 1.0f;
  sc.zfar = 0.5f;  // far before near: treat as infinite rather than reject the file
  cam = FromSceneCamera(sc);
  EXPECT_TRUE(ValidateCamera(cam).ok()) << ValidateCamera(cam);
}

// ---------------------------------------------------------------------------------------------
// ValidateCamera

TEST(ValidateCameraTest, DefaultAndInfiniteFarAreValid) {
  Camera cam;
  EXPECT_TRUE(ValidateCamera(cam).ok()) << ValidateCamera(cam);
  cam.zfar = 0.0f;
  EXPECT_TRUE(ValidateCamera(cam).ok());
  cam.zfar = 1000.0f;
  EXPECT_TRUE(ValidateCamera(cam).ok());
  cam.yfov = 3.09f;
  EXPECT_TRUE(ValidateCamera(cam).ok());
}

TEST(ValidateCameraTest, RejectsBadFieldsNamingThem) {
  const float nan = std::nanf("");
  const float inf = std::numeric_limits<float>::infinity();
  struct Case {
    std::string name;
    Camera camera;
    std::vector<std::string> fields;  // the message must name one of these
  };
  std::vector<Case> cases;
  auto add = [&](std::string name, std::vector<std::string> fields, auto mutate) {
    Case c{std::move(name), Camera{}, std::move(fields)};
    mutate(c.camera);
    cases.push_back(std::move(c));
  };
  add("nan eye", {"camera.eye"}, [&](Camera& c) { c.eye.y = nan; });
  add("inf eye", {"camera.eye"}, [&](Camera& c) { c.eye.x = inf; });
  add("nan target", {"camera.target"}, [&](Camera& c) { c.target.z = nan; });
  add("nan up", {"camera.up"}, [&](Camera& c) { c.up.x = nan; });
  // Which of the two is blamed is a matter of taste; either names the problem.
  add("eye == target", {"camera.eye", "camera.target"},
      [](Camera& c) { c.target = c.eye = glm::vec3(1, 2, 3); });
  add("up parallel", {"camera.up"}, [](Camera& c) {
    c.eye = glm::vec3(0, 5, 0);
    c.target = glm::vec3(0);
    c.up = glm::vec3(0, 1, 0);
  });
  add("up antiparallel", {"camera.up"}, [](Camera& c) {
    c.eye = glm::vec3(0, 0, 5);
    c.target = glm::vec3(0);
    c.up = glm::vec3(0, 0, 3);
  });
  add("up zero", {"camera.up"}, [](Camera& c) { c.up = glm::vec3(0); });
  add("yfov 0", {"camera.yfov"}, [](Camera& c) { c.yfov = 0.0f; });
  add("yfov negative", {"camera.yfov"}, [](Camera& c) { c.yfov = -0.5f; });
  add("yfov 3.1", {"camera.yfov"}, [](Camera& c) { c.yfov = 3.1f; });
  add("yfov pi", {"camera.yfov"}, [](Camera& c) { c.yfov = kPi; });
  add("yfov nan", {"camera.yfov"}, [&](Camera& c) { c.yfov = nan; });
  add("znear 0", {"camera.znear"}, [](Camera& c) { c.znear = 0.0f; });
  add("znear negative", {"camera.znear"}, [](Camera& c) { c.znear = -1.0f; });
  add("znear nan", {"camera.znear"}, [&](Camera& c) { c.znear = nan; });
  add("zfar == znear", {"camera.zfar"}, [](Camera& c) {
    c.znear = 1.0f;
    c.zfar = 1.0f;
  });
  add("zfar < znear", {"camera.zfar"}, [](Camera& c) {
    c.znear = 1.0f;
    c.zfar = 0.5f;
  });
  add("zfar negative", {"camera.zfar"}, [](Camera& c) { c.zfar = -10.0f; });
  add("zfar inf", {"camera.zfar"}, [&](Camera& c) { c.zfar = inf; });
  add("singular view", {"camera.view"},
      [](Camera& c) { c.view = glm::scale(glm::mat4(1.0f), glm::vec3(1, 0, 1)); });
  add("zero view", {"camera.view"}, [](Camera& c) { c.view = glm::mat4(0.0f); });
  add("nan view", {"camera.view"}, [&](Camera& c) {
    c.view = glm::mat4(1.0f);
    (*c.view)[3][1] = nan;
  });

  for (const Case& c : cases) {
    const absl::Status st = ValidateCamera(c.camera);
    EXPECT_EQ(st.code(), absl::StatusCode::kInvalidArgument) << c.name << ": " << st;
    bool named = false;
    for (const std::string& f : c.fields) named = named || Contains(st, f);
    EXPECT_TRUE(named) << c.name << ": message does not name the field: " << st;
  }
}

TEST(ValidateCameraTest, ViewMatrixMakesEyeTargetUpIrrelevant) {
  Camera cam;
  cam.view = glm::lookAtRH(glm::vec3(1, 2, 3), glm::vec3(0), glm::vec3(0, 1, 0));
  cam.eye = cam.target = glm::vec3(0);  // would be rejected without `view`
  EXPECT_TRUE(ValidateCamera(cam).ok()) << ValidateCamera(cam);
}

// ---------------------------------------------------------------------------------------------
// Frustum culling against a brute-force clip-space reference

struct ClipReference {
  bool all_outside_one_plane = false;  // must be culled
  bool some_corner_inside = false;     // must be kept
};

// Classifies a box by its 8 corners in clip space (double precision). Vulkan clip volume with
// reverse Z: -w <= x <= w, -w <= y <= w, 0 <= z <= w. `margin` keeps corners that lie on a
// plane, within rounding, out of both categories.
ClipReference Classify(const glm::mat4& view_proj, const Aabb& box, double margin) {
  const glm::dmat4 m(view_proj);
  std::array<bool, 6> all_out;
  all_out.fill(true);
  ClipReference ref;
  for (const glm::vec3& corner : Corners(box)) {
    const glm::dvec4 c = m * glm::dvec4(glm::dvec3(corner), 1.0);
    const std::array<double, 6> d = {c.w + c.x, c.w - c.x, c.w + c.y, c.w - c.y, c.z, c.w - c.z};
    bool inside = true;
    for (int i = 0; i < 6; ++i) {
      if (d[i] >= -margin) all_out[i] = false;
      if (d[i] <= margin) inside = false;
    }
    // (A corner behind the camera has w < 0, so it can't pass both 0 <= z and z <= w.)
    ref.some_corner_inside = ref.some_corner_inside || inside;
  }
  for (bool b : all_out) ref.all_outside_one_plane = ref.all_outside_one_plane || b;
  return ref;
}

TEST(FrustumTest, MatchesBruteForceClipReference) {
  std::mt19937 rng(20240611u);
  std::uniform_real_distribution<float> pos(-40.0f, 40.0f);
  std::uniform_real_distribution<float> size(0.01f, 8.0f);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);

  int culled = 0, kept = 0, checked_culled = 0, checked_kept = 0;
  for (int cam_i = 0; cam_i < 24; ++cam_i) {
    Camera cam;
    cam.eye = glm::vec3(pos(rng), pos(rng), pos(rng)) * 0.5f;
    cam.target = glm::vec3(pos(rng), pos(rng), pos(rng)) * 0.25f;
    cam.yfov = 0.4f + 1.6f * unit(rng);
    cam.znear = 0.05f + 0.5f * unit(rng);
    cam.zfar = (cam_i % 2 == 0) ? 0.0f : 30.0f + 40.0f * unit(rng);  // infinite and finite
    if (!ValidateCamera(cam).ok()) continue;
    const float aspect = 0.5f + 1.5f * unit(rng);
    const glm::mat4 vp = ProjectionMatrix(cam, aspect) * ViewMatrix(cam);
    const Frustum frustum = FrustumFromViewProj(vp);

    for (int i = 0; i < 2000; ++i) {
      const glm::vec3 lo(pos(rng), pos(rng), pos(rng));
      const Aabb box = Box(lo, lo + glm::vec3(size(rng), size(rng), size(rng)));
      const ClipReference ref = Classify(vp, box, 1e-2);
      const bool visible = AabbIntersectsFrustum(box, frustum);
      (visible ? kept : culled)++;
      if (ref.all_outside_one_plane) {
        ++checked_culled;
        EXPECT_FALSE(visible) << "camera " << cam_i << " box " << i
                              << ": all corners outside one plane but kept";
      }
      if (ref.some_corner_inside) {
        ++checked_kept;
        EXPECT_TRUE(visible) << "camera " << cam_i << " box " << i
                             << ": a corner is inside the clip volume but the box was culled";
      }
    }
  }
  // The random setup must actually exercise both outcomes.
  EXPECT_GT(checked_culled, 1000);
  EXPECT_GT(checked_kept, 1000);
  EXPECT_GT(culled, 0);
  EXPECT_GT(kept, 0);
}

TEST(FrustumTest, BoxesBehindTheCameraAreCulled) {
  for (float zfar : {0.0f, 100.0f}) {
    Camera cam;
    cam.eye = glm::vec3(0, 0, 0);
    cam.target = glm::vec3(0, 0, -1);
    cam.zfar = zfar;
    cam.yfov = 1.5f;
    const Frustum f = FrustumFromViewProj(ProjectionMatrix(cam, 1.0f) * ViewMatrix(cam));
    // Right behind, and behind but so wide it would cover the view if mirrored forwards.
    EXPECT_FALSE(AabbIntersectsFrustum(Box({-1, -1, 2}, {1, 1, 4}), f)) << zfar;
    EXPECT_FALSE(AabbIntersectsFrustum(Box({-100, -100, 0.5f}, {100, 100, 50}), f)) << zfar;
    // Straddling the camera position: part of it is in front, so it is kept.
    EXPECT_TRUE(AabbIntersectsFrustum(Box({-1, -1, -3}, {1, 1, 3}), f)) << zfar;
    // In front.
    EXPECT_TRUE(AabbIntersectsFrustum(Box({-1, -1, -6}, {1, 1, -4}), f)) << zfar;
  }
}

TEST(FrustumTest, InfiniteFarRejectsNothingByDistanceFiniteFarDoes) {
  Camera cam;
  cam.eye = glm::vec3(0);
  cam.target = glm::vec3(0, 0, -1);
  const Aabb far_box = Box({-1e4f, -1e4f, -1.1e6f}, {1e4f, 1e4f, -1e6f});
  const glm::mat4 v = ViewMatrix(cam);
  cam.zfar = 0.0f;
  EXPECT_TRUE(AabbIntersectsFrustum(far_box, FrustumFromViewProj(ProjectionMatrix(cam, 1) * v)));
  cam.zfar = 1000.0f;
  EXPECT_FALSE(AabbIntersectsFrustum(far_box, FrustumFromViewProj(ProjectionMatrix(cam, 1) * v)));
}

TEST(FrustumTest, PlanesAreNormalizedAndPointInward) {
  Camera cam;
  cam.eye = glm::vec3(1, 2, 3);
  cam.target = glm::vec3(0);
  cam.zfar = 50.0f;
  const Frustum f = FrustumFromViewProj(ProjectionMatrix(cam, 1.3f) * ViewMatrix(cam));
  // A point straight ahead between near and far is on the inner side of all six planes.
  const glm::vec3 inside = cam.eye + glm::normalize(cam.target - cam.eye) * 5.0f;
  for (const glm::vec4& p : f) {
    EXPECT_NEAR(glm::length(glm::vec3(p)), 1.0f, 1e-5f);
    EXPECT_GT(glm::dot(glm::vec3(p), inside) + p.w, 0.0f);
  }
}

TEST(FrustumTest, EmptyBoxIsCulled) {
  const Frustum f = FrustumFromViewProj(ProjectionMatrix(Camera{}, 1.0f) * ViewMatrix(Camera{}));
  EXPECT_FALSE(AabbIntersectsFrustum(Aabb{}, f));
}

// ---------------------------------------------------------------------------------------------
// Aabb::transformed

TEST(AabbTest, TransformedEqualsBoundsOfTransformedCorners) {
  std::mt19937 rng(7u);
  std::uniform_real_distribution<float> coord(-5.0f, 5.0f);
  std::uniform_real_distribution<float> extent(0.0f, 4.0f);
  std::uniform_real_distribution<float> scale(0.1f, 3.0f);
  std::uniform_real_distribution<float> angle(-kPi, kPi);
  for (int i = 0; i < 500; ++i) {
    const glm::vec3 axis =
        glm::normalize(glm::vec3(coord(rng), coord(rng), coord(rng)) + glm::vec3(0.01f));
    // Translation * rotation * non-uniform scale, sometimes with a mirror, and a second
    // rotation on the other side so the scale is not axis-aligned (shear).
    glm::vec3 s(scale(rng), scale(rng), scale(rng));
    if (i % 5 == 0) s.x = -s.x;
    glm::mat4 m =
        glm::translate(glm::mat4(1.0f), glm::vec3(coord(rng), coord(rng), coord(rng)) * 2.0f);
    m = glm::rotate(m, angle(rng), axis);
    m = glm::scale(m, s);
    if (i % 2 == 0) m = glm::rotate(m, angle(rng), glm::vec3(0, 1, 0));

    const glm::vec3 lo(coord(rng), coord(rng), coord(rng));
    const Aabb box = Box(lo, lo + glm::vec3(extent(rng), extent(rng), extent(rng)));
    Aabb expected;
    for (const glm::vec3& c : Corners(box)) expected.extend(glm::vec3(m * glm::vec4(c, 1.0f)));
    const Aabb got = box.transformed(m);
    ExpectNear3(got.min, expected.min, 1e-4f, "min, case " + std::to_string(i));
    ExpectNear3(got.max, expected.max, 1e-4f, "max, case " + std::to_string(i));
  }
}

TEST(AabbTest, TransformedEmptyStaysEmpty) {
  EXPECT_TRUE(Aabb{}.transformed(glm::translate(glm::mat4(1.0f), glm::vec3(1))).empty());
}

// ---------------------------------------------------------------------------------------------
// TextureRef::uv_transform (KHR_texture_transform)

// The extension's formula written out: uv' = T * R * S * uv with R = [[cos, sin], [-sin, cos]]
// (rows). This is the direction the spec's prose, its example JSON and the TextureTransformTest
// sample model agree on ("rotate the UVs counter-clockwise" in the V-down UV space).
glm::vec2 SpecUv(const TextureRef& t, glm::vec2 uv) {
  const float c = std::cos(t.rotation), s = std::sin(t.rotation);
  const glm::vec2 scaled = uv * t.scale;
  const glm::vec2 rotated(c * scaled.x + s * scaled.y, -s * scaled.x + c * scaled.y);
  return rotated + t.offset;
}

glm::vec2 Apply(const glm::mat3& m, glm::vec2 uv) { return glm::vec2(m * glm::vec3(uv, 1.0f)); }

TEST(UvTransformTest, IdentityByDefault) {
  const TextureRef t;
  const glm::mat3 m = t.uv_transform();
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) EXPECT_NEAR(m[c][r], c == r ? 1.0f : 0.0f, 1e-7f);
}

TEST(UvTransformTest, MatchesSpecFormulaOnSamplePoints) {
  const std::vector<glm::vec2> points = {{0, 0}, {1, 0},         {0, 1},
                                         {1, 1}, {0.25f, 0.75f}, {-0.5f, 2.0f}};
  std::vector<TextureRef> refs;
  for (float rot : {0.0f, 0.392699f, kPi / 2, -1.0f, 2.5f}) {
    for (glm::vec2 scale : {glm::vec2(1, 1), glm::vec2(0.5f, 2.0f), glm::vec2(1.5f, -1.0f)}) {
      for (glm::vec2 offset : {glm::vec2(0, 0), glm::vec2(0.25f, -0.5f)}) {
        TextureRef t;
        t.rotation = rot;
        t.scale = scale;
        t.offset = offset;
        refs.push_back(t);
      }
    }
  }
  for (const TextureRef& t : refs) {
    const glm::mat3 m = t.uv_transform();
    // Affine: the last row stays (0, 0, 1).
    EXPECT_NEAR(m[0][2], 0.0f, 1e-7f);
    EXPECT_NEAR(m[1][2], 0.0f, 1e-7f);
    EXPECT_NEAR(m[2][2], 1.0f, 1e-7f);
    for (glm::vec2 p : points) {
      const glm::vec2 got = Apply(m, p), want = SpecUv(t, p);
      EXPECT_NEAR(got.x, want.x, 1e-5f) << "rot " << t.rotation << " uv " << p.x << "," << p.y;
      EXPECT_NEAR(got.y, want.y, 1e-5f) << "rot " << t.rotation << " uv " << p.x << "," << p.y;
    }
  }
}

TEST(UvTransformTest, SpecExampleUsesLowerLeftQuadrant) {
  // KHR_texture_transform's example: offset [0, 1], rotation pi/2, scale 0.5 "utilizes only
  // the lower left quadrant of the source image" (V points down, so lower = v in [0.5, 1]).
  TextureRef t;
  t.offset = glm::vec2(0, 1);
  t.rotation = 1.57079632679f;
  t.scale = glm::vec2(0.5f);
  const glm::mat3 m = t.uv_transform();
  for (glm::vec2 p : {glm::vec2(0, 0), glm::vec2(1, 0), glm::vec2(0, 1), glm::vec2(1, 1),
                      glm::vec2(0.3f, 0.6f)}) {
    const glm::vec2 q = Apply(m, p);
    EXPECT_GE(q.x, -1e-6f) << p.x << "," << p.y;
    EXPECT_LE(q.x, 0.5f + 1e-6f) << p.x << "," << p.y;
    EXPECT_GE(q.y, 0.5f - 1e-6f) << p.x << "," << p.y;
    EXPECT_LE(q.y, 1.0f + 1e-6f) << p.x << "," << p.y;
  }
}

TEST(UvTransformTest, OffsetAndScaleAlone) {
  // The spec's second example: offset [0, 1], scale [1, -1] flips V.
  TextureRef t;
  t.offset = glm::vec2(0, 1);
  t.scale = glm::vec2(1, -1);
  const glm::vec2 q = Apply(t.uv_transform(), glm::vec2(0.25f, 0.1f));
  EXPECT_NEAR(q.x, 0.25f, 1e-6f);
  EXPECT_NEAR(q.y, 0.9f, 1e-6f);
}

}  // namespace
}  // namespace tessera
