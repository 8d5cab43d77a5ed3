#version 460
#extension GL_GOOGLE_include_directive : require
// Depth prepass for opaque geometry: positions only.
#include "common/scene.glsl"

layout(location = kAttrPosition) in vec3 in_position;

void main() { gl_Position = ClipPosition(drawables[gl_InstanceIndex].world, in_position); }
