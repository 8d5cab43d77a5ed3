#version 460
#extension GL_GOOGLE_include_directive : require
#include "common/gpu_types.h"
// Shadow maps: positions only, through the shadow view's matrix (a push constant, so one
// pipeline draws every view of the atlas).
#include "common/scene.glsl"

layout(push_constant) uniform Push { TS_PUSH_SHADOW } push;  // common/gpu_types.h
layout(location = kAttrPosition) in vec3 in_position;

void main() {
  gl_Position = push.view_proj * (drawables[gl_InstanceIndex].world * vec4(in_position, 1.0));
}
