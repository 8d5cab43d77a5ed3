#version 460
#extension GL_GOOGLE_include_directive : require
// vis_mlaa resolve: groups a pixel's visibility samples by surface and picks the surface to
// shade. Two samples are on one surface when they hit the same triangle, or triangles of the
// same drawable that share a vertex: the same index, or two vertices at almost the same
// position whose normals are within 8.1 degrees (dot > 0.99). The surface owning the most
// samples wins (ties: the one holding the lowest sample). Writes, per pixel:
//  - out_id: the id of the winning sample nearest the mean position of the winning samples
//    (the triangle the shading pass intersects);
//  - out_coverage: the winning samples' mask and their mean position (PackCoverage).
// The shading (vis_classify.comp, vis_shade_mlaa.comp) then lists and shades each pixel's id.
#include "common/scene.glsl"
#include "common/vis.glsl"

layout(set = kVisSet, binding = kVisBindingSamples) uniform usampler2DMS u_vis;
layout(location = 0) out uint out_id;
layout(location = 1) out uint out_coverage;

bool SameSurface(uint a, uint b) {
  if (a == b) return true;
  uint tb = frame.aa.x;
  if (a == 0u || b == 0u || (a >> tb) != (b >> tb)) return false;
  uvec4 ids = drawables[VisDrawable(a, tb)].ids;
  uvec3 va = TriangleVertices(ids, VisTriangle(a, tb));
  uvec3 vb = TriangleVertices(ids, VisTriangle(b, tb));
  vec3 pa[3] = vec3[3](VertexPosition(va.x), VertexPosition(va.y), VertexPosition(va.z));
  vec3 pb[3] = vec3[3](VertexPosition(vb.x), VertexPosition(vb.y), VertexPosition(vb.z));
  // "Almost the same position": within 0.1% of the shorter triangle's longest edge.
  float size_a = max(distance(pa[0], pa[1]), max(distance(pa[1], pa[2]), distance(pa[2], pa[0])));
  float size_b = max(distance(pb[0], pb[1]), max(distance(pb[1], pb[2]), distance(pb[2], pb[0])));
  float eps = 1e-3 * min(size_a, size_b);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (va[i] == vb[j]) return true;
      if (distance(pa[i], pb[j]) <= eps &&
          dot(normalize(VertexNormal(va[i])), normalize(VertexNormal(vb[j]))) > 0.99)
        return true;
    }
  }
  return false;
}


// Groups the samples by surface and writes the outputs for the surface with the most.
void Group(uint n, uint ids[8]) {
  // Label each sample with the first earlier sample on its surface.
  uint label[8];
  for (uint i = 0u; i < n; ++i) {
    label[i] = i;
    for (uint j = 0u; j < i; ++j) {
      if (label[j] == j && SameSurface(ids[i], ids[j])) {
        label[i] = j;
        break;
      }
    }
    if (label[i] == i) {  // also join a group through any of its members
      for (uint j = 0u; j < i; ++j) {
        if (label[j] != j && SameSurface(ids[i], ids[j])) {
          label[i] = label[j];
          break;
        }
      }
    }
  }
  uint best = 0u, best_count = 0u;
  for (uint g = 0u; g < n; ++g) {
    if (label[g] != g) continue;
    uint count = 0u;
    for (uint s = 0u; s < n; ++s) count += label[s] == g ? 1u : 0u;
    if (count > best_count) {
      best = g;
      best_count = count;
    }
  }
  uint mask = 0u;
  vec2 mean = vec2(0.0);
  for (uint s = 0u; s < n; ++s) {
    if (label[s] != best) continue;
    mask |= 1u << s;
    mean += SamplePosition(n, s);
  }
  mean /= float(best_count);
  uint nearest = best;
  float nearest_d = 1e9;
  for (uint s = 0u; s < n; ++s) {
    if (label[s] != best) continue;
    vec2 d = SamplePosition(n, s) - mean;
    if (dot(d, d) < nearest_d) {
      nearest_d = dot(d, d);
      nearest = s;
    }
  }
  out_id = ids[nearest];
  out_coverage = PackCoverage(mask, mean);
}

void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  uint n = frame.aa.y;
  uint ids[8];
  bool uniform_id = true;
  for (uint s = 0u; s < n; ++s) {
    ids[s] = texelFetch(u_vis, p, int(s)).r;
    uniform_id = uniform_id && ids[s] == ids[0];
  }
  // One triangle covers the pixel (or none): shade it at the pixel centre.
  out_id = ids[0];
  out_coverage = PackCoverage((1u << n) - 1u, vec2(0.5));
  // (On llvmpipe the grouping still costs every 8-pixel block holding an edge pixel; written as a
  // zero-or-one-trip loop it measured the same.)
  if (!uniform_id) Group(n, ids);
}
