#include "renderer/camera.h"

#include <algorithm>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>
#include <limits>

#include "absl/strings/str_cat.h"

namespace tessera {

namespace {
bool Finite(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}
}  // namespace

absl::Status ValidateCamera(const Camera& c) {
  auto bad = [](const char* field, const char* why) {
    return absl::InvalidArgumentError(absl::StrCat("camera.", field, ": ", why));
  };
  if (c.view) {
    for (int i = 0; i < 4; ++i)
      if (!Finite(glm::vec3((*c.view)[i])) || !std::isfinite((*c.view)[i].w))
        return bad("view", "matrix has non-finite values");
    if (std::abs(glm::determinant(*c.view)) < 1e-12f) return bad("view", "matrix is singular");
  } else {
    if (!Finite(c.eye)) return bad("eye", "non-finite");
    if (!Finite(c.target)) return bad("target", "non-finite");
    if (!Finite(c.up)) return bad("up", "non-finite");
    const glm::vec3 d = c.target - c.eye;
    if (glm::length(d) < 1e-6f) return bad("target", "equals eye");
    if (glm::length(glm::cross(glm::normalize(d), c.up)) < 1e-6f)
      return bad("up", "is zero or parallel to the view direction");
  }
  if (!std::isfinite(c.yfov) || c.yfov <= 0.0f || c.yfov >= 3.1f)
    return bad("yfov", "must be in (0, 3.1) radians");
  if (!std::isfinite(c.znear) || c.znear <= 0.0f) return bad("znear", "must be > 0");
  if (!std::isfinite(c.zfar) || (c.zfar != 0.0f && c.zfar <= c.znear))
    return bad("zfar", "must be 0 (infinite) or > znear");
  return absl::OkStatus();
}

glm::mat4 ViewMatrix(const Camera& c) {
  if (c.view) return *c.view;
  return glm::lookAtRH(c.eye, c.target, c.up);
}

glm::mat4 ProjectionMatrix(const Camera& c, float aspect) {
  const float f = 1.0f / std::tan(c.yfov * 0.5f);
  const float n = c.znear;
  glm::mat4 p(0.0f);
  p[0][0] = f / aspect;
  p[1][1] = -f;  // Vulkan clip space has Y down
  p[2][3] = -1.0f;
  if (c.zfar == 0.0f) {
    // Infinite reverse Z: depth = n / -z_view.
    p[3][2] = n;
  } else {
    const float fz = c.zfar;
    p[2][2] = n / (fz - n);
    p[3][2] = n * fz / (fz - n);
  }
  return p;
}

glm::vec3 CameraPosition(const Camera& c) {
  if (c.view) return glm::vec3(glm::inverse(*c.view)[3]);
  return c.eye;
}

PixelRays PixelRaysFor(const glm::mat4& view_proj, uint32_t width, uint32_t height) {
  const glm::dmat4 inv = glm::inverse(glm::dmat4(view_proj));
  // The centre of projection: the point the matrix sends to clip (0, 0, z, 0).
  const glm::dvec4 centre = inv * glm::dvec4(0.0, 0.0, 1.0, 0.0);
  const glm::dvec3 from = glm::dvec3(centre) / centre.w;
  const double w = double(width), h = double(height);
  auto ray = [&](double x, double y) {
    const glm::dvec4 p = inv * glm::dvec4(x / w * 2.0 - 1.0, y / h * 2.0 - 1.0, 1.0, 1.0);
    return glm::dvec3(p) / p.w - from;
  };
  const glm::dvec3 origin = ray(0.0, 0.0);
  return {glm::vec3(origin), glm::vec3((ray(w, 0.0) - origin) / w),
          glm::vec3((ray(0.0, h) - origin) / h)};
}

Camera FrameBounds(const Aabb& bounds, float yfov, float aspect, glm::vec3 direction) {
  Camera cam;
  cam.yfov = yfov;
  const glm::vec3 center = bounds.empty() ? glm::vec3(0.0f) : bounds.center();
  const Aabb box = bounds.empty() ? Aabb{glm::vec3(-1.0f), glm::vec3(1.0f)} : bounds;
  const glm::vec3 back = glm::normalize(direction);  // from the scene towards the camera
  glm::vec3 up(0.0f, 1.0f, 0.0f);
  if (glm::length(glm::cross(back, up)) < 1e-3f) up = glm::vec3(0.0f, 0.0f, -1.0f);
  const glm::vec3 right = glm::normalize(glm::cross(up, back));
  const glm::vec3 true_up = glm::cross(back, right);
  // The nearest distance along `back` at which every corner of the box is inside both fields of
  // view: a corner at lateral offsets (x, y) and depth offset z (towards the camera) needs
  // d >= z + |x| / tan(half_xfov) and d >= z + |y| / tan(half_yfov).
  const float tan_y = std::tan(yfov * 0.5f);
  const float tan_x = tan_y * aspect;
  float distance = 0.0f, nearest = std::numeric_limits<float>::max();
  for (int i = 0; i < 8; ++i) {
    const glm::vec3 o = box.corner(i) - center;
    const float z = glm::dot(o, back);
    distance = std::max({distance, z + std::abs(glm::dot(o, right)) / tan_x,
                         z + std::abs(glm::dot(o, true_up)) / tan_y});
    nearest = std::min(nearest, -z);
  }
  distance *= 1.05f;  // a small margin around the object
  // Keep the eye distinguishable from the target in float even far from the origin.
  const float magnitude = std::max({std::abs(center.x), std::abs(center.y), std::abs(center.z)});
  distance = std::max({distance, 1e-3f, 1e-5f * magnitude});
  cam.target = center;
  cam.eye = center + back * distance;
  cam.up = up;
  // Nearest corner depth from the camera, halved for margin; reverse Z keeps precision anyway.
  cam.znear = std::max((distance + nearest) * 0.5f, distance * 0.01f);
  cam.zfar = 0.0f;
  return cam;
}

Camera FromSceneCamera(const SceneCamera& sc, int32_t index) {
  Camera cam;
  cam.scene_camera = index;
  cam.view = glm::inverse(sc.world);
  cam.yfov = sc.yfov;
  cam.znear = sc.znear > 0.0f ? sc.znear : 0.01f;
  cam.zfar = sc.zfar > cam.znear ? sc.zfar : 0.0f;
  return cam;
}

Frustum FrustumFromViewProj(const glm::mat4& m) {
  // Gribb-Hartmann: rows of the matrix. Clip volume: -w<=x<=w, -w<=y<=w, 0<=z<=w.
  const glm::vec4 r0(m[0][0], m[1][0], m[2][0], m[3][0]);
  const glm::vec4 r1(m[0][1], m[1][1], m[2][1], m[3][1]);
  const glm::vec4 r2(m[0][2], m[1][2], m[2][2], m[3][2]);
  const glm::vec4 r3(m[0][3], m[1][3], m[2][3], m[3][3]);
  Frustum f = {r3 + r0, r3 - r0, r3 + r1, r3 - r1, r2, r3 - r2};
  for (glm::vec4& p : f) {
    const float len = glm::length(glm::vec3(p));
    if (len > 0.0f) p /= len;
  }
  return f;
}

bool AabbIntersectsFrustum(const Aabb& box, const Frustum& frustum) {
  if (box.empty()) return false;
  for (const glm::vec4& p : frustum) {
    const glm::vec3 n(p);
    // The box corner furthest along the plane normal.
    const glm::vec3 v(n.x >= 0 ? box.max.x : box.min.x, n.y >= 0 ? box.max.y : box.min.y,
                      n.z >= 0 ? box.max.z : box.min.z);
    if (glm::dot(n, v) + p.w < 0.0f) return false;
  }
  return true;
}

}  // namespace tessera
