#version 460
// Exposure and the Khronos PBR Neutral tonemapper; the sRGB attachment encodes the output.
layout(set = 0, binding = 0) uniform sampler2D u_hdr;
layout(push_constant) uniform Push {
  float exposure;      // linear multiplier
  uint passthrough;    // debug views: no exposure, no tonemap
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
  vec3 hdr = texelFetch(u_hdr, ivec2(gl_FragCoord.xy), 0).rgb;
  vec3 c = push.passthrough != 0u ? hdr : PbrNeutral(max(hdr * push.exposure, vec3(0.0)));
  out_color = vec4(clamp(c, 0.0, 1.0), 1.0);
}
