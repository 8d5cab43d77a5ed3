#version 460
#extension GL_GOOGLE_include_directive : require
// vis_mlaa's resolve with vis_mlaa_coverage analytic: the samples' ids from the one-sample
// visibility buffer and the neighbours' triangles, counting one atomic per pixel (devices
// without subgroup ballots) (common/vis_resolve.glsl).
#define VIS_RESOLVE_ANALYTIC
#include "common/vis_resolve.glsl"
