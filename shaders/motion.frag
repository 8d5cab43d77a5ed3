#version 460
#extension GL_GOOGLE_include_directive : require
// TAA's object motion: per visible pixel of an animated drawable, how far from where the camera
// alone would put it the point was on last frame's screen (uv units). TAA adds this to its
// camera reprojection; pixels nothing moved on keep the target's clear value, 0. A point that
// was behind last frame's camera gets kMotionOffScreen: no history.
#include "common/scene.glsl"
#include "common/textures.glsl"

layout(location = 0) in vec4 v_prev_clip;
layout(location = 1) in vec4 v_still_clip;
layout(location = 3) in vec2 v_uv0;
layout(location = 4) in vec2 v_uv1;
layout(location = 6) in vec4 v_color;  // COLOR_0: its alpha is cut out too
layout(location = 0) out vec2 out_motion;
// The alpha-mask pipeline's alpha test. The opaque pipeline has none: a shader that may discard
// loses the early depth test on CPU rasterizers, and the hidden fragments cost.
layout(constant_id = 0) const bool kAlphaTest = false;

void main() {
  if (kAlphaTest && CutOut(v_uv0, v_uv1, v_color.a)) discard;
  if (!(v_prev_clip.w > 0.0 && v_still_clip.w > 0.0)) {
    out_motion = vec2(kMotionOffScreen);
    return;
  }
  // uv = ndc / 2 + 1/2 on both sides: the difference is half the NDC difference.
  out_motion = 0.5 * (v_prev_clip.xy / v_prev_clip.w - v_still_clip.xy / v_still_clip.w);
}
