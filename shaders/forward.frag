#version 460
#extension GL_GOOGLE_include_directive : require
// Forward PBR shading of one rasterized surface (common/shading.glsl has the BRDF and lights).
#include "common/scene.glsl"
#include "common/sky.glsl"
#include "common/textures.glsl"
#include "common/shadows.glsl"
#include "common/shading.glsl"

layout(location = 0) in vec3 v_world;
layout(location = 1) in vec3 v_normal;
layout(location = 2) in vec4 v_tangent;
layout(location = 3) in vec2 v_uv0;
layout(location = 4) in vec2 v_uv1;
layout(location = 6) in vec4 v_color;

layout(location = 0) out vec4 out_color;

void main() {
  SurfaceInput s = SurfaceInput(v_world, v_normal, v_tangent, v_uv0, v_uv1, v_color,
                                ComputeUvGradients(v_uv0, v_uv1), gl_FrontFacing);
  out_color = ShadeSurface(s, true);
}
