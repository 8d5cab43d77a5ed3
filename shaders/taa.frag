#version 460
#extension GL_GOOGLE_include_directive : require
// TAA as a fragment shader (common/taa.glsl).
#include "common/taa.glsl"

void main() { PostMain(); }
