#version 460
#extension GL_GOOGLE_include_directive : require
// Bloom's upsample as a fragment shader (common/bloom_up.glsl).
#include "common/bloom_up.glsl"

void main() { PostMain(); }
