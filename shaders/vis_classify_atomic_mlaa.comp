#version 460
#extension GL_GOOGLE_include_directive : require
// vis_mlaa's classification, one atomic per pixel, with the runner-up surfaces: for devices
// whose compute shaders lack subgroup ballots (common/vis_classify.glsl).
#define VIS_MLAA
#include "common/vis_classify.glsl"
