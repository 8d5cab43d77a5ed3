#version 460
#extension GL_GOOGLE_include_directive : require
#include "common/gpu_types.h"
// Auto exposure: the average log2 luminance of the HDR frame, adapted over frames.
//
// One workgroup of 256 threads samples a grid of points spread evenly over the frame (up to
// 64 x 64). Each point is snapped to a texel corner, so one bilinear tap averages the 2x2
// pixels around it (4 pixels for the price of one). The log2 luminances (clamped, so that black
// or blown-out areas cannot drag the average arbitrarily far) are summed per thread, reduced in
// shared memory, and thread 0 moves the stored value towards this frame's average in log2 space
// (a geometric, i.e. perceptually even, adaptation).
layout(local_size_x = 256) in;

layout(set = 0, binding = 0) uniform sampler2D u_hdr;        // HDR frame, LINEAR, clamp to edge
layout(set = 0, binding = 1, r32f) uniform image2D u_state;  // 1x1: adapted average log2 luminance
layout(push_constant) uniform Push { TS_PUSH_EXPOSURE } push;  // common/gpu_types.h

const uint kThreads = 256;    // = local_size_x
const float kMinLum = 1e-5;   // luminance floor before log2 (black is -inf otherwise)

shared float s_sum[kThreads];

void main() {
  uint tid = gl_LocalInvocationIndex;
  uvec2 grid = push.size.zw;
  uint count = grid.x * grid.y;
  vec2 size = vec2(push.size.xy);
  float lo = push.params.y;
  float hi = push.params.z;

  float sum = 0.0;
  for (uint i = tid; i < count; i += kThreads) {
    uvec2 cell = uvec2(i % grid.x, i / grid.x);
    // The texel corner nearest the cell's centre, kept off the border so the tap's 2x2 pixels
    // are all inside (a 1-pixel axis reads its only pixel via clamp to edge).
    vec2 corner = clamp(floor((vec2(cell) + 0.5) / vec2(grid) * size + 0.5), vec2(1.0),
                        max(size - 1.0, vec2(1.0)));
    vec3 rgb = textureLod(u_hdr, corner / size, 0.0).rgb;
    float lum = dot(rgb, vec3(0.2126, 0.7152, 0.0722));  // Rec. 709
    lum = lum >= kMinLum ? lum : kMinLum;                  // also catches NaN (compare is false)
    sum += clamp(log2(lum), lo, hi);                       // +inf clamps to hi
  }
  s_sum[tid] = sum;
  barrier();
  for (uint stride = kThreads / 2u; stride > 0u; stride >>= 1u) {
    if (tid < stride) s_sum[tid] += s_sum[tid + stride];
    barrier();
  }

  if (tid == 0u) {
    float avg = s_sum[0] / float(max(count, 1u));  // an empty grid reads as log2 lum 0
    float rate = push.params.x;
    float result = avg;
    if (rate < 1.0) {
      // The stored value is only read when adapting: on the first frame (rate >= 1) it may be
      // uninitialised. A non-finite one (NaN, inf) restarts from this frame's value.
      float old = imageLoad(u_state, ivec2(0)).r;
      if (!isnan(old) && !isinf(old)) result = mix(clamp(old, lo, hi), avg, max(rate, 0.0));
    }
    imageStore(u_state, ivec2(0), vec4(result));
  }
}
