#version 460
#extension GL_GOOGLE_include_directive : require
// The classification's scan (common/vis_classify.glsl, kClassifyScan): one workgroup, for both
// pipelines (vis_mlaa's lists follow its edge and blend lists: ShadePush params.z) and every way
// of appending.
#define VIS_CLASSIFY_SCAN
#include "common/vis_classify.glsl"
