#version 460
#extension GL_GOOGLE_include_directive : require
// Bloom's downsample as a fragment shader (common/bloom_down.glsl).
#include "common/bloom_down.glsl"

void main() { PostMain(); }
