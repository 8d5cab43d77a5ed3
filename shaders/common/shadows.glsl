// Shadow lookups in the shadow atlas (renderer/shadows.h has the conventions, the Tesseract
// pipeline article the method): the sun picks its cascade by the spheres the cascades cover,
// a point light picks its unrolled cubemap face by comparing the axes of the light-to-surface
// vector (no lookup texture), a spot light has one view. Each lookup is a 3x3 weighted box
// PCF made of 4 bilinear comparison taps of the hardware shadow sampler.
// Needs scene.glsl; fragment shaders only.
#ifndef TESSERA_SHADOWS_GLSL
#define TESSERA_SHADOWS_GLSL

layout(set = 0, binding = kBindingShadows, std140) uniform ShadowBlock { ShadowUniforms shadow; };
layout(set = 0, binding = kBindingShadowAtlas) uniform sampler2DShadow u_shadow_atlas;

// Tesseract's filter: the 3x3 box weights of the texels around `tc` (atlas texels, z the depth
// to compare) folded into 4 bilinear taps placed so each tap's bilinear weights reproduce two
// by two of them; the weights' renormalization is the seed of a Newton iteration, as there.
float ShadowPcf(vec3 tc) {
  vec2 offset = fract(tc.xy - 0.5);
  vec2 center = tc.xy - offset * 0.5;
  vec4 size = vec4(offset + 1.0, 2.0 - offset);
  float inv = shadow.atlas.y;
  // Explicit level 0: the lookups run in non-uniform control flow (per light, per cascade),
  // where implicit derivatives are undefined.
  vec4 taps = vec4(
      textureLod(u_shadow_atlas, vec3((center + vec2(-0.5, -0.5)) * inv, tc.z), 0.0),
      textureLod(u_shadow_atlas, vec3((center + vec2(1.0, -0.5)) * inv, tc.z), 0.0),
      textureLod(u_shadow_atlas, vec3((center + vec2(-0.5, 1.0)) * inv, tc.z), 0.0),
      textureLod(u_shadow_atlas, vec3((center + vec2(1.0, 1.0)) * inv, tc.z), 0.0));
  return (1.0 / 9.0) * dot(size.zxzx * size.wwyy, taps);
}

// Face of a point light's cubemap: the axis of the largest component, positive first
// (renderer/shadows.h CubeFace does the same).
uint CubeFace(vec3 d) {
  vec3 a = abs(d);
  if (a.x >= a.y && a.x >= a.z) return d.x >= 0.0 ? 0u : 1u;
  if (a.y >= a.z) return d.y >= 0.0 ? 2u : 3u;
  return d.z >= 0.0 ? 4u : 5u;
}

// The sun cascade that covers `p` (the first whose sphere holds it, less the filter border),
// or the cascade count when none does.
uint SunCascade(vec3 p) {
  uint count = shadow.counts.y;
  for (uint c = 0u; c < count; ++c) {
    vec4 s = shadow.cascade_spheres[c];
    vec3 d = p - s.xyz;
    if (dot(d, d) < s.w * s.w) return c;
  }
  return count;
}

// How much of a light reaches `p` (1 lit .. 0 shadowed): the sun through its cascades
// (SunShadow), a point or spot light through a cubemap face or the spot's view (LocalShadow).
// Two functions, not one branching on the light's type: lavapipe runs every branch's code, so
// one function ran each kind's lookup for the other. `ng` is the surface's geometric normal: the
// lookup point moves along it by a texel or two (normal offset), which with the rasterizer's
// slope-scaled bias keeps lit surfaces free of acne. The point moves first, then picks its
// cascade or face: one picked from the unmoved point could send the filter past its border into
// a neighbouring map.

// The lookup of `q` in shadow view `view`.
float ShadowLookup(uint view, vec3 q) {
  vec4 c = shadow.views[view].world_to_atlas * vec4(q, 1.0);
  vec3 tc = c.xyz / c.w;
  if (tc.z >= 1.0) return 1.0;  // past the map's far plane
  return ShadowPcf(vec3(tc.xy * shadow.atlas.x, tc.z));
}

float SunShadow(GpuLight light, vec3 p, vec3 ng) {
  uint first = uint(light.spot.z);
  if (first == 0u || (shadow.counts.w & kShadowsOn) == 0u) return 1.0;
  uint view = first - 1u;
  // The cascade is picked with the first cascade's offset; cascades differ in texel size, so
  // the lookup then offsets by the chosen one's.
  uint c = SunCascade(p + ng * (shadow.views[view].params.x * shadow.atlas.z));
  if (c >= shadow.counts.y) return 1.0;  // beyond the shadow distance: lit
  view += c;
  return ShadowLookup(view, p + ng * (shadow.views[view].params.x * shadow.atlas.z));
}

float LocalShadow(GpuLight light, vec3 p, vec3 ng) {
  uint first = uint(light.spot.z);
  if (first == 0u || (shadow.counts.w & kShadowsOn) == 0u) return 1.0;
  uint view = first - 1u;
  // A light's views share their texel size at distance 1 (a cubemap's faces are one size),
  // scaled by the distance along the face's axis (point) or the spot's axis.
  vec3 d = p - light.position_range.xyz;
  bool point = uint(light.direction_type.w) == kLightPoint;
  float dist = point ? max(abs(d.x), max(abs(d.y), abs(d.z)))
                     : max(dot(d, light.direction_type.xyz), 0.0);
  vec3 q = p + ng * (shadow.views[view].params.x * dist * shadow.atlas.z);
  if (point) view += CubeFace(q - light.position_range.xyz);
  return ShadowLookup(view, q);
}

// Debug view "cascades": the colour of the sun cascade that covers `p`.
vec3 CascadeColor(vec3 p) {
  const vec3 kColors[5] = vec3[5](vec3(1.0, 0.25, 0.25), vec3(0.25, 1.0, 0.25),
                                  vec3(0.3, 0.45, 1.0), vec3(1.0, 1.0, 0.25), vec3(0.5));
  return kColors[min(SunCascade(p), 4u)];
}
#endif
