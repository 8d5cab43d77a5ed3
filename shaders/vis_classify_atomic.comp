#version 460
#extension GL_GOOGLE_include_directive : require
// The visibility pipeline's classification, one atomic per pixel: for devices whose compute
// shaders lack subgroup ballots (common/vis_classify.glsl).
#include "common/vis_classify.glsl"
