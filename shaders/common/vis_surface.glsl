// A visibility id's surface point, rebuilt from the scene's buffers: the camera ray through a
// point of the frame meets the triangle's plane at barycentrics that give every attribute, and
// the rays through the next pixel right and down (scene.glsl's RayDirection) give the uv gradients for texture filtering
// (there are no neighbouring fragments of the same triangle to difference). Shared by
// vis_mlaa's shading (vis_shade_mlaa.comp) and the visibility pipeline's (vis_shade.comp). Needs
// scene.glsl, textures.glsl and vis.glsl.
#ifndef TESSERA_VIS_SURFACE_GLSL
#define TESSERA_VIS_SURFACE_GLSL

// The surface of `tri` seen through `pixel` (framebuffer pixels), `b` its barycentrics there.
SurfaceInput VisSurface(Triangle tri, vec3 b, vec2 pixel) {
  mat4 world = DrawableWorld(tri.drawable);
  vec3 bx = Barycentrics(tri.p0, tri.e1, tri.e2, RayDirection(pixel + vec2(1.0, 0.0)));
  vec3 by = Barycentrics(tri.p0, tri.e1, tri.e2, RayDirection(pixel + vec2(0.0, 1.0)));
  uvec3 v = tri.v;
  vec4 uv_a = VertexUvs(v.x), uv_b = VertexUvs(v.y), uv_c = VertexUvs(v.z);
  // Gradients from the ray differentials; the attributes from the barycentrics clamped to the
  // triangle (a point outside it, e.g. vis_mlaa's mean sample position when no triangle of the
  // surface holds it, must not extrapolate across a uv seam into another part of an atlas).
  vec4 uv_dx = (bx.x - b.x) * uv_a + (bx.y - b.y) * uv_b + (bx.z - b.z) * uv_c;
  vec4 uv_dy = (by.x - b.x) * uv_a + (by.y - b.y) * uv_b + (by.z - b.z) * uv_c;
  b = max(b, vec3(0.0));
  b /= max(b.x + b.y + b.z, 1e-20);
  vec4 uv = b.x * uv_a + b.y * uv_b + b.z * uv_c;
  vec3 n = b.x * VertexNormal(v.x) + b.y * VertexNormal(v.y) + b.z * VertexNormal(v.z);
  vec4 t = b.x * VertexTangent(v.x) + b.y * VertexTangent(v.y) + b.z * VertexTangent(v.z);

  SurfaceInput s;
  s.world = tri.p0 + b.y * tri.e1 + b.z * tri.e2;
  s.normal = DrawableNormalMatrix(tri.drawable) * n;
  s.tangent = vec4(mat3(world) * t.xyz, VertexTangent(v.x).w * DrawableHandedness(tri.drawable));
  s.uv0 = uv.xy;
  s.uv1 = uv.zw;
  // Fetched only for the materials of primitives with COLOR_0 (GpuMaterial::flags.w).
  s.color = material.flags.w != 0u
                ? b.x * VertexColor(v.x) + b.y * VertexColor(v.y) + b.z * VertexColor(v.z)
                : vec4(1.0);
  s.grads = UvGradients(uv_dx, uv_dy);
  // glTF front faces wind counter-clockwise as seen from the camera.
  s.front_facing = dot(cross(tri.e1, tri.e2), frame.camera_position.xyz - tri.p0) > 0.0;
  return s;
}
#endif
