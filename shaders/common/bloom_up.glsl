#include "common/gpu_types.h"
#include "common/post_io.glsl"
// One level of the bloom upsample chain (Jimenez, SIGGRAPH 2014): the level below (already
// upsampled, half this size) filtered with a 3x3 tent while magnified, plus this level of the
// downsample chain. The tent (1 2 1 / 2 4 2 / 1 2 1, / 16) of bilinear taps hides the blocky
// 2x magnification that a single bilinear tap would leave; summing the levels builds the wide,
// smooth bloom falloff out of each level's blur.
// The upsampled level below (half this size); LINEAR, clamp to edge.
layout(set = 0, binding = 0) uniform sampler2D u_low;
// This level of the downsample chain (the target's size); LINEAR.
layout(set = 0, binding = 1) uniform sampler2D u_this;
layout(push_constant) uniform Push { TS_PUSH_BLOOM_UP } push;  // common/gpu_types.h
POST_IO(out_color)  // from fullscreen.vert: the target pixel's centre

void PostMain() {
  vec2 step = push.params.xy * push.params.z;  // one tent step in uv
  vec3 sum = vec3(0.0);
  for (int y = -1; y <= 1; ++y) {
    for (int x = -1; x <= 1; ++x) {
      float w = float((2 - abs(x)) * (2 - abs(y)));  // 1 2 1 / 2 4 2 / 1 2 1
      sum += w * textureLod(u_low, v_uv + vec2(x, y) * step, 0.0).rgb;
    }
  }
  // Capped at the largest half: the sum of levels must not overflow the RGBA16F target to +inf
  // (the tonemapper would turn it into NaN).
  vec3 color = min(sum * (1.0 / 16.0) + textureLod(u_this, v_uv, 0.0).rgb, vec3(65504.0));
  out_color = vec4(color, 1.0);
}
