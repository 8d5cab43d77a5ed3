// The visibility shading's dispatches (vis_shade.glsl, vis_sky.glsl): the push constant (params.x:
// the entry dispatched for) and, read-only, the per-material entries and pixel lists that
// vis_classify wrote.
#ifndef TESSERA_SHADE_LISTS_GLSL
#define TESSERA_SHADE_LISTS_GLSL
#include "gpu_types.h"

layout(push_constant) uniform Push { TS_PUSH_SHADE } push;
layout(set = kVisSet, binding = kShadeBindingEntries, std430) readonly buffer EntryBlock {
  GpuShadeEntry entries[];
};
layout(set = kVisSet, binding = kShadeBindingPixels, std430) readonly buffer PixelBlock {
  uint pixels[];
};
#endif
