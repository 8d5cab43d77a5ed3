#version 460
#extension GL_GOOGLE_include_directive : require
// Drawable-id pass (tests: which drawables are truly visible): position and uvs, and the
// drawable index from gl_InstanceIndex (= firstInstance).
#include "common/scene.glsl"

layout(location = kAttrPosition) in vec3 in_position;
layout(location = kAttrUv0) in vec2 in_uv0;
layout(location = kAttrUv1) in vec2 in_uv1;
layout(location = kAttrColor) in uvec2 in_color;  // COLOR_0 as four halves

layout(location = 3) out vec2 v_uv0;
layout(location = 4) out vec2 v_uv1;
layout(location = 6) out vec4 v_color;
layout(location = 5) flat out uint v_drawable;

void main() {
  gl_Position = ClipPosition(drawables[gl_InstanceIndex].world, in_position);
  v_uv0 = in_uv0;
  v_uv1 = in_uv1;
  v_color = VertexColorOf(in_color);
  v_drawable = gl_InstanceIndex;
}
