#version 460
#extension GL_GOOGLE_include_directive : require
// vis_mlaa's resolve, counting one atomic per pixel: for devices whose compute shaders lack
// subgroup ballots (common/vis_resolve.glsl).
#include "common/vis_resolve.glsl"
