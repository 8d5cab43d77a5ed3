#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
// vis_mlaa's resolve with vis_mlaa_coverage analytic: the samples' ids from the one-sample
// visibility buffer and the neighbours' triangles, counting one atomic per subgroup and material (common/vis_resolve.glsl).
#define SHADE_APPEND_SUBGROUPS
#define VIS_RESOLVE_ANALYTIC
#include "common/vis_resolve.glsl"
