#include "common/gpu_types.h"
#include "common/post_io.glsl"
// One level of the bloom upsample chain (Jimenez, SIGGRAPH 2014): the level below (already
// upsampled, half this size) filtered with a 3x3 tent while magnified, plus this level of the
// downsample chain. The tent (1 2 1 / 2 4 2 / 1 2 1, / 16) of bilinear taps hides the blocky
// 2x magnification that a single bilinear tap would leave; summing the levels builds the wide,
// smooth bloom falloff out of each level's blur. The tent's taps are one texel of the level below
// apart.
// The upsampled level below (half this size); LINEAR, clamp to edge.
layout(set = 0, binding = 0) uniform sampler2D u_low;
// This level of the downsample chain (the target's size); LINEAR.
layout(set = 0, binding = 1) uniform sampler2D u_this;
layout(push_constant) uniform Push { TS_PUSH_BLOOM_UP } push;  // common/gpu_types.h
POST_IO(out_color)  // from fullscreen.vert: the target pixel's centre

// The tent's nine bilinear taps one texel of u_low apart are four: along each axis they weigh
// the four texels around the point (i - 1 .. i + 2, where the point lies a fraction f past
// texel i's centre) by (1 - f, 2 - f, 1 + f, f) / 4, and each adjacent pair of those is one
// bilinear tap placed between its two by their weights (clamping to the edge picks the same
// texels either way). Half the fetches for the same sum (lavapipe: bloom's cost is its taps).
void PostMain() {
  vec2 texel = push.params.xy;              // one u_low texel in uv
  vec2 x = v_uv / texel - 0.5;              // in u_low texels, texel centres at integers
  vec2 i = floor(x), f = x - i;
  vec2 w_lo = (3.0 - 2.0 * f) * 0.25;       // texels i - 1 and i
  vec2 w_hi = (1.0 + 2.0 * f) * 0.25;       // texels i + 1 and i + 2
  vec2 lo = (i - 0.5 + (2.0 - f) / (3.0 - 2.0 * f)) * texel;  // the pairs' taps, in uv
  vec2 hi = (i + 1.5 + f / (1.0 + 2.0 * f)) * texel;
  vec3 sum = w_lo.x * w_lo.y * textureLod(u_low, vec2(lo.x, lo.y), 0.0).rgb +
             w_hi.x * w_lo.y * textureLod(u_low, vec2(hi.x, lo.y), 0.0).rgb +
             w_lo.x * w_hi.y * textureLod(u_low, vec2(lo.x, hi.y), 0.0).rgb +
             w_hi.x * w_hi.y * textureLod(u_low, vec2(hi.x, hi.y), 0.0).rgb;
  // Capped at the largest half: the sum of levels must not overflow the RGBA16F target to +inf
  // (the tonemapper would turn it into NaN).
  vec3 color = min(sum + textureLod(u_this, v_uv, 0.0).rgb, vec3(65504.0));
  out_color = vec4(color, 1.0);
}
