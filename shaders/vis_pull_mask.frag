#version 460
#extension GL_GOOGLE_include_directive : require
// The visibility pass, alpha-mask geometry, vertices pulled (common/vis_pull.glsl): the alpha
// test of the depth prepass, then the id the vertex shader passed on.
#include "common/scene.glsl"
#include "common/textures.glsl"

layout(location = 3) in vec2 v_uv0;
layout(location = 4) in vec2 v_uv1;
layout(location = 6) in vec4 v_color;  // COLOR_0: its alpha is cut out too
layout(location = 5) flat in uint v_id;
layout(location = 0) out uint out_id;

void main() {
  if (CutOut(v_uv0, v_uv1, v_color.a)) discard;
  out_id = v_id;
}
