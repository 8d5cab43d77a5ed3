#version 460
#extension GL_GOOGLE_include_directive : require
// The visibility pass, alpha-mask geometry, vertices pulled (common/vis_pull.glsl).
#define VIS_PULL_UVS
#include "common/vis_pull.glsl"
