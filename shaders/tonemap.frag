#version 460
#extension GL_GOOGLE_include_directive : require
// The tonemap as a fragment shader into the sRGB target (common/tonemap.glsl).
#include "common/tonemap.glsl"

void main() { PostMain(); }
