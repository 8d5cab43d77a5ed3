#version 460
#extension GL_GOOGLE_include_directive : require
// The visibility pipeline's shading, one sample per pixel (common/vis_shade.glsl).
#include "common/vis_shade.glsl"
