#version 460
#extension GL_GOOGLE_include_directive : require
// GPU light binning, step 2: the lights binned by tile row, one workgroup per row. The workgroup
// walks the lights in index order, kLightCullGroupSize at a time, and compacts the ones whose
// tile rectangle covers its row with a prefix sum in shared memory (no subgroup operations
// needed), so every row list is sorted and frames are reproducible, as BinLightsByRow's on the
// CPU. Row r's list has room for every light: it starts at 2 * rows + r * lights; entries 2r and
// 2r + 1 say where it begins and ends (light_cull.comp reads the same layout from either).
#include "common/gpu_types.h"

layout(local_size_x = kLightCullGroupSize) in;

layout(set = 0, binding = kCullBindingFrame, std140) uniform FrameBlock { FrameUniforms frame; };
layout(set = 0, binding = kCullBindingLightBounds, std430) readonly buffer BoundsBlock {
  GpuLightBounds light_bounds[];
};
layout(set = 0, binding = kCullBindingRowLights, std430) writeonly buffer RowBlock {
  uint row_lights[];
};

shared uint scan[kLightCullGroupSize];

void main() {
  uint row = gl_WorkGroupID.x;
  uint rows = uint(frame.depth_params.z);
  uint lights = frame.lighting.x;
  uint lid = gl_LocalInvocationIndex;
  uint list = 2u * rows + row * lights;
  uint count = 0u;  // the same in every invocation
  for (uint first = 0u; first < lights; first += kLightCullGroupSize) {
    uint i = first + lid;
    bool hit = false;
    if (i < lights) {
      ivec4 t = light_bounds[i].tiles;
      hit = t.x <= t.z && t.y <= int(row) && int(row) <= t.w;
    }
    scan[lid] = hit ? 1u : 0u;
    barrier();
    for (uint offset = 1u; offset < kLightCullGroupSize; offset <<= 1) {  // inclusive scan
      uint v = lid >= offset ? scan[lid - offset] : 0u;
      barrier();
      scan[lid] += v;
      barrier();
    }
    if (hit) row_lights[list + count + scan[lid] - 1u] = i;
    count += scan[kLightCullGroupSize - 1u];
    barrier();  // everyone has read the totals before the next chunk writes
  }
  if (lid == 0u) {
    row_lights[2u * row] = list;
    row_lights[2u * row + 1u] = list + count;
  }
}
