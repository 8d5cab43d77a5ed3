#version 460
#extension GL_GOOGLE_include_directive : require
// Exposure and the Khronos PBR Neutral tonemapper; the sRGB attachment encodes the output.
// Also shows the debug views that are images rather than surfaces (the shadow atlas, SSAO).
#include "common/gpu_types.h"

layout(set = 0, binding = 0) uniform sampler2D u_hdr;
layout(set = 0, binding = 1) uniform sampler2D u_ao;      // ssao visibility (bilinear)
layout(set = 0, binding = 2) uniform sampler2D u_atlas;   // shadow atlas depths (nearest)
layout(push_constant) uniform Push {
  float exposure;      // linear multiplier
  uint passthrough;    // debug views: no exposure, no tonemap
  uint debug_view;     // kDebug*
  uint unused;
} push;
layout(location = 0) out vec4 out_color;

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

void main() {
  vec2 size = vec2(textureSize(u_hdr, 0));
  if (push.debug_view == kDebugShadowAtlas) {
    // The atlas as a square at the left, full height: near the light dark, far and empty
    // white. The power spreads the perspective maps' depths, which crowd near 1.
    vec2 uv = gl_FragCoord.xy / size.y;
    float d = uv.x <= 1.0 ? pow(textureLod(u_atlas, uv, 0.0).r, 32.0) : 0.0;
    out_color = vec4(vec3(d), 1.0);
    return;
  }
  if (push.debug_view == kDebugSsao) {
    out_color = vec4(vec3(textureLod(u_ao, gl_FragCoord.xy / size, 0.0).r), 1.0);
    return;
  }
  vec3 hdr = texelFetch(u_hdr, ivec2(gl_FragCoord.xy), 0).rgb;
  vec3 c = push.passthrough != 0u ? hdr : PbrNeutral(max(hdr * push.exposure, vec3(0.0)));
  out_color = vec4(clamp(c, 0.0, 1.0), 1.0);
}
