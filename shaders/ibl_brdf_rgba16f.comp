#version 460
#extension GL_GOOGLE_include_directive : require
// The split-sum table as RGBA16F, for devices without R16G16_SFLOAT storage images
// (common/ibl_brdf.glsl).
#define IBL_LUT_RGBA16F
#include "common/ibl_brdf.glsl"
