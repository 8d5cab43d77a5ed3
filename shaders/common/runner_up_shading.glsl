// vis_mlaa's shading of runner-up surfaces (common/vis_shade.glsl, common/vis_sky.glsl): the
// resolve's records and the edge colours the shaded ones are written into, per edge list entry.
#ifndef TESSERA_RUNNER_UP_SHADING_GLSL
#define TESSERA_RUNNER_UP_SHADING_GLSL
#include "gpu_types.h"
#include "runner_up.glsl"

layout(set = kVisSet, binding = kShadeBindingRunnerUps, std430) readonly buffer RunnerUpBlock {
  uvec2 runner_ups[];  // the id to shade, PackRunnerUp
};
layout(set = kVisSet, binding = kShadeBindingEdgeColors, std430) writeonly buffer EdgeColorBlock {
  uvec2 edge_colors[];  // RGBA16F, packed
};

void StoreRunnerUpColor(uint entry, vec3 color) {
  edge_colors[entry] = uvec2(packHalf2x16(color.rg), packHalf2x16(vec2(color.b, 1.0)));
}
#endif
