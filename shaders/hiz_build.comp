#version 460
#extension GL_GOOGLE_include_directive : require
// One level of the depth pyramid (HiZ) used by occlusion culling. Reverse Z: the farthest depth
// is the smallest value, so every texel holds the minimum of what it covers.
//  - Level 0 (push.mode 0) is the power of two at or below half the frame size; texel j covers
//    the depth pixels floor(j * W / w0) .. ceil((j + 1) * W / w0) - 1 (at most 5 per axis, since
//    W / w0 < 4), and reads each of them: nothing is skipped, so the test stays conservative.
//  - Level l > 0 (mode 1) halves level l - 1 exactly (power-of-two sizes): one bilinear tap of a
//    min-reduction sampler at the corner the 2x2 source texels share returns their minimum
//    (samplerFilterMinmax). The coordinate is exact in floating point, so no texel is missed.
//    Mode 2 does the same with four texel fetches, for devices without minmax filtering.
#include "common/gpu_types.h"

layout(local_size_x = kHizGroupSize, local_size_y = kHizGroupSize) in;

layout(set = 0, binding = kHizBindingSource) uniform sampler2D source;
layout(set = 0, binding = kHizBindingDest, r32f) uniform writeonly image2D dest;

layout(push_constant) uniform Push { TS_PUSH_HIZ } push;  // common/gpu_types.h

void main() {
  const uvec2 t = gl_GlobalInvocationID.xy;
  if (any(greaterThanEqual(t, push.dst_size))) return;
  float d;
  if (push.mode == 0u) {
    const uvec2 lo = t * push.src_size / push.dst_size;
    const uvec2 hi = min(((t + 1u) * push.src_size + push.dst_size - 1u) / push.dst_size,
                         push.src_size);
    d = 1.0;
    for (uint y = lo.y; y < hi.y; ++y)
      for (uint x = lo.x; x < hi.x; ++x) d = min(d, texelFetch(source, ivec2(x, y), 0).r);
  } else if (push.mode == 1u) {
    // The shared corner of source texels 2t .. 2t + 1 (or the centre of a 1-texel axis).
    const vec2 uv = (vec2(t) + 0.5) / vec2(push.dst_size);
    d = textureLod(source, uv, float(push.src_level)).r;
  } else {
    const ivec2 a = ivec2(min(t * 2u, push.src_size - 1u));
    const ivec2 b = ivec2(min(t * 2u + 1u, push.src_size - 1u));
    const int l = int(push.src_level);
    d = min(min(texelFetch(source, a, l).r, texelFetch(source, ivec2(b.x, a.y), l).r),
            min(texelFetch(source, ivec2(a.x, b.y), l).r, texelFetch(source, b, l).r));
  }
  imageStore(dest, ivec2(t), vec4(d));
}
