#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
// The visibility pipeline's classification, one atomic per subgroup and material
// (common/vis_classify.glsl).
#define SHADE_APPEND_SUBGROUPS
#include "common/vis_classify.glsl"
