// FXAA's body: fxaa.frag writes the sRGB target; fxaa.comp a UNORM storage image that it
// sRGB-encodes itself. Both read the tonemapped image through an sRGB view.
#ifndef TESSERA_FXAA_GLSL
#define TESSERA_FXAA_GLSL
#include "common/gpu_types.h"
#include "common/post_io.glsl"
// FXAA: one luma-based anti-aliasing pass over the tonemapped image.
//
// For each pixel: measure the local luma contrast and leave low-contrast pixels untouched;
// otherwise decide whether the edge through the pixel runs horizontally or vertically, walk
// along it both ways until the luma of the edge line changes (the edge ends), and shift the
// pixel's sample across the edge by an amount that depends on where the pixel lies on that
// edge segment (pixels near an end of a staircase step get blended most). A separate subpixel
// term blends single-pixel features (thin lines, dots) by how much the pixel differs from the
// average of its 3x3 neighbourhood. The final colour is one bilinear sample at the shifted
// position.
//
// Luma: the image holds linear light (its sRGB view decodes on sampling, before filtering), so
// the Rec. 601 luma of the linear colour is square-rooted, a cheap approximation of gamma
// encoding that makes the contrast thresholds perceptual. Pixels without a detected edge are
// returned with texelFetch, unfiltered, so they come out bit-identical to the input.
layout(set = 0, binding = 0) uniform sampler2D u_ldr;  // an RGBA8 sRGB view, LINEAR filter, clamp to edge
layout(push_constant) uniform Push { TS_PUSH_FXAA } push;  // common/gpu_types.h
POST_IO(out_color)  // v_uv unused: centres come from FRAG_COORD

// An edge needs a luma range (max - min over the centre and its 4 neighbours) of at least this
// fraction of the brightest of them...
const float kEdgeThresholdRelative = 0.125;
// ...and at least this much in absolute terms (leaves dark noise alone).
const float kEdgeThresholdAbsolute = 0.0312;
// Strength of the subpixel blend: 0 off, 1 softest.
const float kSubpixelStrength = 0.75;
// The search along the edge: stride of each step in pixels (23.5 pixels each way in all).
const int kSearchSteps = 10;
const float kSearchStride[kSearchSteps] =
    float[](1.0, 1.0, 1.0, 1.0, 1.5, 2.0, 2.0, 2.0, 4.0, 8.0);

float Luma(vec3 linear_rgb) {
  return sqrt(max(dot(linear_rgb, vec3(0.299, 0.587, 0.114)), 0.0));
}

// One texel, unfiltered, with clamp-to-edge addressing (texelFetch ignores the sampler's).
vec3 FetchTexel(ivec2 texel, ivec2 last) {
  return texelFetch(u_ldr, clamp(texel, ivec2(0), last), 0).rgb;
}

// Luma of a bilinear sample. Explicit LOD: the search runs in non-uniform control flow.
float LumaAt(vec2 uv) {
  return Luma(textureLod(u_ldr, uv, 0.0).rgb);
}

void PostMain() {
  ivec2 pixel = ivec2(FRAG_COORD);
  ivec2 last = textureSize(u_ldr, 0) - 1;
  vec3 center = FetchTexel(pixel, last);

  // 1. Local contrast over the centre and its 4 neighbours. Texel rows grow downwards, so
  //    "up" is y - 1 (the same orientation as v_uv and FRAG_COORD).
  float luma_c = Luma(center);
  float luma_up = Luma(FetchTexel(pixel + ivec2(0, -1), last));
  float luma_down = Luma(FetchTexel(pixel + ivec2(0, 1), last));
  float luma_left = Luma(FetchTexel(pixel + ivec2(-1, 0), last));
  float luma_right = Luma(FetchTexel(pixel + ivec2(1, 0), last));
  float luma_min = min(luma_c, min(min(luma_up, luma_down), min(luma_left, luma_right)));
  float luma_max = max(luma_c, max(max(luma_up, luma_down), max(luma_left, luma_right)));
  float range = luma_max - luma_min;
  if (range < max(kEdgeThresholdAbsolute, luma_max * kEdgeThresholdRelative)) {
    out_color = vec4(center, 1.0);  // no edge: the input pixel, exactly
    return;
  }

  // 2. The corners complete the 3x3 neighbourhood.
  float luma_up_left = Luma(FetchTexel(pixel + ivec2(-1, -1), last));
  float luma_up_right = Luma(FetchTexel(pixel + ivec2(1, -1), last));
  float luma_down_left = Luma(FetchTexel(pixel + ivec2(-1, 1), last));
  float luma_down_right = Luma(FetchTexel(pixel + ivec2(1, 1), last));

  // 3. Orientation. A horizontal edge shows as luma curvature down the columns, a vertical one
  //    as curvature along the rows; the centre column/row counts double.
  float curvature_down_columns = abs(luma_up_left + luma_down_left - 2.0 * luma_left) +
                                 2.0 * abs(luma_up + luma_down - 2.0 * luma_c) +
                                 abs(luma_up_right + luma_down_right - 2.0 * luma_right);
  float curvature_along_rows = abs(luma_up_left + luma_up_right - 2.0 * luma_up) +
                               2.0 * abs(luma_left + luma_right - 2.0 * luma_c) +
                               abs(luma_down_left + luma_down_right - 2.0 * luma_down);
  bool horizontal = curvature_down_columns >= curvature_along_rows;

  // 4. Which side of the pixel the edge lies on: towards the neighbour across the edge with
  //    the larger luma step. `across` is one pixel towards that side, `along` one pixel along
  //    the edge.
  float luma_neg = horizontal ? luma_up : luma_left;     // neighbour across, negative side
  float luma_pos = horizontal ? luma_down : luma_right;  // neighbour across, positive side
  float gradient_neg = abs(luma_neg - luma_c);
  float gradient_pos = abs(luma_pos - luma_c);
  bool edge_on_pos_side = gradient_pos >= gradient_neg;
  float across_sign = edge_on_pos_side ? 1.0 : -1.0;
  vec2 across = horizontal ? vec2(0.0, across_sign * push.inv_size.y)
                           : vec2(across_sign * push.inv_size.x, 0.0);
  vec2 along = horizontal ? vec2(push.inv_size.x, 0.0) : vec2(0.0, push.inv_size.y);
  // The luma on the edge line itself (half way between the centre and the neighbour across),
  // and how far a sample must stray from it to count as the end of the edge.
  float luma_edge = 0.5 * (luma_c + (edge_on_pos_side ? luma_pos : luma_neg));
  float end_threshold = 0.25 * max(gradient_neg, gradient_pos);

  // 5. Walk along the edge line in both directions. Bilinear samples half a pixel across sit
  //    on the line and average the two pixels on either side of it; where the average departs
  //    from luma_edge, the edge has ended (or stepped).
  vec2 uv_center = FRAG_COORD * push.inv_size;  // exact pixel centre
  vec2 uv_on_edge = uv_center + 0.5 * across;
  vec2 uv_neg = uv_on_edge - kSearchStride[0] * along;
  vec2 uv_pos = uv_on_edge + kSearchStride[0] * along;
  float delta_neg = LumaAt(uv_neg) - luma_edge;
  float delta_pos = LumaAt(uv_pos) - luma_edge;
  bool end_neg = abs(delta_neg) >= end_threshold;
  bool end_pos = abs(delta_pos) >= end_threshold;
  for (int i = 1; i < kSearchSteps && !(end_neg && end_pos); ++i) {
    if (!end_neg) {
      uv_neg -= kSearchStride[i] * along;
      delta_neg = LumaAt(uv_neg) - luma_edge;
      end_neg = abs(delta_neg) >= end_threshold;
    }
    if (!end_pos) {
      uv_pos += kSearchStride[i] * along;
      delta_pos = LumaAt(uv_pos) - luma_edge;
      end_pos = abs(delta_pos) >= end_threshold;
    }
  }

  // 6. Offset from the position on the edge segment. The nearer end decides: at the middle of
  //    a segment the pixel stays put, next to an end it moves up to half a pixel across. That
  //    end only counts if the luma there moves the opposite way from the centre's (relative to
  //    luma_edge), i.e. the staircase steps towards this pixel's side; otherwise no offset.
  float dist_neg = horizontal ? uv_center.x - uv_neg.x : uv_center.y - uv_neg.y;
  float dist_pos = horizontal ? uv_pos.x - uv_center.x : uv_pos.y - uv_center.y;
  bool neg_is_nearer = dist_neg < dist_pos;
  float dist_nearer = min(dist_neg, dist_pos);
  float delta_nearer = neg_is_nearer ? delta_neg : delta_pos;
  bool center_darker = luma_c < luma_edge;
  bool steps_towards_us = (delta_nearer < 0.0) != center_darker;
  float edge_offset = steps_towards_us ? 0.5 - dist_nearer / (dist_neg + dist_pos) : 0.0;

  // 7. Subpixel aliasing: how much the centre differs from its weighted 3x3 average, relative to
  //    the local range, shaped with a smoothstep and squared so that only strong outliers blend.
  float luma_average = (2.0 * (luma_up + luma_down + luma_left + luma_right) +
                        (luma_up_left + luma_up_right + luma_down_left + luma_down_right)) /
                       12.0;
  float subpixel = smoothstep(0.0, 1.0, clamp(abs(luma_average - luma_c) / range, 0.0, 1.0));
  float subpixel_offset = subpixel * subpixel * kSubpixelStrength;

  // 8. One bilinear sample, moved across the edge by the larger of the two offsets.
  float offset = max(edge_offset, subpixel_offset);
  vec3 color = offset > 0.0 ? textureLod(u_ldr, uv_center + offset * across, 0.0).rgb : center;
  out_color = vec4(color, 1.0);
}
#endif
