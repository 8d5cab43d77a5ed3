// Exposure (fixed, or auto: common/exposure.glsl), bloom added in exposed units, then a
// tonemapper: Khronos PBR Neutral or the photographic operator on luma; the sRGB attachment
// encodes the output (the compute variant, tonemap.comp, encodes it itself). Also shows the debug views that are images rather than surfaces (the
// shadow atlas, SSAO, bloom).
#include "common/gpu_types.h"
#include "common/post_io.glsl"
#include "common/exposure.glsl"

layout(set = 0, binding = 0) uniform sampler2D u_hdr;
layout(set = 0, binding = 1) uniform sampler2D u_ao;        // ssao visibility (bilinear)
layout(set = 0, binding = 2) uniform sampler2D u_atlas;     // shadow atlas depths (nearest)
layout(set = 0, binding = 3) uniform sampler2D u_bloom;     // bloom, half size (bilinear)
layout(set = 0, binding = 4) uniform sampler2D u_exposure;  // auto exposure's state (nearest)
layout(push_constant) uniform Push { TS_PUSH_TONEMAP } push;  // common/gpu_types.h
// The variant (kTonemap*): a pipeline per combination used, so each holds only the code it runs
// (lavapipe runs untaken branches under a lane mask: one shader for every view, curve and effect
// cost its full-screen pass four times a plain tonemap's).
layout(constant_id = 0) const uint kVariant = kTonemapViewColor;
const uint kView = kVariant & 7u;
const bool kBloom = (kVariant & kTonemapBloom) != 0u;
const bool kPhotographic = (kVariant & kTonemapPhotographic) != 0u;
const bool kAutoExposure = (kVariant & kTonemapAutoExposure) != 0u;
#ifdef TESSERA_COMPUTE
vec4 out_color;
#else
layout(location = 0) out vec4 out_color;
#endif

// Khronos PBR Neutral: identity below ~0.76, then a smooth shoulder that desaturates towards
// white, so base colours under neutral light come out as authored.
vec3 PbrNeutral(vec3 color) {
  const float kStart = 0.8 - 0.04;
  const float kDesaturation = 0.15;
  float x = min(color.r, min(color.g, color.b));
  float offset = x < 0.08 ? x - 6.25 * x * x : 0.04;
  color -= offset;
  float peak = max(color.r, max(color.g, color.b));
  if (peak < kStart) return color;
  const float d = 1.0 - kStart;
  float new_peak = 1.0 - d * d / (peak + d - kStart);
  color *= new_peak / peak;
  float g = 1.0 - 1.0 / (kDesaturation * (peak - new_peak) + 1.0);
  return mix(color, vec3(new_peak), g);
}

float Luma(vec3 c) { return dot(c, vec3(0.2126, 0.7152, 0.0722)); }  // Rec. 709

// The photographic operator 1 - e^-L (Humus; Tesseract applies it to luma): luma is mapped and
// the colour scaled with it, so hues keep their ratios. Near black it is the identity (slope 1);
// it reaches white only at infinity. A colour whose scaled peak passes 1 is moved towards grey
// of the same luma until its peak is 1, rather than clipped per channel (which shifts the hue).
vec3 Photographic(vec3 color) {
  float l = Luma(color);
  if (!(l > 1e-8)) return vec3(0.0);  // also NaN
  float ld = 1.0 - exp(-l);
  vec3 c = color * (ld / l);
  float peak = max(c.r, max(c.g, c.b));
  if (peak > 1.0) c = mix(c, vec3(ld), (peak - 1.0) / (peak - ld));
  return c;
}

vec3 Tonemap(vec3 c) {
  c = clamp(c, vec3(0.0), vec3(65504.0));  // no inf: both curves divide by the peak or luma
  return kPhotographic ? Photographic(c) : PbrNeutral(c);
}

void PostMain() {
  vec2 size = vec2(textureSize(u_hdr, 0));
  vec2 uv = FRAG_COORD / size;
  if (kView == kTonemapViewBloom) {  // the bloom at strength 1, tonemapped
    out_color = vec4(clamp(Tonemap(textureLod(u_bloom, uv, 0.0).rgb * push.bloom.y), 0.0, 1.0),
                     1.0);
    return;
  }
  if (kView == kTonemapViewAtlas) {
    // The atlas as a square at the left, full height: near the light dark, far and empty
    // white. The power spreads the perspective maps' depths, which crowd near 1.
    vec2 square = FRAG_COORD / size.y;
    float d = square.x <= 1.0 ? pow(textureLod(u_atlas, square, 0.0).r, 32.0) : 0.0;
    out_color = vec4(vec3(d), 1.0);
    return;
  }
  if (kView == kTonemapViewSsao) {
    out_color = vec4(vec3(textureLod(u_ao, uv, 0.0).r), 1.0);
    return;
  }
  vec3 hdr = texelFetch(u_hdr, ivec2(FRAG_COORD), 0).rgb;
  if (kView == kTonemapViewPlain) {  // the other debug views: the colour as the shading wrote it
    out_color = vec4(clamp(hdr, 0.0, 1.0), 1.0);
    return;
  }
  vec3 c = hdr * (kAutoExposure ? Exposure(u_exposure, push.exposure) : push.exposure.x);
  if (kBloom) c += textureLod(u_bloom, uv, 0.0).rgb * push.bloom.x;
  out_color = vec4(clamp(Tonemap(c), 0.0, 1.0), 1.0);
}
