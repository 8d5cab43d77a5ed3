#version 460
#extension GL_GOOGLE_include_directive : require
// Scene vertex shader of the shading passes (and of the alpha-mask depth prepass). The
// drawable comes from gl_InstanceIndex (= firstInstance of the draw).
#include "common/scene.glsl"

layout(location = kAttrPosition) in vec3 in_position;
layout(location = kAttrNormal) in vec3 in_normal;
layout(location = kAttrTangent) in vec4 in_tangent;
layout(location = kAttrUv0) in vec2 in_uv0;
layout(location = kAttrUv1) in vec2 in_uv1;
layout(location = kAttrColor) in uvec2 in_color;  // COLOR_0 as four halves

layout(location = 0) out vec3 v_world;
layout(location = 1) out vec3 v_normal;
layout(location = 2) out vec4 v_tangent;
layout(location = 3) out vec2 v_uv0;
layout(location = 4) out vec2 v_uv1;
layout(location = 6) out vec4 v_color;  // the mask passes' too

void main() {
  mat4 world = drawables[gl_InstanceIndex].world;
  gl_Position = ClipPosition(world, in_position);
  v_world = (world * vec4(in_position, 1.0)).xyz;
  v_normal = mat3(drawables[gl_InstanceIndex].normal_matrix) * in_normal;
  // A mirrored drawable's tangent frame has the other handedness (normal_matrix[3][3]: -1).
  v_tangent = vec4(mat3(world) * in_tangent.xyz,
                   in_tangent.w * drawables[gl_InstanceIndex].normal_matrix[3][3]);
  v_uv0 = in_uv0;
  v_uv1 = in_uv1;
  v_color = VertexColorOf(in_color);
}
