#include "common/gpu_types.h"
#include "common/post_io.glsl"
// One level of the bloom downsample chain: the 13-tap filter of Jimenez, "Next Generation Post
// Processing in Call of Duty: Advanced Warfare" (SIGGRAPH 2014). The target is half the source.
//
// 13 bilinear taps around the target pixel's centre (offsets in source texels):
//     a(-2,-2)  b(0,-2)  c(2,-2)
//          d(-1,-1)  e(1,-1)
//     f(-2, 0)  g(0, 0)  h(2, 0)
//          i(-1, 1)  j(1, 1)
//     k(-2, 2)  l(0, 2)  m(2, 2)
// form five 2x2 boxes (each tap itself averages 2x2 texels): the inner box d e i j weighs 0.5,
// the four overlapping outer boxes (a b f g, b c g h, f g k l, g h l m) 0.125 each. This covers
// 6x6 source texels with a smooth falloff, avoiding the pulsing/aliasing of a plain 2x2 box.
// The first level (reading the HDR frame) also weighs each box by 1 / (1 + luma) (Karis
// average, so a single very bright pixel cannot flicker into a large blob: fireflies) and
// applies a soft-knee threshold to the result.
// The first level also exposes the frame (common/exposure.glsl): the threshold is in exposed
// units, the units the tonemap pass adds the bloom in.
#include "common/exposure.glsl"
// The previous level, or the HDR frame; LINEAR, clamp to edge.
layout(set = 0, binding = 0) uniform sampler2D u_src;
layout(set = 0, binding = 1) uniform sampler2D u_exposure;  // auto exposure's state (NEAREST)
layout(push_constant) uniform Push { TS_PUSH_BLOOM_DOWN } push;  // common/gpu_types.h
POST_IO(out_color)  // from fullscreen.vert: the target pixel's centre

const float kMaxHalf = 65504.0;  // largest finite RGBA16F value

float Luma(vec3 c) {
  return dot(c, vec3(0.2126, 0.7152, 0.0722));  // Rec. 709
}

// The variant (gpu_types.h): kBloomDownFirst, and kBloomDownQuads for bloom_down.comp. A
// specialization constant, not a branch on the push constants: lavapipe runs an untaken branch's
// code under a lane mask, so every level would pay for the first level's.
layout(constant_id = 0) const uint kVariant = 0u;
const bool kFirst = (kVariant & kBloomDownFirst) != 0u;

float g_scale = 1.0;  // the exposure on the first level, else 1
void BeginLevel() {
  if (kFirst) g_scale = Exposure(u_exposure, push.exposure);
}

// One bilinear tap at `uv` (source uv), scaled, made non-negative and finite (NaN and negative
// channels 0, +inf the largest half) so one bad pixel cannot poison the chain.
vec3 TapAt(vec2 uv) {
  vec3 c = textureLod(u_src, uv, 0.0).rgb * g_scale;
  return mix(vec3(0.0), min(c, vec3(kMaxHalf)), greaterThanEqual(c, vec3(0.0)));
}

// One tap `offset` source texels from the centre.
vec3 Tap(vec2 offset) { return TapAt(v_uv + offset * push.src.xy); }

// The filter of the 13 taps (named as above): the five boxes, Karis-weighted and thresholded on
// the first level.
vec4 BloomDown(vec3 a, vec3 b, vec3 c, vec3 d, vec3 e, vec3 f, vec3 g, vec3 h, vec3 i, vec3 j,
               vec3 k, vec3 l, vec3 m) {
  // The five box averages and their weights.
  vec3 box[5] = vec3[](0.25 * (d + e + i + j), 0.25 * (a + b + f + g), 0.25 * (b + c + g + h),
                       0.25 * (f + g + k + l), 0.25 * (g + h + l + m));
  float weight[5] = float[](0.5, 0.125, 0.125, 0.125, 0.125);

  vec3 color = vec3(0.0);
  float total = 0.0;
  for (int n = 0; n < 5; ++n) {
    float w = weight[n] * (kFirst ? 1.0 / (1.0 + Luma(box[n])) : 1.0);  // Karis on level 0
    color += box[n] * w;
    total += w;
  }
  color /= total;  // total is 1 without Karis

  if (kFirst) {
    // Soft-knee threshold: below t - k nothing passes, above t + k the excess br - t, in between
    // a quadratic blend (rq) so the cut-off does not show as a hard edge. Scaling by the
    // brightest channel keeps the hue.
    float t = push.threshold.x;
    float knee = push.threshold.y;
    float br = max(color.r, max(color.g, color.b));
    float rq = clamp(br - t + knee, 0.0, 2.0 * knee);
    rq = rq * rq / (4.0 * knee + 1e-5);  // 1e-5: knee 0 is a hard threshold, not 0 / 0
    color *= max(rq, br - t) / max(br, 1e-5);
  }
  return vec4(color, 1.0);
}

void PostMain() {
  BeginLevel();
  out_color = BloomDown(Tap(vec2(-2.0, -2.0)), Tap(vec2(0.0, -2.0)), Tap(vec2(2.0, -2.0)),
                        Tap(vec2(-1.0, -1.0)), Tap(vec2(1.0, -1.0)), Tap(vec2(-2.0, 0.0)),
                        Tap(vec2(0.0, 0.0)), Tap(vec2(2.0, 0.0)), Tap(vec2(-1.0, 1.0)),
                        Tap(vec2(1.0, 1.0)), Tap(vec2(-2.0, 2.0)), Tap(vec2(0.0, 2.0)),
                        Tap(vec2(2.0, 2.0)));
}
