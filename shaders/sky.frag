#version 460
#extension GL_GOOGLE_include_directive : require
// Background: drawn as a full-screen triangle at the far plane (depth 0 in reverse Z) after the
// opaque geometry, so only pixels no surface covered run this shader.
#include "common/scene.glsl"
#include "common/sky.glsl"

layout(location = 0) in vec2 v_uv;
layout(location = 0) out vec4 out_color;

void main() {
  vec4 world = frame.inv_view_proj * vec4(v_uv * 2.0 - 1.0, 1.0, 1.0);  // on the near plane
  vec3 dir = normalize(world.xyz / world.w - frame.camera_position.xyz);
  out_color = vec4(SkyRadiance(dir), 1.0);
}
