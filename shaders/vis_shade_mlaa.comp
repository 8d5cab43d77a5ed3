#version 460
#extension GL_GOOGLE_include_directive : require
// vis_mlaa's shading, at the mean position of the shaded surface's samples
// (common/vis_shade.glsl).
#define VIS_MLAA
#include "common/vis_shade.glsl"
