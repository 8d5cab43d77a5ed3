#version 460
#extension GL_GOOGLE_include_directive : require
// The visibility pipeline's background (common/vis_sky.glsl).
#include "common/vis_sky.glsl"
