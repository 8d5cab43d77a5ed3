#version 460
#extension GL_GOOGLE_include_directive : require
// The visibility pass, opaque geometry, vertices pulled (common/vis_pull.glsl): each sample
// stores the id (drawable and triangle) the vertex shader passed on.
#include "common/scene.glsl"

layout(location = 5) flat in uint v_id;
layout(location = 0) out uint out_id;

void main() { out_id = v_id; }
