#version 460
#extension GL_GOOGLE_include_directive : require
// Drawable-id pass: writes drawable + 1 where the surface is at the frame's depth (tested
// against it, no writes), with the alpha-mask test of the depth prepass.
#include "common/scene.glsl"
#include "common/textures.glsl"

layout(location = 3) in vec2 v_uv0;
layout(location = 4) in vec2 v_uv1;
layout(location = 6) in vec4 v_color;  // COLOR_0: its alpha is cut out too
layout(location = 5) flat in uint v_drawable;
layout(location = 0) out uint out_id;

void main() {
  if (material.flags.x == kAlphaMask && CutOut(v_uv0, v_uv1, v_color.a)) discard;
  out_id = v_drawable + 1u;
}
