// Geometry culling (cull.comp; cull_shared_scan.comp for devices whose compute shaders lack
// subgroup arithmetic): tests every cull item against the view and appends an indexed indirect
// draw command (firstInstance = drawable) to its segment's list and, for opaque items, to its
// batch's list, then writes each list's count.
//
// One workgroup walks the items in order, kCullGroupSize at a time, with a prefix sum over the
// chunk: an item's place in its list is the number of visible items between the list's first
// item and itself. The lists therefore come out in item order whatever the device's scheduling,
// so a frame is the same, pixel for pixel, in every culling mode and on every run. (Appending
// with atomics from many workgroups would be faster on a big GPU and would reorder the draws of
// equal-depth surfaces from run to run.) The chunk's prefix sum uses subgroup arithmetic where
// the device has it (CULL_SUBGROUP_SCAN), else a scan in shared memory.
//
// Phases (uniforms.counts.w):
//  - kCullPhaseFrustum: draw what is in the frustum.
//  - kCullPhaseEarly: draw what was visible last frame (bits in vis_prev) and is in the frustum.
//  - kCullPhaseLate, after the early draws' depth became a pyramid: test every item in the
//    frustum against the pyramid, record it in vis_next, and draw those visible now that the
//    early phase did not draw. Nothing visible is drawn a frame late.
#include "common/gpu_types.h"

layout(local_size_x = kCullGroupSize) in;

// A storage buffer rather than a uniform one: see renderer_init.cpp (a lavapipe leak).
layout(set = 0, binding = kCullBindingUniforms, std430) readonly buffer CullBlock {
  CullUniforms cull;
};
layout(set = 0, binding = kCullBindingItems, std430) readonly buffer ItemBlock {
  GpuCullItem items[];
};
layout(set = 0, binding = kCullBindingDrawables, std430) readonly buffer DrawableBlock {
  GpuDrawable drawables[];
};
layout(set = 0, binding = kCullBindingCommands, std430) writeonly buffer CommandBlock {
  uint commands[];
};
layout(set = 0, binding = kCullBindingCounts, std430) buffer CountBlock { uint counts[]; };
layout(set = 0, binding = kCullBindingBases, std430) coherent buffer BaseBlock { uint bases[]; };
layout(set = 0, binding = kCullBindingVisPrev, std430) readonly buffer VisPrevBlock {
  uint vis_prev[];
};
layout(set = 0, binding = kCullBindingVisNext, std430) buffer VisNextBlock { uint vis_next[]; };
layout(set = 0, binding = kCullBindingHiz) uniform sampler2D hiz;

#ifdef CULL_SUBGROUP_SCAN
shared uint s_subgroup_sums[kCullGroupSize];
#else
shared uint s_scan[kCullGroupSize];
#endif
shared uint s_chunk_total;

bool InFrustum(vec3 lo, vec3 hi) {
  for (int i = 0; i < 6; ++i) {
    vec4 p = cull.planes[i];
    // The box corner furthest along the plane normal.
    vec3 v = vec3(p.x >= 0.0 ? hi.x : lo.x, p.y >= 0.0 ? hi.y : lo.y, p.z >= 0.0 ? hi.z : lo.z);
    if (dot(p.xyz, v) + p.w < 0.0) return false;
  }
  return true;
}

// Conservative occlusion test of a world AABB against the pyramid (reverse Z: larger is nearer;
// the pyramid holds the farthest depth under each texel). The box's screen rectangle, in pixels
// whose centres it can cover, maps to level-0 texels; the level is the finest one at which the
// rectangle spans at most 2x2 texels, and all four texels are read. Occluded only when the box's
// nearest point is behind the farthest depth of all of them.
bool Occluded(vec3 lo, vec3 hi) {
  vec2 ndc_min = vec2(1e30), ndc_max = vec2(-1e30);
  float nearest = 0.0;
  for (int i = 0; i < 8; ++i) {
    vec3 corner = vec3((i & 1) != 0 ? hi.x : lo.x, (i & 2) != 0 ? hi.y : lo.y,
                       (i & 4) != 0 ? hi.z : lo.z);
    vec4 clip = cull.view_proj * vec4(corner, 1.0);
    if (clip.w <= 1e-5) return false;  // reaches behind the eye: cannot be judged here
    vec3 ndc = clip.xyz / clip.w;
    ndc_min = min(ndc_min, ndc.xy);
    ndc_max = max(ndc_max, ndc.xy);
    nearest = max(nearest, ndc.z);
  }
  if (nearest >= 1.0) return false;  // crosses the near plane
  if (any(greaterThan(ndc_min, vec2(1.0))) || any(lessThan(ndc_max, vec2(-1.0))))
    return false;  // off screen: the frustum test decides (shadow views may not test it)
  vec2 frame = vec2(cull.frame.xy);
  // Pixels whose centres may be covered, as level-0 texels (texel j covers the pixels
  // floor(j * W / w0) .. ceil((j + 1) * W / w0) - 1, so pixel p is in texel p * w0 / W).
  uvec2 p0 = uvec2(clamp(floor((ndc_min * 0.5 + 0.5) * frame), vec2(0.0), frame - 1.0));
  uvec2 p1 = uvec2(clamp(floor((ndc_max * 0.5 + 0.5) * frame), vec2(0.0), frame - 1.0));
  uvec2 size0 = cull.hiz.xy;
  uvec2 t0 = p0 * size0 / cull.frame.xy;
  uvec2 t1 = p1 * size0 / cull.frame.xy;
  uint level = 0;
  while (level + 1 < cull.hiz.z &&
         ((t1.x >> level) - (t0.x >> level) > 1 || (t1.y >> level) - (t0.y >> level) > 1))
    level++;
  uvec2 size = max(size0 >> level, uvec2(1));
  ivec2 a = ivec2(min(t0 >> level, size - 1));
  ivec2 b = ivec2(min((t0 >> level) + 1, size - 1));
  int l = int(level);
  float farthest = min(min(texelFetch(hiz, a, l).r, texelFetch(hiz, ivec2(b.x, a.y), l).r),
                       min(texelFetch(hiz, ivec2(a.x, b.y), l).r, texelFetch(hiz, b, l).r));
  return nearest < farthest;
}

// Writes item's draw (one instance, firstInstance = drawable) as command `index`.
void WriteCommand(uint index, GpuCullItem item) {
  const uint c = index * kDrawCommandWords;
  commands[c + 0] = item.draw.y;  // indexCount
  commands[c + 1] = 1u;           // instanceCount
  commands[c + 2] = item.draw.x;  // firstIndex
  commands[c + 3] = item.draw.z;  // vertexOffset
  commands[c + 4] = item.draw.w;  // firstInstance = drawable
  commands[c + 5] = item.draw.y;  // the pulled draw (common/vis_pull.glsl): vertexCount
  commands[c + 6] = 1u;           // instanceCount
  commands[c + 7] = item.draw.x;  // firstVertex = firstIndex
  commands[c + 8] = item.draw.w;  // firstInstance = drawable
}

void main() {
  const uint n = cull.counts.x;
  const uint phase = cull.counts.w;
  const uint lane = gl_LocalInvocationIndex;
  const uint cmd_base = cull.offsets.x;
  const uint count_base = cull.offsets.y;
  const uint stats = count_base + cull.counts.y + cull.counts.z;
  uint running = 0;  // visible items before this chunk
  uint in_frustum = 0, visible = 0, stale = 0;
  for (uint chunk = 0; chunk < n; chunk += kCullGroupSize) {
    const uint i = chunk + lane;
    bool draw = false;
    GpuCullItem item;
    if (i < n) {
      item = items[i];
      GpuDrawable d = drawables[item.draw.w];
      const vec3 lo = d.aabb_min.xyz, hi = d.aabb_max.xyz;
      const bool frustum = InFrustum(lo, hi);
      const bool was_visible =
          phase != kCullPhaseFrustum && (vis_prev[i >> 5] & (1u << (i & 31))) != 0;
      if (phase == kCullPhaseFrustum) {
        draw = frustum;
      } else if (phase == kCullPhaseEarly) {
        draw = frustum && was_visible;
      } else {
        const bool now_visible = frustum && !Occluded(lo, hi);
        if (now_visible) atomicOr(vis_next[i >> 5], 1u << (i & 31));
        draw = now_visible && !was_visible;
        visible += now_visible ? 1u : 0u;
        stale += (frustum && was_visible && !now_visible) ? 1u : 0u;
      }
      in_frustum += frustum ? 1u : 0u;
    }
    const uint flag = draw ? 1u : 0u;
#ifdef CULL_SUBGROUP_SCAN
    // Exclusive prefix sum of `draw` over the chunk: within the subgroup, then across subgroups.
    const uint in_subgroup = subgroupExclusiveAdd(flag);
    const uint subgroup_sum = subgroupAdd(flag);
    if (subgroupElect()) s_subgroup_sums[gl_SubgroupID] = subgroup_sum;
    barrier();
    if (lane == 0) {
      uint sum = 0;
      for (uint s = 0; s < gl_NumSubgroups; ++s) {
        const uint v = s_subgroup_sums[s];
        s_subgroup_sums[s] = sum;
        sum += v;
      }
      s_chunk_total = sum;
    }
    barrier();
    const uint before = running + s_subgroup_sums[gl_SubgroupID] + in_subgroup;
#else
    // The same sum in shared memory (Hillis-Steele: log2(kCullGroupSize) steps).
    s_scan[lane] = flag;
    barrier();
    for (uint offset = 1u; offset < kCullGroupSize; offset <<= 1) {
      const uint add = lane >= offset ? s_scan[lane - offset] : 0u;
      barrier();
      s_scan[lane] += add;
      barrier();
    }
    const uint before = running + s_scan[lane] - flag;
    if (lane == kCullGroupSize - 1u) s_chunk_total = s_scan[lane];
    barrier();
#endif
    // The first item of a list records how many visible items precede the list.
    if (i < n) {
      if (item.slot.y == i) bases[item.slot.x] = before;
      if (item.slot.z != ~0u && item.slot.w == i) bases[cull.counts.y + item.slot.z] = before;
    }
    memoryBarrierBuffer();
    barrier();
    if (i < n) {
      const uint seg_base = bases[item.slot.x];
      if (draw) WriteCommand(cmd_base + item.slot.y + (before - seg_base), item);
      if ((item.flags.x & 1u) != 0) counts[count_base + item.slot.x] = before + flag - seg_base;
      if (item.slot.z != ~0u) {
        const uint batch_base = bases[cull.counts.y + item.slot.z];
        if (draw) WriteCommand(cmd_base + n + item.slot.w + (before - batch_base), item);
        if ((item.flags.x & 2u) != 0)
          counts[count_base + cull.counts.y + item.slot.z] = before + flag - batch_base;
      }
    }
    running += s_chunk_total;
    barrier();  // s_subgroup_sums and s_chunk_total are rewritten by the next chunk
  }
  // Statistics of the phase.
#ifdef CULL_SUBGROUP_SCAN
  const uint f = subgroupAdd(in_frustum), v = subgroupAdd(visible), st = subgroupAdd(stale);
  if (subgroupElect()) {
    atomicAdd(counts[stats + kCullStatInFrustum], f);
    atomicAdd(counts[stats + kCullStatVisible], v);
    atomicAdd(counts[stats + kCullStatStale], st);
  }
#else
  if (in_frustum != 0u) atomicAdd(counts[stats + kCullStatInFrustum], in_frustum);
  if (visible != 0u) atomicAdd(counts[stats + kCullStatVisible], visible);
  if (stale != 0u) atomicAdd(counts[stats + kCullStatStale], stale);
#endif
}
