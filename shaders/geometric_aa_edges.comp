#version 460
#extension GL_GOOGLE_include_directive : require
// vis_mlaa's geometric AA over the edge pixels only (common/geometric_aa.glsl), in place in the
// frame's HDR colour: every other pixel's surface owns all its samples and passes through, so the
// pass costs per edge, not per pixel of the frame. The resolve listed the edge pixels (the start
// of the pixel lists, entry push.edges, dispatched 64 to a workgroup); kGeometricAaBlend writes
// each one's blend into a list of colours (its neighbours are read unchanged), kGeometricAaWrite
// stores them into the image.
#define TESSERA_COMPUTE
#define GEOMETRIC_AA_EDGES
#include "common/geometric_aa.glsl"

layout(set = 0, binding = kGeometricAaBindingEntries, std430) readonly buffer EntryBlock {
  GpuShadeEntry entries[];
};
layout(set = 0, binding = kGeometricAaBindingPixels, std430) readonly buffer PixelBlock {
  uint pixels[];
};
layout(set = 0, binding = kGeometricAaBindingColors, std430) buffer ColorBlock {
  uvec2 colors[];  // RGBA16F, packed
};

void main() {
  uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  uint i = group * kShadeGroupSize + gl_LocalInvocationIndex;
  if (i >= entries[push.edges].dispatch.w) return;
  uint packed = pixels[i];
  ivec2 p = ivec2(packed & 0xffffu, packed >> 16);
  if (push.mode == kGeometricAaBlend) {
    vec4 c = GeometricAa(p);
    colors[i] = uvec2(packHalf2x16(c.rg), packHalf2x16(c.ba));
  } else {
    imageStore(u_hdr, p, vec4(unpackHalf2x16(colors[i].x), unpackHalf2x16(colors[i].y)));
  }
}
