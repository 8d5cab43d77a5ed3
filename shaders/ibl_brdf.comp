#version 460
#extension GL_GOOGLE_include_directive : require
// The split-sum table as RG16F (common/ibl_brdf.glsl).
#include "common/ibl_brdf.glsl"
