// vis_mlaa: visibility ids, the standard sample positions, the coverage word, and reading the
// scene's triangles from its index and vertex buffers (set kVisSet, bindings 2 and 3).
#ifndef TESSERA_VIS_GLSL
#define TESSERA_VIS_GLSL
#include "gpu_types.h"
#include "runner_up.glsl"

layout(set = kVisSet, binding = kVisBindingIndices, std430) readonly buffer VisIndexBlock {
  uint vis_indices[];
};
layout(set = kVisSet, binding = kVisBindingVertices, std430) readonly buffer VisVertexBlock {
  float vis_vertices[];
};

uint VisDrawable(uint id, uint triangle_bits) { return (id >> triangle_bits) - 1u; }
uint VisTriangle(uint id, uint triangle_bits) { return id & ((1u << triangle_bits) - 1u); }

// Vulkan's standard sample locations (VkPhysicalDeviceLimits::standardSampleLocations), in
// pixel units from the pixel's top-left corner.
vec2 SamplePosition(uint samples, uint s) {
  if (samples == 2u) return s == 0u ? vec2(0.75, 0.75) : vec2(0.25, 0.25);
  if (samples == 4u) {
    const vec2 p4[4] = vec2[4](vec2(0.375, 0.125), vec2(0.875, 0.375), vec2(0.125, 0.625),
                               vec2(0.625, 0.875));
    return p4[s];
  }
  if (samples == 8u) {
    const vec2 p8[8] = vec2[8](vec2(0.5625, 0.3125), vec2(0.4375, 0.6875), vec2(0.8125, 0.5625),
                               vec2(0.3125, 0.1875), vec2(0.1875, 0.8125), vec2(0.0625, 0.4375),
                               vec2(0.6875, 0.9375), vec2(0.9375, 0.0625));
    return p8[s];
  }
  return vec2(0.5);
}

// The coverage word: bits 0-7 the samples of the shaded surface, 8-19 and 20-31 the mean
// position of those samples in the pixel (x, y), 12-bit fixed point over [0, 1].
uint PackCoverage(uint mask, vec2 mean) {
  uvec2 q = uvec2(clamp(mean, 0.0, 1.0) * 4095.0 + 0.5);
  return (mask & 0xffu) | (q.x << 8) | (q.y << 20);
}
uint CoverageMask(uint word) { return word & 0xffu; }
vec2 CoverageMean(uint word) { return vec2((word >> 8) & 0xfffu, word >> 20) / 4095.0; }

// One vertex of the scene's vertex buffer (scene::Vertex, kVertexFloats floats).
vec3 VertexPosition(uint v) {
  uint b = v * kVertexFloats;
  return vec3(vis_vertices[b], vis_vertices[b + 1u], vis_vertices[b + 2u]);
}
vec3 VertexNormal(uint v) {
  uint b = v * kVertexFloats + 3u;
  return vec3(vis_vertices[b], vis_vertices[b + 1u], vis_vertices[b + 2u]);
}
vec4 VertexTangent(uint v) {
  uint b = v * kVertexFloats + 6u;
  return vec4(vis_vertices[b], vis_vertices[b + 1u], vis_vertices[b + 2u], vis_vertices[b + 3u]);
}
vec4 VertexUvs(uint v) {  // xy TEXCOORD_0, zw TEXCOORD_1
  uint b = v * kVertexFloats + 10u;
  return vec4(vis_vertices[b], vis_vertices[b + 1u], vis_vertices[b + 2u], vis_vertices[b + 3u]);
}

// The vertex indices of a triangle of a drawable (GpuDrawable.ids: z first index, w offset).
uvec3 TriangleVertices(uvec4 drawable_ids, uint triangle) {
  uint first = drawable_ids.z + 3u * triangle;
  int offset = int(drawable_ids.w);
  return uvec3(uint(int(vis_indices[first]) + offset), uint(int(vis_indices[first + 1u]) + offset),
               uint(int(vis_indices[first + 2u]) + offset));
}
#endif
