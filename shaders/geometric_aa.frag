#version 460
#extension GL_GOOGLE_include_directive : require
// vis_mlaa's geometric AA as a fragment shader (common/geometric_aa.glsl).
#include "common/geometric_aa.glsl"

void main() { PostMain(); }
