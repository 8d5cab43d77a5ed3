#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_EXT_nonuniform_qualifier : require
// The visibility pipeline's shading in one dispatch over every pixel, where the device indexes
// sampler arrays (common/vis_shade.glsl, SHADE_ALL_MATERIALS).
#define SHADE_ALL_MATERIALS
#define SHADE_APPEND_SUBGROUPS
#include "common/vis_shade.glsl"
