#include "common/gpu_types.h"
#include "common/post_io.glsl"
#include "common/runner_up.glsl"
// vis_mlaa geometric AA. A pixel whose shaded surface owns every sample passes through. In any
// other pixel the mean position of the surface's samples lies off the pixel centre, towards
// the surface; the other surface lies the opposite way. That direction (the "compass") picks
// the two of the 8 neighbours it falls between and how much of each (by angle); the blend of
// the two is mixed into the pixel by the share of samples the surface does not own. Linear HDR
// colour in and out. The aa_mask debug view shows the share the surface owns (black: few).
// A neighbour shading the pixel's own triangle tells nothing about the other surface (e.g. where
// an edge ends at a corner); it is replaced by the nearest neighbour, by angle within 90 degrees
// of the compass, that shows another triangle.
// Where the pixel has a runner-up surface (vis_resolve.comp; edge pixels only), its samples take
// its colour (a neighbour's that shows it, or its own shading), the compass points to the
// samples neither surface owns, and only those borrow from the neighbours it picks.
#ifdef GEOMETRIC_AA_EDGES
// geometric_aa_edges.comp: the HDR colour, read and then written in place (storage).
layout(set = 0, binding = kGeometricAaBindingOut, rgba16f) uniform image2D u_hdr;
vec4 LoadColor(ivec2 p) { return imageLoad(u_hdr, p); }
ivec2 ColorSize() { return imageSize(u_hdr); }
#else
layout(set = 0, binding = 0) uniform sampler2D u_color;
vec4 LoadColor(ivec2 p) { return texelFetch(u_color, p, 0); }
ivec2 ColorSize() { return textureSize(u_color, 0); }
#endif
layout(set = 0, binding = 1) uniform usampler2D u_coverage;
layout(set = 0, binding = 2) uniform usampler2D u_id;
layout(push_constant) uniform Push { TS_PUSH_GEOMETRIC_AA } push;  // common/gpu_types.h
#ifndef GEOMETRIC_AA_EDGES
#ifdef TESSERA_COMPUTE
vec4 out_color;
#else
layout(location = 0) out vec4 out_color;
#endif
#endif

const float kPi = 3.14159265359;

vec3 Fetch(ivec2 p) { return LoadColor(clamp(p, ivec2(0), ColorSize() - 1)).rgb; }

// The visibility id (drawable and triangle; 0 the sky) a pixel shades.
uint IdAt(ivec2 p) {
  ivec2 size = textureSize(u_id, 0);
  return texelFetch(u_id, clamp(p, ivec2(0), size - 1), 0).r;
}

// The colour the compass `away` points to: the two neighbours it falls between, by angle, or
// the one of them that shows another triangle than the pixel's, or the next neighbours out on
// either side (the nearer in angle first). False when none of these shows another triangle.
// The neighbours to take are chosen first and their colours fetched once, after: lavapipe runs
// every side of a branch under a lane mask, so a fetch in each case cost them all.
bool Borrow(ivec2 p, vec2 away, out vec3 other) {
  float sector = atan(away.y, away.x) / (0.25 * kPi);
  if (sector < 0.0) sector += 8.0;
  int i0 = int(floor(sector)) & 7;
  int i1 = (i0 + 1) & 7;
  float t = sector - floor(sector);
  uint own = IdAt(p);
  bool use0 = IdAt(p + kNeighbours[i0]) != own;
  bool use1 = IdAt(p + kNeighbours[i1]) != own;
  int a = (i0 + 7) & 7, b = (i1 + 1) & 7;
  bool a_first = t < 0.5;
  int first = a_first ? a : b, second = a_first ? b : a;
  bool use_first = IdAt(p + kNeighbours[first]) != own;
  bool use_second = IdAt(p + kNeighbours[second]) != own;
  // j0 alone, or j0 and j1 mixed by t.
  bool both = use0 && use1;
  int j0 = use0 ? i0 : use1 ? i1 : use_first ? first : second;
  vec3 c0 = Fetch(p + kNeighbours[j0]);
  vec3 c1 = Fetch(p + kNeighbours[i1]);
  other = both ? mix(c0, c1, t) : c0;
  return use0 || use1 || use_first || use_second;
}

// The pixel's colour after geometric AA; `runner` is the runner-up surface's colour and
// `runner_mean` the mean position of its samples in the pixel (runner.a: the share of the
// samples it owns, 0 where the pixel has none).
vec4 GeometricAa(ivec2 p, vec4 runner, vec2 runner_mean) {
  vec4 color = LoadColor(p);
  uint word = texelFetch(u_coverage, p, 0).r;
  uint full = (1u << push.samples) - 1u;
  uint mask = word & full;
  float owned = float(bitCount(mask)) / float(push.samples);
  if (push.show_mask != 0u) return vec4(vec3(owned), 1.0);
  vec2 away = vec2(0.5) - vec2((word >> 8) & 0xfffu, word >> 20) / 4095.0;
  // One Borrow for both cases below (each call's code would run under a lane mask in the other).
  bool has_runner = runner.a > 0.0;
  // With a runner-up, the samples neither surface owns: the standard sample positions average to
  // the pixel's centre, so their mean lies along owned * away + runner.a * (0.5 - runner_mean).
  vec3 known = owned * color.rgb + runner.a * runner.rgb;
  float rest = 1.0 - owned - runner.a;
  if (has_runner) away += (runner.a / owned) * (vec2(0.5) - runner_mean);
  bool skip = (has_runner ? rest < 0.5 / float(push.samples) : mask == full) ||
              dot(away, away) < 1e-6;
  vec3 other;
  // Without another surface in sight there is nothing to blend with.
  bool found = !skip && Borrow(p, away, other);
  if (has_runner) return vec4(found ? known + rest * other : known / (owned + runner.a), 1.0);
  return found ? vec4(mix(color.rgb, other, 1.0 - owned), 1.0) : color;
}

vec4 GeometricAa(ivec2 p) { return GeometricAa(p, vec4(0.0), vec2(0.5)); }

#ifndef GEOMETRIC_AA_EDGES
void PostMain() { out_color = GeometricAa(ivec2(FRAG_COORD)); }
#endif
