#include "common/gpu_types.h"
#include "common/post_io.glsl"
// Temporal anti-aliasing resolve, in HDR before tonemapping.
//
// Each frame is rendered with a subpixel jitter; this pass blends the frame into an
// accumulated history so that, for a still camera, the output converges to the average of the
// jittered frames (a supersampled image). Per pixel:
//   1. Read the 3x3 neighbourhood of the current frame: its colour bounds (in YCoCg) and its
//      nearest depth.
//   2. Reproject the pixel centre with the nearest depth (dilation: silhouette pixels follow
//      the foreground) into last frame's screen, plus the object motion at that texel where
//      animated geometry moved (the motion pass: how far from the camera's reprojection the
//      surface was), and sample the history there with a 5-tap Catmull-Rom filter (sharper
//      than bilinear under motion).
//   3. Clip the history to the neighbourhood's colour box (rejects stale history after
//      disocclusion or shading changes), in YCoCg where the box fits colours more tightly;
//      where anything moved, the box is tightened to the mean +- one standard deviation.
//   4. Blend with the current colour, params.x being the current frame's weight, each side
//      weighted by the inverse of its luminance above 1 (see ResolveWeight) against fireflies.
// Without valid history (params.y == 0, params.x == 1, off screen, behind last frame's camera)
// the output is the current colour.
layout(set = 0, binding = 0) uniform sampler2D u_current;  // RGBA16F, NEAREST
layout(set = 0, binding = 1) uniform sampler2D u_depth;    // D32, reverse Z (1 near, 0 far), NEAREST
layout(set = 0, binding = 2) uniform sampler2D u_history;  // RGBA16F, LINEAR, clamp to edge
layout(set = 0, binding = 3) uniform sampler2D u_motion;   // RG16F uv offsets, NEAREST (motion.x)
layout(push_constant) uniform Push { TS_PUSH_TAA } push;  // common/gpu_types.h
#ifdef TESSERA_COMPUTE
vec4 out_color;    // this frame's anti-aliased HDR colour
vec4 out_history;  // the same, as next frame's history
#else
layout(location = 0) out vec4 out_color;
layout(location = 1) out vec4 out_history;
#endif

const float kMaxHalf = 65504.0;  // largest finite RGBA16F value

// Non-negative and finite: NaN and negative channels become 0, +inf the largest half.
// (A comparison with NaN is false, so the select drops it.)
vec3 Sanitize(vec3 c) {
  return mix(vec3(0.0), min(c, vec3(kMaxHalf)), greaterThanEqual(c, vec3(0.0)));
}

float Luminance(vec3 c) {
  return dot(c, vec3(0.2126, 0.7152, 0.0722));  // Rec. 709
}

vec3 RgbToYCoCg(vec3 c) {
  return vec3(0.25 * c.r + 0.5 * c.g + 0.25 * c.b,   // Y
              0.5 * c.r - 0.5 * c.b,                 // Co
              -0.25 * c.r + 0.5 * c.g - 0.25 * c.b); // Cg
}

vec3 YCoCgToRgb(vec3 c) {
  return vec3(c.x + c.y - c.z, c.x + c.z, c.x - c.y - c.z);
}

// Weight of a colour in the blend, after Karis' luminance weighting: the ratio
// tonemapped/linear of the tonemapper the weighting stands in for, so that the blend behaves
// as if done after tonemapping. Karis uses Reinhard, 1/(1 + L); ours is PBR Neutral, which is
// the identity up to ~0.76 and saturates at 1, so the ratio is ~1/max(L, 1). That keeps the
// blend a plain average for colours up to luminance 1 (a still camera converges to the mean of
// its jittered frames, e.g. exact coverage on white-on-black edges, where 1/(1 + L) would turn
// 50 % coverage into ~33 %), while a firefly of luminance L still only counts 1/L as much.
// Assumes exposure ~1 (the exposure is applied later, in tonemap.frag).
float ResolveWeight(float luminance) {
  return 1.0 / max(luminance, 1.0);
}

// The history at `uv`, filtered with a Catmull-Rom spline over the 4x4 texels around it,
// evaluated with 5 bilinear taps: along each axis the two middle weights are merged into one
// bilinear tap between them, and the 4 corner taps (the smallest weights) are left out and the
// rest renormalised. Catmull-Rom has negative lobes, hence the clamp to non-negative.
vec3 SampleHistory(vec2 uv) {
  vec2 size = vec2(textureSize(u_history, 0));
  vec2 position = uv * size;                     // in texels; texel centres at i + 0.5
  vec2 center1 = floor(position - 0.5) + 0.5;    // centre of the texel at or left/above
  vec2 t = position - center1;                   // 0..1 towards the next texel
  // Catmull-Rom weights of the texels at center1 - 1, center1, center1 + 1, center1 + 2.
  vec2 w0 = t * (-0.5 + t * (1.0 - 0.5 * t));
  vec2 w1 = 1.0 + t * t * (-2.5 + 1.5 * t);
  vec2 w2 = t * (0.5 + t * (2.0 - 1.5 * t));
  vec2 w3 = t * t * (-0.5 + 0.5 * t);
  vec2 w12 = w1 + w2;  // >= 1, never 0
  vec2 uv0 = (center1 - 1.0) / size;
  vec2 uv12 = (center1 + w2 / w12) / size;
  vec2 uv3 = (center1 + 2.0) / size;

  vec3 sum = textureLod(u_history, vec2(uv12.x, uv0.y), 0.0).rgb * (w12.x * w0.y) +
             textureLod(u_history, vec2(uv0.x, uv12.y), 0.0).rgb * (w0.x * w12.y) +
             textureLod(u_history, uv12, 0.0).rgb * (w12.x * w12.y) +
             textureLod(u_history, vec2(uv3.x, uv12.y), 0.0).rgb * (w3.x * w12.y) +
             textureLod(u_history, vec2(uv12.x, uv3.y), 0.0).rgb * (w12.x * w3.y);
  float weight = w12.x * w0.y + w0.x * w12.y + w12.x * w12.y + w3.x * w12.y + w12.x * w3.y;
  return Sanitize(sum / weight);
}

// Clips `history` to the box [box_min, box_max] (YCoCg) along the line towards the box centre:
// unchanged when inside, else the point where that line leaves the box.
vec3 ClipToBox(vec3 history, vec3 box_min, vec3 box_max) {
  vec3 history_ycocg = RgbToYCoCg(history);
  vec3 center = 0.5 * (box_max + box_min);
  vec3 half_extent = max(0.5 * (box_max - box_min), vec3(1e-6));
  vec3 offset = history_ycocg - center;
  vec3 units = abs(offset / half_extent);  // > 1 on an axis where the history lies outside
  float outside = max(units.x, max(units.y, units.z));
  if (outside <= 1.0) return history;  // inside: keep the exact RGB (no round trip)
  return Sanitize(YCoCgToRgb(center + offset / outside));
}

void PostMain() {
  ivec2 pixel = ivec2(FRAG_COORD);
  ivec2 last = textureSize(u_current, 0) - 1;

  // 1. The 3x3 neighbourhood (clamped at the image border): the centre colour, the colour box
  //    and the nearest depth (largest in reverse Z).
  vec3 current = vec3(0.0);
  vec3 box_min = vec3(kMaxHalf);
  vec3 box_max = vec3(-kMaxHalf);
  vec3 m1 = vec3(0.0), m2 = vec3(0.0);
  float nearest_depth = 0.0;
  ivec2 nearest_texel = pixel;
  for (int dy = -1; dy <= 1; ++dy) {
    for (int dx = -1; dx <= 1; ++dx) {
      ivec2 texel = clamp(pixel + ivec2(dx, dy), ivec2(0), last);
      vec3 color = Sanitize(texelFetch(u_current, texel, 0).rgb);
      if (dx == 0 && dy == 0) current = color;
      vec3 ycocg = RgbToYCoCg(color);
      box_min = min(box_min, ycocg);
      box_max = max(box_max, ycocg);
      m1 += ycocg;
      m2 += ycocg * ycocg;
      float depth = texelFetch(u_depth, texel, 0).r;
      if (depth > nearest_depth) {  // also skips a NaN depth
        nearest_depth = depth;
        nearest_texel = texel;
      }
    }
  }

  vec3 result = current;
  float current_weight = clamp(push.params.x, 0.0, 1.0);
  if (push.params.y > 0.5 && current_weight < 1.0) {
    // 2. Reproject the (unjittered) pixel centre into last frame's screen.
    vec2 uv = FRAG_COORD * push.params.zw;
    vec4 prev_clip = push.reproject * vec4(uv * 2.0 - 1.0, nearest_depth, 1.0);
    vec2 prev_uv = prev_clip.xy / prev_clip.w * 0.5 + 0.5;
    vec2 object = push.motion.x > 0.5 ? texelFetch(u_motion, nearest_texel, 0).xy : vec2(0.0);
    prev_uv += object;
    // Valid when in front of last frame's camera and on last frame's screen (false for NaN).
    bool on_screen = prev_clip.w > 0.0 && all(greaterThanEqual(prev_uv, vec2(0.0))) &&
                     all(lessThanEqual(prev_uv, vec2(1.0)));
    if (on_screen) {
      // 3. History, clipped to what this frame's neighbourhood can plausibly contain.
      //    Where the camera or the surface moved, the box shrinks to the neighbourhood's mean
      //    plus or minus one standard deviation (variance clipping): resampled history from
      //    elsewhere needs the tighter test (a playing animation's frame 0.6-1.6 dB closer to
      //    the settled pose), while a still pixel's history is exact and keeps the whole box
      //    (variance clipping there cost 0.15-0.23 dB of edge PSNR on Sponza and the helmet).
      if (push.motion.y > 0.5 || object != vec2(0.0)) {
        vec3 mean = m1 / 9.0;
        vec3 sigma = sqrt(max(m2 / 9.0 - mean * mean, vec3(0.0)));
        box_min = max(box_min, mean - sigma);
        box_max = min(box_max, mean + sigma);
      }
      vec3 history = ClipToBox(SampleHistory(prev_uv), box_min, box_max);
      // 4. Blend.
      float w_current = current_weight * ResolveWeight(Luminance(current));
      float w_history = (1.0 - current_weight) * ResolveWeight(Luminance(history));
      result = mix(history, current, w_current / (w_current + w_history));
    }
  }

  result = Sanitize(result);
  out_color = vec4(result, 1.0);
  out_history = out_color;
}
