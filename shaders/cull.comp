#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
// Geometry culling with the chunk's prefix sum in subgroup arithmetic (common/cull.glsl).
#define CULL_SUBGROUP_SCAN
#include "common/cull.glsl"
