#version 460
#extension GL_GOOGLE_include_directive : require
// The visibility pass, opaque geometry, vertices pulled (common/vis_pull.glsl): each sample
// stores its drawable and the triangle the vertex shader passed on.
#include "common/scene.glsl"

layout(location = 5) flat in uint v_drawable;
layout(location = 6) flat in uint v_triangle;
layout(location = 0) out uint out_id;

void main() { out_id = ((v_drawable + 1u) << frame.aa.x) | v_triangle; }
