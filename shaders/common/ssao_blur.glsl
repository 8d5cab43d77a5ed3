#include "common/gpu_types.h"
#include "common/post_io.glsl"
// One direction of the separable bilateral blur of ssao.frag's output (run horizontally, then
// vertically). AO and view distance share a texel (RGBA16F), so each tap is one fetch.
//
// 9 taps (radius 4) with gaussian weights, each times a depth weight that falls linearly to 0
// as the tap's distance departs from the centre's by 1 / sharpness of the centre distance: the
// blur removes SAO's per-pixel rotation noise without bleeding AO across silhouettes.
// Output: r = blurred visibility, g = the centre's distance unchanged (the next pass needs it);
// sky centres (g == 0) pass through as (1, 0), sky taps never count for non-sky centres.
// RGBA16F: r visibility, g view distance (0: sky); NEAREST sampler (texelFetch only).
layout(set = 0, binding = 0) uniform sampler2D u_ao;
layout(push_constant) uniform Push { TS_PUSH_SSAO_BLUR } push;  // common/gpu_types.h
POST_IO(out_ao)  // from fullscreen.vert; unused: pixels come from gl_FragCoord

const int kRadius = 4;  // taps each side of the centre
// Gaussian weights for offsets 0..4 (SAO's blur kernel, sigma ~ 2.6; they sum to 1 over 9 taps).
const float kGaussian[kRadius + 1] = float[](0.153170, 0.144893, 0.122649, 0.092902, 0.062970);

void PostMain() {
  ivec2 pixel = ivec2(FRAG_COORD);
  ivec2 last = push.dir.zw - 1;
  vec2 center = texelFetch(u_ao, pixel, 0).rg;
  float z = center.g;
  if (!(z > 0.0)) {  // sky
    out_ao = vec4(1.0, 0.0, 0.0, 0.0);
    return;
  }
  // Depth weight per unit of |dz|; max() guards a centre distance that rounded to ~0.
  float depth_scale = push.params.x / max(z, 1e-4);

  float sum = center.r * kGaussian[0];
  float total = kGaussian[0];
  for (int i = -kRadius; i <= kRadius; ++i) {
    if (i == 0) continue;
    vec2 tap = texelFetch(u_ao, clamp(pixel + i * push.dir.xy, ivec2(0), last), 0).rg;
    // Sky taps (g == 0) never count: with a sharpness below 1 the depth weight alone would
    // let them in.
    float w = tap.g > 0.0 ? kGaussian[abs(i)] * max(0.0, 1.0 - depth_scale * abs(tap.g - z)) : 0.0;
    sum += tap.r * w;
    total += w;
  }
  out_ao = vec4(sum / total, z, 0.0, 0.0);  // total >= the centre's weight > 0
}
