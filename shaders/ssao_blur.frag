#version 460
#extension GL_GOOGLE_include_directive : require
// SSAO's blur as a fragment shader (common/ssao_blur.glsl).
#include "common/ssao_blur.glsl"

void main() { PostMain(); }
