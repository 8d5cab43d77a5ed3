#pragma once
// Camera description and the math around it: view and reverse-Z projection matrices, framing
// a scene's bounds, and view-frustum planes for culling. Pure math, no Vulkan.
#include <array>
#include <glm/glm.hpp>
#include <optional>

#include "absl/status/status.h"
#include "renderer/scene/cpu_scene.h"

namespace tessera {

struct Camera {
  glm::vec3 eye{0.0f, 0.0f, 5.0f};
  glm::vec3 target{0.0f};
  glm::vec3 up{0.0f, 1.0f, 0.0f};
  std::optional<glm::mat4> view;  // world -> view; when set, eye/target/up are ignored
  float yfov = 0.8f;              // vertical field of view, radians, (0, pi)
  float znear = 0.05f;            // > 0, world units
  float zfar = 0.0f;              // 0 = infinite; else > znear
  // The file's camera this is (SceneInfo::cameras, FromSceneCamera's index), or -1. In an
  // animated scene whose animation moves that camera's node, the frame's pose places `view`.
  int32_t scene_camera = -1;
};

// INVALID_ARGUMENT naming the field: non-finite values, eye == target, up parallel to the view
// direction, fov out of range, near <= 0, far <= near.
absl::Status ValidateCamera(const Camera& camera);

// World -> view (right-handed, looking down -Z).
glm::mat4 ViewMatrix(const Camera& camera);

// View -> Vulkan clip space with reverse Z (near plane at depth 1, far or infinity at 0) and
// Y pointing down in clip space, so glTF's counter-clockwise front faces stay front faces.
glm::mat4 ProjectionMatrix(const Camera& camera, float aspect);

// The camera's world position (from eye, or from the inverse of `view`).
glm::vec3 CameraPosition(const Camera& camera);

// The camera ray through a point of a width x height frame (framebuffer pixels, y down): from
// the centre of projection of `view_proj` (reverse Z) to the point's place on its near plane.
// A perspective projection's w is the same all over the near plane, so the ray is affine in
// the pixel: ray(x, y) = origin + x * dx + y * dy, computed here in double precision. The
// shaders read it from FrameUniforms (shaders/common/scene.glsl's RayDirection) instead of
// unprojecting each pixel through the inverse view-projection and subtracting the camera's
// position, which cost lavapipe's visibility classification about 10 ms of a 1280x720 frame.
// The rays start at the matrix's own centre rather than the camera's position: a float
// view-projection 1 km from the origin has its centre about 0.1 mm off the eye, which tilts
// rays aimed at a near plane 5 cm away by pixels (the shaders cast them from the camera's
// position; that offset then moves a hit by 0.1 mm / its distance).
struct PixelRays {
  glm::vec3 origin;  // the ray through the frame's corner (0, 0)
  glm::vec3 dx;      // its change per pixel right
  glm::vec3 dy;      // and down
};
PixelRays PixelRaysFor(const glm::mat4& view_proj, uint32_t width, uint32_t height);

// A camera looking at the centre of `bounds` from `direction` (pointing from the scene towards
// the camera), at the nearest distance where all eight corners of the box are in view (plus 5%).
Camera FrameBounds(const Aabb& bounds, float yfov, float aspect,
                   glm::vec3 direction = glm::vec3(0.55f, 0.45f, 0.70f));

// The camera of a glTF camera node (its world matrix is camera -> world).
// `index`: the camera's place in SceneInfo::cameras, kept as Camera::scene_camera so an
// animated scene can pose it (-1: not one of the scene's).
Camera FromSceneCamera(const SceneCamera& camera, int32_t index = -1);

// Frustum planes (xyz normal pointing inside, w distance) from a view-projection matrix with
// reverse Z; an infinite far plane gives a degenerate far plane that rejects nothing.
using Frustum = std::array<glm::vec4, 6>;
Frustum FrustumFromViewProj(const glm::mat4& view_proj);

// False when the box lies entirely outside one plane (conservative: may keep boxes that are
// outside near a frustum corner).
bool AabbIntersectsFrustum(const Aabb& box, const Frustum& frustum);

}  // namespace tessera
