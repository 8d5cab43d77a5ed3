#version 460
#extension GL_GOOGLE_include_directive : require
// vis_mlaa shading of one material's pixels. The resolve pass chose, per pixel, the surface to
// shade, a triangle of it and the mean position of its samples; common/vis_surface.glsl
// rebuilds the surface there, and the forward path's material and lighting
// (common/shading.glsl) shade it once.
#include "common/scene.glsl"
#include "common/sky.glsl"
#include "common/textures.glsl"
#include "common/shadows.glsl"
#include "common/shading.glsl"
#include "common/vis.glsl"
#include "common/vis_surface.glsl"

layout(set = kVisSet, binding = kVisBindingId) uniform usampler2D u_vis_id;
layout(set = kVisSet, binding = kVisBindingCoverage) uniform usampler2D u_vis_coverage;
layout(set = kVisSet, binding = kVisBindingShadeSamples) uniform usampler2DMS u_vis_samples;
layout(location = 0) in vec2 v_uv;
layout(location = 0) out vec4 out_color;

void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  uint id = texelFetch(u_vis_id, p, 0).r;
  uint word = texelFetch(u_vis_coverage, p, 0).r;
  vec2 pixel = vec2(p) + CoverageMean(word);
  vec3 dir = RayDirection(pixel);
  Triangle tri = LoadTriangle(id);
  vec3 b = Barycentrics(tri.p0, tri.e1, tri.e2, dir);
  // When the surface spans several triangles, the mean position can miss the nearest sample's
  // triangle: take the first of the surface's other triangles that contains it.
  uint mask = CoverageMask(word);
  const float kInside = -1e-4;
  for (uint s = 0u; s < frame.aa.y && min(b.x, min(b.y, b.z)) < kInside; ++s) {
    if ((mask & (1u << s)) == 0u) continue;
    uint other = texelFetch(u_vis_samples, p, int(s)).r;
    if (other == id) continue;
    Triangle t = LoadTriangle(other);
    vec3 bt = Barycentrics(t.p0, t.e1, t.e2, dir);
    if (min(bt.x, min(bt.y, bt.z)) >= kInside) {
      tri = t;
      b = bt;
      id = other;
    }
  }
  out_color = vec4(ShadeSurface(VisSurface(tri, b, pixel), false).rgb, 1.0);
}
