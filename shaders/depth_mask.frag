#version 460
#extension GL_GOOGLE_include_directive : require
// Depth prepass for alpha-mask materials: discard where alpha is below the cutoff.
#include "common/scene.glsl"
#include "common/textures.glsl"

layout(location = 3) in vec2 v_uv0;
layout(location = 4) in vec2 v_uv1;

void main() {
  if (CutOut(v_uv0, v_uv1)) discard;
}
