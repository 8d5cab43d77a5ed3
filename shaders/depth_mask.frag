#version 460
#extension GL_GOOGLE_include_directive : require
// Depth prepass for alpha-mask materials: discard where alpha is below the cutoff.
#include "common/scene.glsl"
#include "common/textures.glsl"

layout(location = 3) in vec2 v_uv0;
layout(location = 4) in vec2 v_uv1;
layout(location = 6) in vec4 v_color;  // COLOR_0: its alpha is cut out too

void main() {
  if (CutOut(v_uv0, v_uv1, v_color.a)) discard;
}
