#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
// vis_mlaa's resolve, counting one atomic per subgroup and material (common/vis_resolve.glsl).
#define SHADE_APPEND_SUBGROUPS
#include "common/vis_resolve.glsl"
