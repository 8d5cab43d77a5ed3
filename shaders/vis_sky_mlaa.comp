#version 460
#extension GL_GOOGLE_include_directive : require
// vis_mlaa's background, with the runner-up surfaces that are the sky (common/vis_sky.glsl).
#define VIS_MLAA
#include "common/vis_sky.glsl"
