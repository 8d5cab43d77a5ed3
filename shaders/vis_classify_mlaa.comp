#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
// vis_mlaa's classification, one atomic per subgroup and material, with the runner-up surfaces
// (common/vis_classify.glsl).
#define SHADE_APPEND_SUBGROUPS
#define VIS_MLAA
#include "common/vis_classify.glsl"
