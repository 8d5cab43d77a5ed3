#version 460
#extension GL_GOOGLE_include_directive : require
#include "common/gpu_types.h"
// Shadow maps of alpha-mask materials: shadow.vert plus the texture coordinates that
// depth_mask.frag tests the base colour's alpha with.
#include "common/scene.glsl"

layout(push_constant) uniform Push { TS_PUSH_SHADOW } push;  // common/gpu_types.h
layout(location = kAttrPosition) in vec3 in_position;
layout(location = kAttrUv0) in vec2 in_uv0;
layout(location = kAttrUv1) in vec2 in_uv1;
layout(location = kAttrColor) in uvec2 in_color;  // COLOR_0 as four halves
layout(location = 3) out vec2 v_uv0;
layout(location = 4) out vec2 v_uv1;
layout(location = 6) out vec4 v_color;

void main() {
  gl_Position = push.view_proj * (drawables[gl_InstanceIndex].world * vec4(in_position, 1.0));
  v_uv0 = in_uv0;
  v_uv1 = in_uv1;
  v_color = VertexColorOf(in_color);
}
