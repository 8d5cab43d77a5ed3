#version 460
#extension GL_GOOGLE_include_directive : require
// Geometry culling with the chunk's prefix sum in shared memory, for devices whose compute
// shaders lack subgroup arithmetic (common/cull.glsl).
#include "common/cull.glsl"
