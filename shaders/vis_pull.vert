#version 460
#extension GL_GOOGLE_include_directive : require
// The visibility pass, opaque geometry, vertices pulled (common/vis_pull.glsl).
#include "common/vis_pull.glsl"
