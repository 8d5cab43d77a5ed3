#version 460
#extension GL_GOOGLE_include_directive : require
// FXAA as a fragment shader into the sRGB target (common/fxaa.glsl).
#include "common/fxaa.glsl"

void main() { PostMain(); }
