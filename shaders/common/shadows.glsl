// Shadow lookups in the shadow atlas (renderer/shadows.h has the conventions, the Tesseract
// pipeline article the method): the sun picks its cascade by the spheres the cascades cover,
// a point light picks its unrolled cubemap face by comparing the axes of the light-to-surface
// vector (no lookup texture), a spot light has one view. Each lookup is Tesseract's 3x3 box
// PCF, made of 4 comparison gathers of the hardware shadow sampler.
// Needs scene.glsl; fragment shaders only.
#ifndef TESSERA_SHADOWS_GLSL
#define TESSERA_SHADOWS_GLSL

layout(set = 0, binding = kBindingShadows, std140) uniform ShadowBlock { ShadowUniforms shadow; };
layout(set = 0, binding = kBindingShadowAtlas) uniform sampler2DShadow u_shadow_atlas;

// The weights of a gather's four texels (its order, below) from those of its two columns `wx`
// and two rows `wy`.
vec4 Quarter(vec2 wx, vec2 wy) { return vec4(wx.x * wy.y, wx.y * wy.y, wx.y * wy.x, wx.x * wy.x); }

// Tesseract's filter: a box 3 texels wide around `tc` (atlas texels, z the depth to compare)
// covers the 4x4 texels i - 1 .. i + 2 per axis, where tc lies o past texel i's centre, by
// (1 - o, 1, 1, o) / 3. Each 2x2 quarter of those is one comparison gather (the texels a
// bilinear tap at its shared corner reads), weighed here: Tesseract folds the weights into 4
// bilinear taps placed to reproduce them, which read the same texels, but lavapipe's bilinear
// comparison taps cost more than its gathers (Sponza's full stack, four alternating rounds:
// shading 147.8-156.0 -> 143.3-150.2 ms; the shadow goldens 63-65 dB from the taps', a few
// shadow-edge pixels apart, likely where the taps' weights were rounded to the sampler's
// subtexel precision). A gather has no level of detail to pick, so it needs no derivatives in
// the lookups' non-uniform control flow (per light, per cascade).
float ShadowPcf(vec3 tc) {
  vec2 x = tc.xy - 0.5;
  vec2 i = floor(x), o = x - i;
  float inv = shadow.atlas.y;
  // A gather at the corner shared by texels (i0, i0 + 1) x (j0, j0 + 1) returns them as
  // (i0, j0 + 1), (i0 + 1, j0 + 1), (i0 + 1, j0), (i0, j0).
  vec4 near_near = textureGather(u_shadow_atlas, i * inv, tc.z);  // texels i - 1, i
  vec4 far_near = textureGather(u_shadow_atlas, (i + vec2(2.0, 0.0)) * inv, tc.z);
  vec4 near_far = textureGather(u_shadow_atlas, (i + vec2(0.0, 2.0)) * inv, tc.z);
  vec4 far_far = textureGather(u_shadow_atlas, (i + 2.0) * inv, tc.z);  // texels i + 1, i + 2
  // Per axis the weights of a quarter's two texels: the near quarter's (1 - o, 1), the far's
  // (1, o); a quarter's four, in the gather's order, from its x and y pairs.
  vec2 near = vec2(1.0 - o.x, 1.0), far = vec2(1.0, o.x);
  vec2 near_y = vec2(1.0 - o.y, 1.0), far_y = vec2(1.0, o.y);
  float sum = dot(near_near, Quarter(near, near_y)) + dot(far_near, Quarter(far, near_y)) +
              dot(near_far, Quarter(near, far_y)) + dot(far_far, Quarter(far, far_y));
  return sum * (1.0 / 9.0);
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

// How much of a light reaches `p` (1 lit .. 0 shadowed): the sun (`sun`) through its cascades,
// a point or spot light through a cubemap face or the spot's view. Each kind picks its view and
// point with a little arithmetic, and one lookup follows for both: lavapipe runs every branch's
// code, so a lookup per kind ran each kind's lookup for the other. `ng` is the surface's
// geometric normal: the lookup point moves along it by a texel or two (normal offset), which
// with the rasterizer's slope-scaled bias keeps lit surfaces free of acne. The point moves
// first, then picks its cascade or face: one picked from the unmoved point could send the
// filter past its border into a neighbouring map.

// The lookup of `q` in shadow view `view`.
float ShadowLookup(uint view, vec3 q) {
  vec4 c = shadow.views[view].world_to_atlas * vec4(q, 1.0);
  vec3 tc = c.xyz / c.w;
  if (tc.z >= 1.0) return 1.0;  // past the map's far plane
  return ShadowPcf(vec3(tc.xy * shadow.atlas.x, tc.z));
}

float LightShadow(GpuLight light, vec3 p, vec3 ng, bool sun) {
  uint first = uint(light.spot.z);
  if (first == 0u || (shadow.counts.w & kShadowsOn) == 0u) return 1.0;
  uint view = first - 1u;
  // A light's views share their texel size at distance 1 (a cubemap's faces are one size),
  // scaled by the distance along the face's axis (point) or the spot's axis; the sun's cascade
  // is picked with the first cascade's offset, and cascades differ in texel size, so the lookup
  // then offsets by the chosen one's.
  vec3 d = p - light.position_range.xyz;
  bool point = !sun && uint(light.direction_type.w) == kLightPoint;
  float dist = sun     ? 1.0
               : point ? max(abs(d.x), max(abs(d.y), abs(d.z)))
                       : max(dot(d, light.direction_type.xyz), 0.0);
  vec3 q = p + ng * (shadow.views[view].params.x * dist * shadow.atlas.z);
  if (sun) {
    uint c = SunCascade(q);
    if (c >= shadow.counts.y) return 1.0;  // beyond the shadow distance: lit
    view += c;
    q = p + ng * (shadow.views[view].params.x * shadow.atlas.z);
  } else if (point) {
    view += CubeFace(q - light.position_range.xyz);
  }
  return ShadowLookup(view, q);
}

// Debug view "cascades": the colour of the sun cascade that covers `p`.
vec3 CascadeColor(vec3 p) {
  const vec3 kColors[5] = vec3[5](vec3(1.0, 0.25, 0.25), vec3(0.25, 1.0, 0.25),
                                  vec3(0.3, 0.45, 1.0), vec3(1.0, 1.0, 0.25), vec3(0.5));
  return kColors[min(SunCascade(p), 4u)];
}
#endif
