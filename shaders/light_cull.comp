#version 460
#extension GL_GOOGLE_include_directive : require
// Forward+ light culling: one invocation per screen tile, no shared memory and no barriers
// (lavapipe runs a workgroup as a loop of SIMD-8 coroutines, where both are costly). Every light
// was projected once into a tile rectangle (GpuLightBounds) and binned into the tile rows it
// covers, on the CPU or on the GPU (light_bounds.comp, light_bins.comp: setting light_binning),
// so a tile visits only its row's lights, starting with four integer compares.
// Measured on lavapipe (2 cores), Sponza 1280x720, 16 px tiles, tessera-lights-bench: looping
// over every light in every tile cost 55 ms at 4096 lights and 248 ms at 20000; with the row
// bins it is 17 ms and 74 ms, so the bins stay. (Shared-memory variants were not tried: a
// workgroup barrier on lavapipe switches between its SIMD-8 coroutines.) Lights are visited in index order, so every list is sorted
// and frames are reproducible. renderer/light_culling.cpp has the same algorithm on the CPU;
// keep the two in step.
#include "common/gpu_types.h"

layout(local_size_x = kLightCullGroupSize) in;

layout(set = 0, binding = kCullBindingFrame, std140) uniform FrameBlock { FrameUniforms frame; };
layout(set = 0, binding = kCullBindingLightBounds, std430) readonly buffer BoundsBlock {
  GpuLightBounds light_bounds[];
};
layout(set = 0, binding = kCullBindingDepth) uniform sampler2D u_depth;
layout(set = 0, binding = kCullBindingTileCounts, std430) writeonly buffer CountBlock {
  uint tile_counts[];
};
layout(set = 0, binding = kCullBindingTileLights, std430) writeonly buffer ListBlock {
  uint tile_lights[];
};
layout(set = 0, binding = kCullBindingRowLights, std430) readonly buffer RowBlock {
  uint row_lights[];
};

vec3 CornerRay(vec2 pixel) {
  vec2 ndc = 2.0 * pixel / vec2(frame.counts.zw) - 1.0;
  return vec3(ndc.x / frame.proj[0][0], ndc.y / frame.proj[1][1], -1.0);
}

float ViewDepth(float d) { return frame.depth_params.y / (d + frame.depth_params.x); }

uint SliceMask(float z0, float z1, float dmin, float scale) {
  if (z1 < dmin) return 0u;
  // Clamped as floats: (z - dmin) * scale can exceed the int range when dmax ~ dmin.
  int s0 = int(clamp(floor((z0 - dmin) * scale), 0.0, 31.0));
  int s1 = int(clamp(floor((z1 - dmin) * scale), 0.0, 31.0));
  uint hi = s1 == 31 ? 0xffffffffu : ((2u << uint(s1)) - 1u);
  return hi & ~((1u << uint(s0)) - 1u);
}

void main() {
  uint tiles_x = frame.lighting.z;
  uint tiles_y = uint(frame.depth_params.z);
  uint tile = gl_GlobalInvocationID.x;
  if (tile >= tiles_x * tiles_y) return;
  uint tx = tile % tiles_x, ty = tile / tiles_x;
  uint ts = frame.lighting.y;
  ivec2 p0 = ivec2(tx * ts, ty * ts);
  ivec2 p1 = min(p0 + ivec2(ts), ivec2(frame.counts.zw));

  // Depth bounds of the tile's surfaces (depth 0 is sky: no surface).
  float dmin = 1e30, dmax = 0.0;
  for (int y = p0.y; y < p1.y; ++y)
    for (int x = p0.x; x < p1.x; ++x) {
      float d = texelFetch(u_depth, ivec2(x, y), 0).r;
      if (d > 0.0) {
        float z = ViewDepth(d);
        dmin = min(dmin, z);
        dmax = max(dmax, z);
      }
    }
  uint count = 0u;
  if (dmax > 0.0) {
    // 2.5D mask: which of 32 depth slices between dmin and dmax hold a surface.
    float scale = 32.0 / max(dmax - dmin, 1e-20);
    uint mask = 0u;
    for (int y = p0.y; y < p1.y; ++y)
      for (int x = p0.x; x < p1.x; ++x) {
        float d = texelFetch(u_depth, ivec2(x, y), 0).r;
        if (d > 0.0) mask |= 1u << uint(min(31.0, (ViewDepth(d) - dmin) * scale));
      }
    // The tile frustum from all four corners; normals face the centre ray.
    vec3 rays[4] = vec3[4](CornerRay(vec2(p0)), CornerRay(vec2(p1.x, p0.y)), CornerRay(vec2(p1)),
                           CornerRay(vec2(p0.x, p1.y)));
    vec3 centre = CornerRay(0.5 * vec2(p0 + p1));
    vec3 planes[4];
    for (int i = 0; i < 4; ++i) {
      vec3 n = normalize(cross(rays[i], rays[(i + 1) % 4]));
      planes[i] = dot(n, centre) < 0.0 ? -n : n;
    }
    // The tile's bounding sphere between dmin and dmax (for spot cones).
    vec3 tc = vec3(0.0);
    for (int i = 0; i < 4; ++i) tc += rays[i] * (0.5 * (dmin + dmax));
    tc *= 0.25;
    float tr = 0.0;
    for (int i = 0; i < 4; ++i)
      tr = max(tr, max(length(rays[i] * dmin - tc), length(rays[i] * dmax - tc)));

    bool use_mask = (frame.lighting.w & 2u) != 0u;
    uint base = tile * kMaxLightsPerTile;
    // Only the lights binned to this tile row (in index order).
    uint row_end = row_lights[2u * ty + 1u];
    for (uint k = row_lights[2u * ty]; k < row_end; ++k) {
      uint i = row_lights[k];
      ivec4 r = light_bounds[i].tiles;
      if (int(tx) < r.x || int(tx) > r.z || int(ty) < r.y || int(ty) > r.w) continue;
      vec4 s = light_bounds[i].sphere;
      float zc = -s.z;
      if (zc + s.w < dmin || zc - s.w > dmax) continue;
      if (dot(planes[0], s.xyz) < -s.w || dot(planes[1], s.xyz) < -s.w ||
          dot(planes[2], s.xyz) < -s.w || dot(planes[3], s.xyz) < -s.w)
        continue;
      if (use_mask && (SliceMask(zc - s.w, zc + s.w, dmin, scale) & mask) == 0u) continue;
      vec4 cone = light_bounds[i].cone;
      if (cone.w > -1.5) {  // spot: Wronski's cone test against the tile's sphere
        vec4 cone2 = light_bounds[i].cone2;
        vec3 v = tc - cone.xyz;
        float v1 = dot(v, cone2.xyz);
        float sin_a = sqrt(max(0.0, 1.0 - cone.w * cone.w));
        float closest = cone.w * sqrt(max(0.0, dot(v, v) - v1 * v1)) - v1 * sin_a;
        if (closest > tr || v1 > tr + cone2.w || v1 < -tr) continue;
      }
      if (count < kMaxLightsPerTile) tile_lights[base + count] = i;
      ++count;
    }
  }
  tile_counts[tile] = count > kMaxLightsPerTile ? (kMaxLightsPerTile | kTileOverflowBit) : count;
}
