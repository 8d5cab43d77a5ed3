#version 460
#extension GL_GOOGLE_include_directive : require
// vis_mlaa visibility pass, opaque geometry: positions only, and the drawable (firstInstance).
#include "common/scene.glsl"

layout(location = kAttrPosition) in vec3 in_position;
layout(location = 5) flat out uint v_drawable;

void main() {
  gl_Position = ClipPosition(drawables[gl_InstanceIndex].world, in_position);
  v_drawable = gl_InstanceIndex;
}
