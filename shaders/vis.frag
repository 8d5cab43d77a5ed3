#version 460
#extension GL_GOOGLE_include_directive : require
// vis_mlaa visibility pass, opaque geometry: each sample stores its drawable and triangle.
// (gl_PrimitiveID restarts at 0 with every draw, so it is the triangle within the drawable.)
#include "common/scene.glsl"

layout(location = 5) flat in uint v_drawable;
layout(location = 0) out uint out_id;

void main() { out_id = ((v_drawable + 1u) << frame.aa.x) | uint(gl_PrimitiveID); }
