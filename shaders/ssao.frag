#version 460
#extension GL_GOOGLE_include_directive : require
// SSAO as a fragment shader (common/ssao.glsl).
#include "common/ssao.glsl"

void main() { PostMain(); }
