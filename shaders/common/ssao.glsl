#include "common/gpu_types.h"
#include "common/post_io.glsl"
// Screen-space ambient obscurance: SAO / Alchemy AO (McGuire, Mara, Luebke, "Scalable Ambient
// Obscurance", HPG 2012), at half or full resolution.
//
// Per output pixel q: the centre is the depth texel at q * scale (scale = depth size / output
// size, 1 or 2). Its view position and a normal come from the depth buffer alone (there is no
// normal buffer); 12 taps on a spiral of 7 turns, rotated per pixel, sample the full-resolution
// depth within a world-space radius, and each tap Q obscures in proportion to how far it lies
// above the centre's tangent plane, with SAO's smooth falloff to zero at the radius. The
// per-pixel rotation leaves noise that ssao_blur.frag averages out.
//
// Output (RGBA16F): r = visibility (1 unoccluded, 0 fully occluded), g = the centre's
// view distance z, for the bilateral blur; sky (depth 0) is (1, 0).
// D32, reverse Z (1 near, 0 sky), NEAREST sampler (texelFetch only).
layout(set = 0, binding = 0) uniform sampler2D u_depth;
layout(push_constant) uniform Push { TS_PUSH_SSAO } push;  // common/gpu_types.h
POST_IO(out_ao)  // from fullscreen.vert; unused: pixels come from gl_FragCoord

const int kSamples = 12;          // taps per pixel
const float kSpiralTurns = 7.0;   // turns of the spiral over the taps (SAO: coprime with 12)
const float kMinRadiusPx = 1.0;   // smallest disk, in depth pixels (below, only the centre)
const float kMaxRadiusPx = 96.0;  // largest disk, in depth pixels: bounds the cost of close-ups,
                                  // which would otherwise spread taps over the whole screen

// View-space position (looking down -Z) of depth pixel `p` at reverse-Z depth `d` > 0.
vec3 ViewPosition(ivec2 p, float d) {
  float z = push.proj.w / (d + push.proj.z);
  vec2 ndc = (vec2(p) + 0.5) / vec2(push.size.xy) * 2.0 - 1.0;
  return vec3(ndc * z / push.proj.xy, -z);
}

float Depth(ivec2 p) {
  return texelFetch(u_depth, p, 0).r;
}

// The step of the surface position from the centre c (position P, depth d) one pixel along
// `axis`, taken on the side whose position differs less in z: across a silhouette one side
// jumps to another surface, and using it would tilt the normal. Sides off the image or on sky
// are skipped; with neither side usable, the surface is assumed to face the camera along this
// axis.
vec3 Tangent(ivec2 c, ivec2 axis, vec3 P, float d) {
  ivec2 lo = c - axis;
  ivec2 hi = c + axis;
  float d_lo = all(greaterThanEqual(lo, ivec2(0))) ? Depth(lo) : 0.0;
  float d_hi = all(lessThan(hi, ivec2(push.size.xy))) ? Depth(hi) : 0.0;
  vec3 t_lo = P - ViewPosition(lo, d_lo);
  vec3 t_hi = ViewPosition(hi, d_hi) - P;
  if (d_lo > 0.0 && d_hi > 0.0) return abs(t_lo.z) < abs(t_hi.z) ? t_lo : t_hi;
  if (d_hi > 0.0) return t_hi;
  if (d_lo > 0.0) return t_lo;
  return ViewPosition(hi, d) - P;  // the neighbour at the centre's depth
}

void PostMain() {
  ivec2 q = ivec2(FRAG_COORD);
  ivec2 scale = ivec2(push.size.xy / push.size.zw);
  ivec2 last = ivec2(push.size.xy) - 1;
  ivec2 c = min(q * scale, last);
  float d = Depth(c);
  if (!(d > 0.0)) {  // sky (or a NaN depth): nothing to occlude, no distance
    out_ao = vec4(1.0, 0.0, 0.0, 0.0);
    return;
  }
  vec3 P = ViewPosition(c, d);
  float z = -P.z;

  // Normal from the positions of the neighbours, turned towards the camera (at the origin).
  vec3 n = cross(Tangent(c, ivec2(0, 1), P, d), Tangent(c, ivec2(1, 0), P, d));
  float n_len2 = dot(n, n);
  n = n_len2 > 0.0 && !isinf(n_len2) ? n * inversesqrt(n_len2) : normalize(-P);
  if (dot(n, -P) < 0.0) n = -n;

  float radius = push.params.x;
  float radius2 = radius * radius;
  float bias = push.params.z;
  // Disk radius in depth pixels: the world radius projected at distance z (horizontal scale).
  float disk_px = clamp(radius * push.proj.x * 0.5 * float(push.size.x) / z, kMinRadiusPx,
                        kMaxRadiusPx);
  // Per-pixel rotation of the spiral, SAO's hash (3x ^ y + xy) * 10 radians; the integer is
  // wrapped to 12 bits so the float angle keeps its precision (cos of ~1e8 rad is all rounding).
  int hash = (3 * q.x) ^ (q.y + q.x * q.y);
  float spin = float(hash & 4095) * 10.0;

  float sum = 0.0;
  for (int i = 0; i < kSamples; ++i) {
    // SAO's spiral: tap i at fraction alpha of the radius, alpha * turns of a full circle round.
    float alpha = (float(i) + 0.5) / float(kSamples);
    float angle = alpha * (kSpiralTurns * 6.2831853) + spin;
    ivec2 p = clamp(c + ivec2(round(alpha * disk_px * vec2(cos(angle), sin(angle)))), ivec2(0),
                    last);
    float dq = Depth(p);
    if (!(dq > 0.0)) continue;  // sky occludes nothing
    vec3 v = ViewPosition(p, dq) - P;
    float vv = dot(v, v);
    float vn = dot(v, n);
    // SAO's estimator, f^3 * max((v.n - bias) / (v.v + eps), 0) with f = r^2 - v.v, here with f
    // divided by r^2 (so f^3 by r^6, the normalisation of the final sum) to keep the numbers
    // near 1 whatever the scene's scale. eps = 0.01 r^2 keeps taps near the centre finite.
    float f = max(1.0 - vv / radius2, 0.0);
    sum += f * f * f * max((vn - bias) / (vv + 0.01 * radius2), 0.0);
  }
  // A = 1 - sum * 5 * intensity / (r^6 N) (the r^6 already applied above). As in SAO the sum is
  // in 1 / world units, so the same intensity darkens more with a smaller radius.
  float visibility = max(0.0, 1.0 - sum * (5.0 * push.params.y / float(kSamples)));
  out_ao = vec4(visibility, z, 0.0, 0.0);
}
