// vis_mlaa: visibility ids, the standard sample positions, the coverage word, and reading the
// scene's triangles and drawables (set kVisSet: bindings 2 and 3, or the texel buffers 10-12).
// Needs scene.glsl (the drawables' storage buffer).
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
// The same and the drawables as texel buffers (gpu_types.h, kVisBindingIndexTexels): a pipeline
// reads one or the other, as its specialization constant says.
layout(set = kVisSet, binding = kVisBindingIndexTexels) uniform usamplerBuffer vis_index_texels;
layout(set = kVisSet, binding = kVisBindingVertexTexels) uniform usamplerBuffer vis_vertex_texels;
layout(set = kVisSet, binding = kVisBindingDrawableTexels) uniform usamplerBuffer
    vis_drawable_texels;
layout(constant_id = kVisTexelsConstant) const bool kVisTexels = false;

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

// One vertex of the scene's vertex buffer (scene::Vertex, kVertexFloats floats; as texels: xy
// position.xy, then position.z normal.x, normal.yz, tangent.xy, tangent.zw, uv0, uv1, colour).
vec2 VertexTexel(uint v, uint t) {
  return uintBitsToFloat(texelFetch(vis_vertex_texels, int(v * kVertexTexels + t)).xy);
}
vec3 VertexPosition(uint v) {
  if (kVisTexels) return vec3(VertexTexel(v, 0u), VertexTexel(v, 1u).x);
  uint b = v * kVertexFloats;
  return vec3(vis_vertices[b], vis_vertices[b + 1u], vis_vertices[b + 2u]);
}
vec3 VertexNormal(uint v) {
  if (kVisTexels) return vec3(VertexTexel(v, 1u).y, VertexTexel(v, 2u));
  uint b = v * kVertexFloats + 3u;
  return vec3(vis_vertices[b], vis_vertices[b + 1u], vis_vertices[b + 2u]);
}
vec4 VertexTangent(uint v) {
  if (kVisTexels) return vec4(VertexTexel(v, 3u), VertexTexel(v, 4u));
  uint b = v * kVertexFloats + 6u;
  return vec4(vis_vertices[b], vis_vertices[b + 1u], vis_vertices[b + 2u], vis_vertices[b + 3u]);
}
vec4 VertexUvs(uint v) {  // xy TEXCOORD_0, zw TEXCOORD_1
  if (kVisTexels) return vec4(VertexTexel(v, 5u), VertexTexel(v, 6u));
  uint b = v * kVertexFloats + 10u;
  return vec4(vis_vertices[b], vis_vertices[b + 1u], vis_vertices[b + 2u], vis_vertices[b + 3u]);
}
vec4 VertexColor(uint v) {  // COLOR_0
  if (kVisTexels) return VertexColorOf(texelFetch(vis_vertex_texels, int(v * kVertexTexels + 7u)).xy);
  uint b = v * kVertexFloats + 14u;
  return VertexColorOf(uvec2(floatBitsToUint(vis_vertices[b]), floatBitsToUint(vis_vertices[b + 1u])));
}

// The vertex at place k of the index buffer, for a drawable (GpuDrawable.ids: w its vertex
// offset).
uint IndexedVertex(uvec4 drawable_ids, uint k) {
  uint index = kVisTexels ? texelFetch(vis_index_texels, int(k)).x : vis_indices[k];
  return uint(int(index) + int(drawable_ids.w));
}

// The vertex indices of a triangle of a drawable (GpuDrawable.ids: z first index, w offset).
uvec3 TriangleVertices(uvec4 drawable_ids, uint triangle) {
  uint first = drawable_ids.z + 3u * triangle;
  return uvec3(IndexedVertex(drawable_ids, first), IndexedVertex(drawable_ids, first + 1u),
               IndexedVertex(drawable_ids, first + 2u));
}

// Drawable `d`'s record (scene.glsl's drawables[d]): its world matrix, normal matrix and ids.
uvec4 DrawableTexel(uint d, uint t) {
  return texelFetch(vis_drawable_texels, int(d * kDrawableTexels + t));
}
mat4 DrawableWorld(uint d) {
  if (!kVisTexels) return drawables[d].world;
  return mat4(uintBitsToFloat(DrawableTexel(d, 0u)), uintBitsToFloat(DrawableTexel(d, 1u)),
              uintBitsToFloat(DrawableTexel(d, 2u)), uintBitsToFloat(DrawableTexel(d, 3u)));
}
mat3 DrawableNormalMatrix(uint d) {
  if (!kVisTexels) return mat3(drawables[d].normal_matrix);
  return mat3(uintBitsToFloat(DrawableTexel(d, 4u).xyz), uintBitsToFloat(DrawableTexel(d, 5u).xyz),
              uintBitsToFloat(DrawableTexel(d, 6u).xyz));
}
// -1 where the drawable's transform mirrors it (its tangent frame's handedness turns over), else 1.
float DrawableHandedness(uint d) {
  if (!kVisTexels) return drawables[d].normal_matrix[3][3];
  return uintBitsToFloat(DrawableTexel(d, 7u).w);
}
uvec4 DrawableIds(uint d) { return kVisTexels ? DrawableTexel(d, 8u) : drawables[d].ids; }

// Barycentrics (b0, b1, b2) of where the ray from the camera along `dir` meets the plane of the
// triangle p0, p0 + e1, p0 + e2 (Moller-Trumbore: triple products, well conditioned even for
// thin triangles, where the normal equations lose the digits the uv gradients need).
vec3 Barycentrics(vec3 p0, vec3 e1, vec3 e2, vec3 dir) {
  vec3 t = frame.camera_position.xyz - p0;
  vec3 pv = cross(dir, e2);
  float det = dot(e1, pv);
  float inv = abs(det) > 1e-30 ? 1.0 / det : 0.0;
  float b1 = dot(t, pv) * inv;
  float b2 = dot(dir, cross(t, e1)) * inv;
  return vec3(1.0 - b1 - b2, b1, b2);
}

struct Triangle {
  uint drawable;
  uvec3 v;
  vec3 p0, e1, e2;  // world space
};

Triangle LoadTriangle(uint id) {
  Triangle t;
  uint tb = frame.aa.x;
  t.drawable = VisDrawable(id, tb);
  mat4 world = DrawableWorld(t.drawable);
  t.v = TriangleVertices(DrawableIds(t.drawable), VisTriangle(id, tb));
  t.p0 = (world * vec4(VertexPosition(t.v.x), 1.0)).xyz;
  t.e1 = (world * vec4(VertexPosition(t.v.y), 1.0)).xyz - t.p0;
  t.e2 = (world * vec4(VertexPosition(t.v.z), 1.0)).xyz - t.p0;
  return t;
}

// Whether barycentrics b lie in their triangle (a little outside counts: the shared edges).
bool Inside(vec3 b) { return min(b.x, min(b.y, b.z)) >= -1e-4; }
#endif
