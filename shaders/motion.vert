#version 460
#extension GL_GOOGLE_include_directive : require
// TAA's object motion (renderer/features/motion.cpp): an animated drawable drawn again against
// the frame's depth, with where each point was in last frame's pose as last frame's camera saw
// it, and where it would have been had it not moved. gl_Position is the depth pass's, exactly
// (ClipPosition), so the depth test finds the visible surface.
#include "common/scene.glsl"

layout(location = kAttrPosition) in vec3 in_position;
layout(location = kAttrUv0) in vec2 in_uv0;
layout(location = kAttrUv1) in vec2 in_uv1;
layout(location = kAttrColor) in uvec2 in_color;  // COLOR_0 as four halves

// The view's kept copy of the deformed vertices as its last frame saw them (Vertex layout).
layout(set = 2, binding = 0, std430) readonly buffer KeptBlock { float kept[]; };
layout(push_constant) uniform Push { TS_PUSH_MOTION } push;  // common/gpu_types.h

layout(location = 0) out vec4 v_prev_clip;    // last frame's clip position of the point
layout(location = 1) out vec4 v_still_clip;   // the same, had the point not moved
layout(location = 3) out vec2 v_uv0;
layout(location = 4) out vec2 v_uv1;
layout(location = 6) out vec4 v_color;

void main() {
  mat4 world = drawables[gl_InstanceIndex].world;
  gl_Position = ClipPosition(world, in_position);
  vec3 prev = in_position;
  if (push.kept.y != 0u) {
    uint b = (uint(gl_VertexIndex) - push.kept.x) * kVertexFloats;
    prev = vec3(kept[b], kept[b + 1u], kept[b + 2u]);
  }
  v_prev_clip = frame.prev_view_proj * (push.prev_world * vec4(prev, 1.0));
  v_still_clip = frame.prev_view_proj * (world * vec4(in_position, 1.0));
  v_uv0 = in_uv0;
  v_uv1 = in_uv1;
  v_color = VertexColorOf(in_color);
}
